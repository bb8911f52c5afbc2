"""A scenario given as a Python dict, written as the TOML text ncosim reads.

Tables are dicts, arrays of tables are lists of dicts (``[[sensor]]``), matrices are lists of
lists or NumPy arrays; NumPy scalars and arrays are taken as their Python values.
"""
import json
import math
import re

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _plain(v):
    """NumPy arrays and scalars as Python lists and numbers; everything else as it is."""
    if hasattr(v, "tolist") and not isinstance(v, (str, bytes)):
        return v.tolist()
    return v


def key(k):
    if not isinstance(k, str):
        raise TypeError(f"a scenario key must be a string, got {k!r}")
    return k if _BARE.fullmatch(k) else _string(k)


def _string(s):
    text = json.dumps(s, ensure_ascii=False)
    # TOML forbids DEL and other control characters unescaped (json leaves DEL as it is).
    return "".join(f"\\u{ord(c):04x}" if ord(c) == 0x7F else c for c in text)


def value(v, where="value"):
    """One TOML value (inline)."""
    v = _plain(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        if not -2**63 <= v < 2**63:
            from ._api import ScenarioError
            raise ScenarioError(f"{where}: expected an integer TOML can hold (-2**63 .. 2**63 - 1), "
                                f"got {v}")
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, dict):
        return "{" + ", ".join(f"{key(k)} = {value(x, f'{where}.{k}')}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(value(x, f"{where}[{i}]") for i, x in enumerate(v)) + "]"
    if v is None:
        raise TypeError(f"{where}: None has no TOML form (leave the key out for its default)")
    raise TypeError(f"{where}: expected a number, string, bool, list or dict, got {type(v).__name__}")


def _is_table_array(v):
    v = _plain(v)
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def _table(lines, path, d):
    # Plain keys first, then sub-tables, then arrays of tables (TOML's order).
    for k, v in d.items():
        if not isinstance(v, dict) and not _is_table_array(v):
            lines.append(f"{key(k)} = {value(v, '.'.join(path + [k]))}")
    for k, v in d.items():
        if isinstance(v, dict):
            sub = path + [key(k)]
            lines.append(f"\n[{'.'.join(sub)}]")
            _table(lines, sub, v)
    for k, v in d.items():
        if _is_table_array(v):
            sub = path + [key(k)]
            for t in _plain(v):
                lines.append(f"\n[[{'.'.join(sub)}]]")
                _table(lines, sub, t)


def dumps(d):
    """The TOML text of a scenario dict."""
    if not isinstance(d, dict):
        raise TypeError(f"a scenario must be a dict, a TOML string or a path, got {type(d).__name__}")
    lines = []
    _table(lines, [], d)
    return "\n".join(lines).lstrip("\n") + "\n"
