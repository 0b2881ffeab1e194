"""Helpers the subcommands share: number lists, the file's overrides, the result a command returns.

Imported only when a subcommand runs (the parser itself stays light, docs/design.md §4).
"""

from __future__ import annotations

import argparse
from typing import Any, NamedTuple

from ..errors import InputError
from ..model import System

__all__ = ["CommandResult", "floats", "number", "with_overrides"]


class CommandResult(NamedTuple):
    """What a subcommand returns: the JSON object, the text, and the exit code (0 unless said)."""

    data: dict[str, Any]
    text: str
    code: int = 0


def floats(text: str, field: str) -> list[float]:
    """``"1,-2.5"`` -> ``[1.0, -2.5]``; anything else is an :class:`InputError` naming ``field``."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        raise InputError(field, f"expected comma-separated numbers, found {text!r}") from None
    return values


def number(text: str, field: str) -> float:
    """Exactly one number."""
    values = floats(text, field)
    if len(values) != 1:
        raise InputError(field, f"expected one number, found {text[:40]!r}")
    return values[0]


def with_overrides(system: System, args: argparse.Namespace) -> System:
    """The file's system with ``--mu`` and ``--x0`` applied, errors renamed to the flag."""
    if getattr(args, "mu", None) is not None:
        try:
            system = system.with_mu(floats(args.mu, "--mu"))
        except InputError as err:
            raise err.renamed("--mu") from None
    if getattr(args, "x0", None) is not None:
        try:
            system = system.with_x0(floats(args.x0, "--x0"))
        except InputError as err:
            raise err.renamed("--x0") from None
    return system
