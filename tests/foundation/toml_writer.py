"""A tiny TOML writer for the loader tests: every value inline, every key quoted.

It covers the subset case files use (tables, arrays, strings, numbers including nan and inf,
booleans). Kept in the tests because it writes malformed cases on purpose, which a library
writer would refuse.
"""

from __future__ import annotations


def _toml_str(s: str) -> str:
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)  # 'nan', 'inf', '-inf', '1e-05' are all TOML floats
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_str(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(case: dict) -> str:
    return "".join(f"{_toml_str(k)} = {toml_value(v)}\n" for k, v in case.items())
