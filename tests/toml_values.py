"""A value of any type written as a TOML literal (the property tests that mutate actuator files use it)."""

from __future__ import annotations

import math


def toml_literal(v) -> str:
    """``v`` (bool, str, float, int, dict, list) as TOML text; strings are reduced to alphanumerics and ``_``,
    dicts and list entries that are dicts become a fixed inline table."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + "".join(c if c.isalnum() else "_" for c in v) + '"'
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, dict):
        return "{ x = 1 }"
    if isinstance(v, list):
        return "[" + ", ".join(toml_literal(x) if not isinstance(x, dict) else "{ a = 1 }" for x in v) + "]"
    return str(v)
