"""Reading and writing the TOML of switchest model files.

Reading uses the standard library's ``tomllib``. Writing needs only numbers,
strings, booleans, arrays and tables, so a small emitter does it: floats are
written with ``repr``, the shortest text that reads back to the same double,
which makes a round trip exact.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from ._checks import did_you_mean

__all__ = ["ModelFileError", "read", "dumps", "matrix", "number", "where", "unknown_key"]


class ModelFileError(ValueError):
    """A malformed model file; the message names the file, the table and the key."""


def where(source: str, key: str) -> str:
    """``"file.toml: modes[2].A"`` — the prefix of every model-file error."""
    return f"{source}: {key}"


def read(path: str | Path) -> dict:
    """Parse a TOML file, turning syntax errors into :class:`ModelFileError`."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError as exc:
        raise ModelFileError(f"{path}: no such model file") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ModelFileError(f"{path}: not valid TOML: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise ModelFileError(f"{path}: not a UTF-8 text file: {exc}") from None


def unknown_key(source: str, table: str, key, valid) -> ModelFileError:
    """The error for an unknown model-file key: file, table and key, and the closest valid key.

    A key differing only in case (``a`` for ``A``) or close in spelling (``v_mx``
    for ``v_max``: :func:`switchest._checks.closest_name`) is suggested.
    """
    valid, key = sorted(valid), str(key)
    hint = did_you_mean(key, valid, after=" ")
    at = f"{table}.{key}" if table else key
    expected = ", ".join(valid)
    return ModelFileError(where(source, f"{at}: unknown key; {hint}expected one of {expected}"))


def matrix(
    value, at: str, *, shape: tuple[int | None, int | None] | None = None, ndim: int = 2
) -> np.ndarray:
    """A finite numeric array from a TOML value, with the expected shape (None = any).

    Only TOML integers and floats are numbers: strings and booleans (which numpy
    would convert to ``-1.0`` or ``1.0``) are refused.
    """
    bad = _non_number(value)
    if bad is not None:
        raise ModelFileError(f"{at}: expected numbers, got {bad!r}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelFileError(f"{at}: expected a {'matrix' if ndim == 2 else 'vector'} of numbers, "
                             f"got {value!r}") from exc
    if arr.ndim != ndim:
        kind = "matrix (a list of rows)" if ndim == 2 else "vector (a list of numbers)"
        raise ModelFileError(f"{at}: expected a {kind}, got {arr.ndim} dimension(s)")
    if shape is not None:
        want = tuple(arr.shape[i] if s is None else s for i, s in enumerate(shape))
        if arr.shape != want:
            text = "x".join("?" if s is None else str(s) for s in shape)
            raise ModelFileError(f"{at}: expected {text}, got {'x'.join(map(str, arr.shape))}")
    if not np.all(np.isfinite(arr)):
        raise ModelFileError(f"{at}: entries must be finite numbers")
    return arr


def _non_number(value):
    """The first entry of a nested list that is not an int or float (a bool is not), or None."""
    if isinstance(value, (list, tuple)):
        for item in value:
            bad = _non_number(item)
            if bad is not None:
                return bad
        return None
    return value if isinstance(value, bool) or not isinstance(value, (int, float)) else None


def number(value, at: str, *, positive: bool = False) -> float:
    """A finite real number from a TOML value."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelFileError(f"{at}: expected a number, got {value!r}")
    if not np.isfinite(value) or (positive and value <= 0):
        raise ModelFileError(f"{at}: expected a finite {'positive ' if positive else ''}number, "
                             f"got {value!r}")
    return float(value)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, np.ndarray):
        return _value(v.tolist())
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def dumps(doc: dict, *, comment: str = "") -> str:
    """TOML text of ``doc``: top-level values, tables, then arrays of tables (lists of dicts)."""
    lines = [f"# {line}" for line in comment.splitlines()]
    plain = {k: v for k, v in doc.items() if not isinstance(v, dict) and not _is_table_list(v)}
    lines += [f"{k} = {_value(v)}" for k, v in plain.items()]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{kk} = {_value(vv)}" for kk, vv in v.items()]
    for k, v in doc.items():
        if _is_table_list(v):
            for item in v:
                lines += ["", f"[[{k}]]"] + [f"{kk} = {_value(vv)}" for kk, vv in item.items()]
    return "\n".join(lines).lstrip("\n") + "\n"


def _is_table_list(v) -> bool:
    return isinstance(v, list) and len(v) > 0 and all(isinstance(x, dict) for x in v)
