"""TOML files read as petroll reads scenes: at most MAX_SCENE_BYTES, UTF-8 (a leading byte-order mark
ignored, as Windows editors write one), TOML nested at most MAX_NESTING deep; SceneError naming the file
for anything else. No validation of the scene itself (petroll.model.scene)."""

from __future__ import annotations

import pathlib
import tomllib

from petroll.errors import SceneError, Shown

MAX_SCENE_BYTES = 16 * 2**20
"""The largest scene file read (a scene is a few kB; /dev/zero is refused, not read forever)."""


def load_scene_table(path: str | pathlib.Path) -> dict:
    """The tables of a TOML file read as a scene file is (petroll.model.scene.load_scene), not validated as one."""
    return read_scene_file(pathlib.Path(path))[1]


def read_scene_file(path: pathlib.Path) -> tuple[str, dict]:
    """(text, tables) of a scene file, or SceneError naming it: unreadable, larger than MAX_SCENE_BYTES,
    not UTF-8, not TOML (:func:`read_toml`)."""
    source = str(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_SCENE_BYTES + 1)
    except OSError as exc:
        raise SceneError(source, "(file)", str(path), f"must be a readable scene file ({exc.strerror})") from None
    if len(data) > MAX_SCENE_BYTES:
        raise SceneError(source, "(file)", str(path), f"is larger than {MAX_SCENE_BYTES // 2**20} MiB: not a "
                         "scene (tables of values belong in files that the scene names)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise SceneError(source, "(file)", str(path), "must be a UTF-8 text file (TOML)") from None
    text = text.removeprefix("\ufeff")  # a byte-order mark: not the scene's (results.h5 stores the text)
    return text, read_toml(text, source)


MAX_NESTING = 16
"""The deepest nesting of tables and arrays in a scene (its sections count 1; the schema's deepest values,
the [x, y] pairs of a tabulated program's list, nest 4 deep)."""


def read_toml(text: str, source: str) -> dict:
    """A scene's TOML text parsed: a leading byte-order mark is ignored (Windows editors write one).
    SceneError naming the file for text that is not TOML, nests deeper than MAX_NESTING or holds an
    integer of more digits than Python reads (4300)."""
    try:
        raw = tomllib.loads(text.removeprefix("\ufeff"))
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(source, "(syntax)", str(exc), "must be valid TOML") from None
    except RecursionError:
        raise SceneError(source, "(syntax)", Shown("<tables or arrays nested deeper than Python reads>"),
                         f"tables and arrays may nest at most {MAX_NESTING} deep") from None
    except ValueError as exc:  # int(): "Exceeds the limit (4300 digits) for integer string conversion"
        why = str(exc).partition(";")[0]  # without the advice to raise Python's limit
        raise SceneError(source, "(syntax)", Shown("<a number Python cannot read>"),
                         f"must be valid TOML with numbers Python can read ({why})") from None
    check_nesting(raw, source)
    return raw


def check_nesting(raw: dict, source: str) -> None:
    """SceneError naming the key where ``raw`` nests tables and arrays deeper than MAX_NESTING (or holds
    itself), before anything recurses into it (a copy, a check, the TOML writer)."""
    stack = [(raw, 0, ())]  # depth first: a value that holds itself reaches the limit at once
    while stack:
        value, depth, where = stack.pop()
        if not isinstance(value, (dict, list, tuple)):
            continue
        if depth > MAX_NESTING:
            key = (f"[{where[0]}]" + (f" {where[1]}" if len(where) > 1 else "")) if where else "(scene)"
            raise SceneError(source, key, Shown(f"<tables or arrays nested more than {MAX_NESTING} deep>"),
                             f"tables and arrays may nest at most {MAX_NESTING} deep")
        items = value.items() if isinstance(value, dict) else enumerate(value)
        stack.extend((item, depth + 1, (*where, str(name))) for name, item in items)
