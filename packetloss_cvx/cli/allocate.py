"""``packetloss-cvx allocate FILE``: the cheapest channel qualities with J*(mu) <= alpha (§VI)."""

from __future__ import annotations

import argparse
from typing import Any

from ..allocation import allocate, parse_constraint
from ..errors import InfeasibleError, InputError
from . import format as fmt
from .actuator_section import actuator_strategies, membership_section
from .allocate_power import run as run_power  # power, the ack link priced
from .allocate_power import wants_power
from .allocate_stability import run_target
from .common import (
    CommandResult,
    allocation_numbers,
    attained_rows,
    progress_of,
    search_options,
    system_of,
    warning_advice,
)

__all__ = ["run"]

#: the API's argument names -> the flags that set them (errors are renamed to the flag)
FLAGS = {"alpha": "--alpha", "beta": "--beta", "bounds": "--bounds", "gap": "--gap", "max_boxes": "--max-boxes",
         "time_limit": "--time-limit", "target": "--target"}


def run(args: argparse.Namespace) -> CommandResult:
    """Exit 0 with status "optimal"; 4 with status "gap_not_certified" (a cap was hit: the
    allocation is feasible and its lower bound proven, but the gap is larger than asked; the
    result is printed on stdout as usual); 3 when proven infeasible.

    Examples
    --------
    One step of x' = x + v u from x0 = 1: J*_tcp(mu) = 1/(1 + mu) is <= 0.8 from mu = 1/4 on, and never below 1/2.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> parse = build_parser().parse_args
    >>> result = run(parse(["allocate", path, "--protocol", "tcp", "--alpha", "0.8", "--beta", "1"]))
    >>> result.code, result.data["status"], bool(abs(result.data["mu"][0] - 0.25) < 1e-4)
    (0, 'optimal', True)
    >>> result = run(parse(["allocate", path, "--protocol", "tcp", "--alpha", "0.4", "--beta", "1"]))
    >>> result.code, result.data["status"], round(result.data["min_cost"], 6)
    (3, 'infeasible', 0.5)
    >>> folder.cleanup()
    """
    if args.target in ("stable", "dp-cost") or (args.target is None and args.margin is not None):
        return run_target(args)                                 # design for stability: its own module
    if args.margin is not None:
        raise InputError("--margin", "applies to --target stable only")
    target = args.target or "paper"     # "attainable": the same program on the attainable cost (allocation.api)
    for flag, value in (("--ack-price", args.ack_price), ("--ack-power", args.ack_power)):
        if value is not None and args.protocol != "best":          # else ignored: the answer without the link
            raise InputError(flag, "prices the acknowledgement link, which only --protocol best compares")
    system = system_of(args)     # behind a chain: its mean rates, burstiness held (allocation/chains.py)
    if args.protocol == "best" or wants_power(args, system):
        if target == "attainable":
            raise InputError("--target", "attainable designs delivery probabilities priced by --beta with --protocol "
                                         "tcp|udp; the power designs and --protocol best report the attainable cost "
                                         "of their paper design")
        if system.channel is not None:
            raise InputError("channel", "power-limited links map power to independent (Bernoulli) delivery "
                                        "probabilities; this file has a Markov chain: give a file with [channel] mu")
        return run_power(args, system)
    if args.protocol is None:
        raise InputError("--protocol", "required (or --target stable|dp-cost to design for stability)")
    for flag, value in (("--alpha", args.alpha), ("--beta", args.beta)):
        if value is None:
            raise InputError(flag, "required" + (" (or buy power: --power)" if flag == "--beta" else ""))
    strategies = actuator_strategies(getattr(args, "actuator", None), system, args.protocol)
    alpha, beta, bounds = allocation_numbers(args, system.m)
    options: dict[str, Any] = {}       # unset flags keep the API's defaults (one source of truth)
    options.update(search_options(args))
    constraints = [parse_constraint(text, system.m, "--constraint") for text in args.constraint or []]
    options["progress"] = progress_of(args)
    try:
        result = allocate(system, args.protocol, alpha, beta, bounds=tuple(bounds), constraints=constraints,
                          target=target, **options)
    except InputError as err:
        raise err.renamed(FLAGS[err.field]) if err.field in FLAGS else err from None
    except InfeasibleError as err:
        data = {"protocol": args.protocol, "alpha": alpha, "beta": beta, "mu": None, "communication_cost": None,
                "cost": None, "lower_bound": None, "gap": None, "status": "infeasible", "method": None,
                "boxes": None, "min_cost": err.min_cost, "basis": "paper", "attainable_cost": None,
                "attainable_note": "", "stabilisable": None, "stability_note": "no allocation"}
        return CommandResult(data, f"infeasible: {err}", 3)
    data = {**result.to_dict(), "min_cost": None}
    rows = [("mu*", fmt.numbers(result.mu)), ("beta'mu", fmt.num(result.communication_cost)),
            (f"J*(mu*), {result.basis}", f"{fmt.num(result.cost, 10)} <= alpha = {fmt.num(alpha)}"),
            *attained_rows(result),
            ("lower bound", f"{fmt.num(result.lower_bound)} on beta'mu (proved)"),
            ("gap", f"{result.gap:.1e}"),
            ("method", result.method + (f", {result.boxes} box" + ("es" if result.boxes > 1 else "")
                                        if result.boxes else ""))]
    if strategies:                  # the allocation under each actuator strategy on a loss: stabilisable at mu*?
        data["actuator"], more = membership_section(system, strategies, result.mu, args.protocol)
        rows += more
    name = fmt.name(system.name or args.file)
    warning = [] if result.warning is None else [result.warning + warning_advice(result, system.channel, args.file)]
    if result.status == "optimal":
        on = " on the attainable cost" if result.basis == "attainable" and args.protocol == "tcp" else ""
        return CommandResult(data, "\n".join([f"{args.protocol.upper()}-like: optimal allocation{on} for {name}"]
                                             + fmt.fields(rows) + warning))
    advice = ("raise --max-boxes or --time-limit, or --gap" if args.protocol == "udp" else
              "the TCP-like SOCP's certificate is limited by the solver's accuracy: ask for a larger --gap")
    heading = (f"{args.protocol.upper()}-like: GAP NOT CERTIFIED, allocation for {name} (gap reached "
               f"{result.gap:.1e} > the requested gap)")
    return CommandResult(data, "\n".join([heading] + fmt.fields(rows + [("advice", advice)]) + warning), 4)

