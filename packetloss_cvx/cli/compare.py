"""``packetloss-cvx compare FILE``: the actuator strategies on a loss side by side (zero, hold, buffered plan)."""

from __future__ import annotations

import argparse
from typing import Any

from ..allocation.api import cheapest_links
from ..closedloop.actuator_design import check_protocol
from ..errors import InputError, UnobservedModeError
from ..tolerances import ACTUATOR_COMPARE_TOL, ALLOCATION_GAP_DEFAULT
from . import format as fmt
from .actuator_section import actuator_strategies, design_section
from .common import CommandResult, floats, number, system_of

__all__ = ["run"]

_FLAGS = {"alpha": "--target", "beta": "--beta", "gap": "--gap"}


def run(args: argparse.Namespace) -> CommandResult:
    """Per strategy the optimal law's radius and costs and the strategy's critical mu along the ray
    (cli.actuator_section.design_section), for the ``--protocol``'s controller: TCP-like, every strategy; UDP-like,
    the strategies whose TCP-like optimal law it can run (closedloop.actuator_design.check_protocol: then it is its
    optimum too), the others' rows giving the reason (a strategy named with ``--actuator`` is refused instead).

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
    protocol = getattr(args, "protocol", "tcp")
    named = args.actuator.strip().lower() != "all"     # named strategies a UDP-like controller cannot run: refused
    strategies = actuator_strategies(args.actuator, system, protocol if named else "tcp")
    unrunnable: dict[str, str] = {}
    for strategy in strategies:
        try:
            check_protocol(system, strategy, protocol)
        except UnobservedModeError as err:
            unrunnable[str(strategy)] = err.detail
    runnable = tuple(s for s in strategies if str(s) not in unrunnable)
    direction = None
    if args.direction is not None:
        direction = floats(args.direction, "--direction")
        if len(direction) != system.m or any(v < 0 for v in direction) or not any(v > 0 for v in direction):
            raise InputError("--direction", f"expected {system.m} nonnegative numbers, not all zero, found "
                                            f"{args.direction[:60]!r}")
    links, target = None, None
    if args.target is not None:
        target = number(args.target, "--target")
        beta = None if args.beta is None else floats(args.beta, "--beta")
        try:
            links = cheapest_links(system, target, beta, runnable, gap=ALLOCATION_GAP_DEFAULT if args.gap is None
                                   else number(args.gap, "--gap")) if runnable else {}
        except InputError as err:
            raise err.renamed(_FLAGS[err.field]) if err.field in _FLAGS else err from None
    elif args.beta is not None or args.gap is not None:
        raise InputError("--beta" if args.beta is not None else "--gap", "applies with --target only")
    data, lines = design_section(system, runnable, direction, ACTUATOR_COMPARE_TOL, links)
    for name, reason in unrunnable.items():     # the strategies whose optimal law this controller cannot run
        data[name] = {"radius": None, "average_stage_cost": None, "initial_cost": None, "critical": None,
                      "reason": reason}
        lines.append(f"{name}: no {protocol.upper()}-like optimal law: {reason}")
    heading = (f"actuator strategies on a loss for {fmt.name(system.name or args.file)}: the optimal "
               f"{protocol.upper()}-like law "
               f"of each (radius, average stage cost under the noise, noise-free cost from x0 over an infinite "
               f"horizon: the law's costs in its loop [basis: loop]) and its critical mu")
    out: dict[str, Any] = {"name": system.name, "protocol": protocol, "strategies": data}
    if links:
        basis = next(iter(links.values()))["basis"]
        prices = next(iter(links.values()))["beta"]
        out["target"] = {"alpha": target, "basis": basis, "beta": prices}
        heading += (f"; the cheapest links (min beta'mu, beta = {fmt.numbers(prices)}) at which its optimal law's "
                    f"{'average stage cost' if basis == 'average' else 'total noise-free cost from x0'} is <= "
                    f"{fmt.num(target)}" + (" (* gap not certified)" if any(
                        row.get("status") == "gap_not_certified" for row in links.values()) else ""))
    return CommandResult(out, "\n".join([heading, *lines]))
