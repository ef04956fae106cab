"""TOML text of a configuration given as a dict.

A configuration built in a notebook (``sweep.run({"design": {...}, "outputs": {...}})``)
is validated exactly as a file is: it is written as TOML text here and parsed by
:func:`sweep.sweeps.config.loads`, so a dict and the equivalent file give the same
configuration, the same hash, the same errors, and the text stored in the dataset's
``sweep_config`` attribute runs again with ``sweep run``.

Owns :func:`dumps`, a writer for the subset of TOML a configuration uses: tables, strings,
integers, floats, booleans, arrays and inline tables (no dates). Top-level tables become
``[section]`` headers, tables holding tables nested sections, other tables inline
(``gamma = {start = 0.0, stop = 0.1, num = 1000}``).

Floor 4: imports numpy (its scalars and arrays are accepted) and nothing of the package.
"""
from __future__ import annotations

import json
import math
import numbers
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["dumps", "TomlValueError"]

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


class TomlValueError(ValueError):
    """A value that TOML cannot hold (None, an object); the message names its key."""


def _key(key: Any, where: str) -> str:
    if not isinstance(key, str):
        raise TomlValueError(f"{where}: keys must be strings, got {key!r}")
    return key if _BARE_KEY.fullmatch(key) else _string(key)


def _string(text: str) -> str:
    # JSON escapes quotes, backslashes and control characters as TOML does; TOML also
    # forbids a raw DEL.
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007F")


def _value(value: Any, where: str) -> str:
    """One value, inline."""
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, (bool, np.bool_)):  # before the integers: bools are ints
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        value = float(value)
        if math.isnan(value):
            return "nan"
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_key(k, where)} = {_value(v, f'{where}.{k}')}"
                               for k, v in value.items()) + "}"
    if isinstance(value, (Sequence, np.ndarray)):  # lists, tuples, arrays
        items = value.tolist() if isinstance(value, np.ndarray) else list(value)
        if not isinstance(items, list):  # a 0-d array
            return _value(items, where)
        return "[" + ", ".join(_value(v, f"{where}[{i}]") for i, v in enumerate(items)) + "]"
    raise TomlValueError(f"{where}: TOML has no value for {type(value).__name__} {value!r}")


def _is_section(value: Any, top: bool) -> bool:
    """Write ``value`` as a ``[section]``: a top-level table, or one that holds tables."""
    return isinstance(value, Mapping) and (top or any(isinstance(v, Mapping)
                                                      for v in value.values()))


def _table(path: tuple, table: Mapping, lines: list) -> None:
    sections = []
    for key, value in table.items():
        where = ".".join(path + (str(key),))
        if _is_section(value, top=not path):
            sections.append((key, value))
        else:
            lines.append(f"{_key(key, where)} = {_value(value, where)}")
    for key, value in sections:
        sub = path + (key,)
        lines.append("")
        lines.append("[" + ".".join(_key(k, ".".join(map(str, sub))) for k in sub) + "]")
        _table(sub, value, lines)


def dumps(data: Mapping[str, Any]) -> str:
    """TOML text of ``data``.

    Parameters
    ----------
    data : mapping
        Keys are strings; values strings, numbers and booleans (numpy scalars too),
        sequences (numpy arrays too) and mappings.

    Returns
    -------
    str
        A TOML document that ``tomllib.loads`` reads back as ``data`` (tuples and arrays
        as lists, numpy scalars as Python numbers).

    Raises
    ------
    TomlValueError
        A value TOML cannot hold (e.g. None), or a key that is not a string; the message
        names the dotted key.
    """
    if not isinstance(data, Mapping):
        raise TomlValueError(f"a configuration must be a mapping, got {type(data).__name__}")
    lines: list[str] = []
    _table((), data, lines)
    return "\n".join(lines).lstrip("\n") + "\n"
