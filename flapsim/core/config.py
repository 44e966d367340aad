"""Frozen parameter dataclasses read from TOML tables and written back as TOML.

A configuration class is a frozen dataclass of plain fields (bool, int, float, str) with a
docstring line under each field. :func:`read_toml` reads a file's tables,
:func:`from_table` builds an instance from one table over a base instance (the keys left
out keep the base's values; an unknown key or a value of the wrong type is a one-line
:class:`~flapsim.core.errors.DataFileError` naming the key and the fix), and
:func:`to_toml` writes an instance back with each field's docstring as a comment, so that
what it prints can be copied, edited and read again.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import textwrap
import tomllib
from collections.abc import Iterable, Mapping
from functools import cache
from pathlib import Path
from typing import Any

from flapsim.core.errors import DataFileError, InputError
from flapsim.core.validate import require_finite


def read_toml(path: str | Path, tables: Iterable[str]) -> dict[str, dict]:
    """The tables of the TOML file ``path`` (each a dict; a table left out: empty). Anything
    at the top level other than the ``tables`` named is refused with a one-line error."""
    path = Path(path)
    tables = tuple(tables)
    try:
        raw = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise DataFileError(f"{path}: no such file (flapsim list config prints one to copy)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(f"{path}: cannot be read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise DataFileError(f"{path}: not valid TOML ({exc})") from None
    require_finite(raw, path, fix="write a finite number (flapsim list config prints the defaults)")
    for key, value in raw.items():
        if key not in tables or not isinstance(value, dict):
            raise DataFileError(f"{path}: unknown top-level key {key!r}; the file holds the "
                                f"tables {', '.join(f'[{t}]' for t in tables)} "
                                "(flapsim list config prints them)")
    return {t: raw.get(t, {}) for t in tables}


def _kind(value: Any) -> type:
    return bool if isinstance(value, bool) else type(value)


def from_table(base: Any, table: Mapping[str, Any], where: str) -> Any:
    """``base`` with the fields ``table`` gives replaced (:func:`dataclasses.replace`).
    ``where`` names the table in errors (``file.toml [controller]``). A key that is not a
    field, or a value whose type is not the field's (an integer is a float where a float is
    asked), is a one-line :class:`DataFileError`; the class's own checks run on the result."""
    known = {f.name: f for f in dataclasses.fields(base)}
    given = {}
    for key, value in table.items():
        if key not in known:
            raise DataFileError(f"{where}: unknown key {key!r}; known keys: {', '.join(known)} "
                                "(flapsim list config prints them with their meaning)")
        want = _kind(getattr(base, key))
        have = _kind(value)
        if want is float and have is int:
            value = float(value)
        elif have is not want:
            raise DataFileError(f"{where}: {key} must be {_NAMES.get(want, want.__name__)}, got "
                                f"{value!r} ({_NAMES.get(have, have.__name__)}); write it as "
                                f"{key} = {_toml_value(getattr(base, key))}")
        given[key] = value
    try:
        return dataclasses.replace(base, **given)
    except InputError as exc:  # a value out of range: say which file holds it
        raise DataFileError(f"{where}: {exc}") from None


_NAMES = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}


@cache
def field_docs(cls: type) -> dict[str, str]:
    """Each field's docstring (the string literal under it in the class), on one line."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body
    out = {}
    for node, nxt in zip(body, body[1:], strict=False):
        if (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                and isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)):
            text = " ".join(nxt.value.value.split())
            out[node.target.id] = text
    return out


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf" if v < 0 else "nan")
    if isinstance(v, int):
        return str(v)
    return '"' + str(v).replace("\\", "\\\\").replace('"', '\\"') + '"'


def to_toml(obj: Any, table: str, notes: Mapping[str, str] | None = None) -> str:
    """``obj``'s fields as the TOML table ``[table]``, each under its docstring as a comment
    (``notes``: more words after a field's value, such as another dove's default)."""
    docs = field_docs(type(obj))
    notes = notes or {}
    lines = [f"[{table}]"]
    for f in dataclasses.fields(obj):
        if docs.get(f.name):
            lines.extend("# " + line for line in textwrap.wrap(docs[f.name], 86))
        note = f"  # {notes[f.name]}" if f.name in notes else ""
        lines.append(f"{f.name} = {_toml_value(getattr(obj, f.name))}{note}")
    return "\n".join(lines) + "\n"
