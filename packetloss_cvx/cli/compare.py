"""``packetloss-cvx compare FILE``: the actuator strategies on a loss side by side (zero, hold, buffered plan)."""

from __future__ import annotations

import argparse

from ..errors import InputError
from ..tolerances import ACTUATOR_COMPARE_TOL
from . import format as fmt
from .actuator_section import actuator_strategies, design_section
from .common import CommandResult, floats, system_of

__all__ = ["run"]


def run(args: argparse.Namespace) -> CommandResult:
    """Per strategy the optimal TCP-like law's radius and costs and the strategy's critical mu along the ray
    (cli.actuator_section.design_section).

    Examples
    --------
    One state, x' = 2x + v u: every strategy stabilises iff mu > 1 - 1/a^2 = 0.75.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> result = run(build_parser().parse_args(["compare", path, "--actuator", "zero,buffer:2", "-q"]))
    >>> result.code, [abs(result.data["strategies"][a]["critical"]["t"] - 0.75) <= 1e-4 for a in ("zero", "buffer:2")]
    (0, [True, True])
    >>> folder.cleanup()
    """
    system = system_of(args)
    strategies = actuator_strategies(args.actuator, system)
    direction = None
    if args.direction is not None:
        direction = floats(args.direction, "--direction")
        if len(direction) != system.m or any(v < 0 for v in direction) or not any(v > 0 for v in direction):
            raise InputError("--direction", f"expected {system.m} nonnegative numbers, not all zero, found "
                                            f"{args.direction[:60]!r}")
    data, lines = design_section(system, strategies, direction, ACTUATOR_COMPARE_TOL)
    heading = (f"actuator strategies on a loss for {fmt.name(system.name or args.file)}: the optimal TCP-like law "
               f"of each (radius, average stage cost under the noise, noise-free cost from x0 over an infinite "
               f"horizon) and its critical mu")
    return CommandResult({"name": system.name, "strategies": data}, "\n".join([heading, *lines]))
