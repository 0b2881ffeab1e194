"""System files: the TOML schema of docs/design.md §4, reading, writing, and the examples
shipped with the package (``packetloss_cvx/examples/*.toml``, read with importlib.resources).
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .errors import InputError
from .model import System

__all__ = ["load_system", "system_from_dict"]


# TOML section -> {key: System keyword}
_SCHEMA: dict[str, dict[str, str]] = {
    "plant": {"A": "A", "B": "B", "noise_cov": "noise_cov"},
    "cost": {
        "horizon": "horizon", "state_weight": "state_weight", "state_weights": "state_weights",
        "input_weight": "input_weight", "input_weights": "input_weights",
        "initial_weight": "initial_weight",
    },
    "channel": {"mu": "mu", "mu_schedule": "mu_schedule"},
    "state": {"x0": "x0"},
}
_REQUIRED = {"plant": ("A", "B"), "cost": ("horizon",), "channel": (), "state": ("x0",)}


def system_from_dict(data: Mapping[str, Any]) -> System:
    """Build a :class:`System` from the TOML schema's structure (see docs/design.md §4).

    Errors name the TOML path of the offending field (``cost.state_weight``).
    """
    if not isinstance(data, Mapping):
        raise InputError("<file>", "expected a table")
    for key in data:
        if key != "name" and key not in _SCHEMA:
            raise InputError(str(key), f"unknown section; expected one of name, {', '.join(_SCHEMA)}")
    kwargs: dict[str, Any] = {"name": data.get("name")}
    where: dict[str, str] = {"name": "name"}
    for section, keys in _SCHEMA.items():
        if section not in data:
            raise InputError(section, "missing section")
        table = data[section]
        if not isinstance(table, Mapping):
            raise InputError(section, "expected a table")
        for key in table:
            if key not in keys:
                raise InputError(f"{section}.{key}", f"unknown key; expected one of {', '.join(keys)}")
        for key in _REQUIRED[section]:
            if key not in table:
                raise InputError(f"{section}.{key}", "missing field")
        for key, kw in keys.items():
            if key in table:
                kwargs[kw] = table[key]
                where[kw] = f"{section}.{key}"
    try:
        return System(**kwargs)
    except InputError as err:
        raise err.renamed(_toml_field(err.field, where)) from None


def _toml_field(field: str, where: Mapping[str, str]) -> str:
    if "/" in field:  # a paired key
        first, second = field.split("/")
        section = where.get(first, where.get(second, "")).split(".")[0] or _section_of(first)
        return f"{section}.{first}/{second}"
    base, bracket, rest = field.partition("[")
    return where.get(base, f"{_section_of(base)}.{base}") + bracket + rest


def _section_of(kw: str) -> str:
    for section, keys in _SCHEMA.items():
        if kw in keys.values():
            return section
    return kw


def load_system(path: str | Path) -> System:
    """Read a system file in the TOML schema of docs/design.md §4.

    Raises
    ------
    InputError
        Missing or unreadable file (field ``file``), invalid TOML, or any field
        that fails validation (named by its TOML path).
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise InputError("file", f"no such file: {path}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError("file", f"cannot read {path}: {err}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise InputError("file", f"{path} is not valid TOML: {err}") from None
    return system_from_dict(data)

