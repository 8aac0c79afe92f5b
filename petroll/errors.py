"""User-facing errors: each carries one line that names what is wrong and what is allowed.

The command line prints the message of a :class:`PetrollError` on one line and exits non-zero, without a
traceback; anything else is a bug and keeps its traceback.
"""


class PetrollError(Exception):
    """A problem the user can fix (bad input, unreachable target, solver that did not converge)."""


class _Missing:
    def __repr__(self) -> str:
        return "(missing)"


MISSING = _Missing()
"""Marks a key that the scene does not give."""

class Shown:
    """A value that an error message describes instead of writing it (one too deep or too long)."""

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return self.text


SHOWN_CHARACTERS = 200
"""The longest value an error message shows whole; a longer one is cut, saying how long it was."""


def shown(value: object) -> str:
    """``repr(value)`` for an error message, on one line: cut after SHOWN_CHARACTERS characters (a list of
    a million numbers, a 4000-digit integer), or a description where it cannot be written (nested deeper
    than Python's recursion allows)."""
    try:
        text = repr(value)
    except (RecursionError, ValueError):  # nested too deep; an integer beyond Python's 4300 digits
        return f"<{type(value).__name__} too deep or too long to show>"
    if len(text) > SHOWN_CHARACTERS:
        return f"{text[:SHOWN_CHARACTERS - 50]}... ({len(text)} characters)"
    return text


class SceneError(PetrollError):
    """An invalid scene: the message names the file, the key, the bad value and what is allowed."""

    def __init__(self, source: str, key: str, value: object, allowed: str):
        self.source, self.key, self.value, self.allowed = source, key, value, allowed
        shown_source = source if str(source).isprintable() else repr(str(source))  # a file name with a newline
        super().__init__(f"{shown_source}: {key} = {shown(value)}: {allowed}")


class SolverError(PetrollError):
    """A numerical failure that the user can act on (the message names the cause and the remedy)."""


def reason(exc: BaseException) -> str:
    """An exception's message on one line (an OSError's strerror when it names no file)."""
    text = exc.strerror if isinstance(exc, OSError) and exc.strerror and not exc.filename else str(exc)
    return " ".join(str(text or type(exc).__name__).split())


class DMAError(PetrollError):
    """A DMA table or fit request that cannot be used (``petroll material fit``): the message names the
    file, the line or option, and what is allowed."""
