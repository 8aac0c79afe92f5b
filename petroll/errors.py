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


class SceneError(PetrollError):
    """An invalid scene: the message names the file, the key, the bad value and what is allowed."""

    def __init__(self, source: str, key: str, value: object, allowed: str):
        self.source, self.key, self.value, self.allowed = source, key, value, allowed
        shown = source if str(source).isprintable() else repr(str(source))  # a file name with a newline...
        super().__init__(f"{shown}: {key} = {value!r}: {allowed}")


class SolverError(PetrollError):
    """A numerical failure that the user can act on (the message names the cause and the remedy)."""


def reason(exc: BaseException) -> str:
    """An exception's message on one line (an OSError's strerror when it names no file)."""
    text = exc.strerror if isinstance(exc, OSError) and exc.strerror and not exc.filename else str(exc)
    return " ".join(str(text or type(exc).__name__).split())


class DMAError(PetrollError):
    """A DMA table or fit request that cannot be used (``petroll material fit``): the message names the
    file, the line or option, and what is allowed."""
