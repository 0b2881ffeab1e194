"""``packetloss-cvx allocate FILE --target stable|dp-cost``: the cheapest channel qualities for which some linear
law holds the loop with a margin, or whose DP law costs at most alpha (allocation.stability)."""

from __future__ import annotations

import argparse
from typing import Any

from ..allocation import parse_constraint
from ..allocation.stability import LINE_METHOD, stability_allocate
from ..errors import InfeasibleError, InputError
from . import format as fmt
from .common import (
    CommandResult,
    attained_rows,
    number,
    prices_and_bounds,
    progress_of,
    search_options,
    system_of,
)

__all__ = ["run_target"]

#: the API's argument names -> the flags that set them (errors are renamed to the flag)
FLAGS = {"alpha": "--alpha", "beta": "--beta", "bounds": "--bounds", "gap": "--gap", "max_boxes": "--max-boxes",
         "time_limit": "--time-limit", "margin": "--margin", "target": "--target"}


def run_target(args: argparse.Namespace) -> CommandResult:
    """Exit 0 with status "optimal"; 4 with "gap_not_certified" (a cap was hit; the channel is certified and
    its lower bound proved); 3 when proved infeasible; 2 for bad input (a margin outside (0, 1], --margin
    without --target stable, --protocol with --target).

    Examples
    --------
    One state, x+ = 2 x + v u: radius 4 (1 - mu) < 1 from mu = 3/4 on, < 0.5 from 7/8 on.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> parse = build_parser().parse_args
    >>> result = run_target(parse(["allocate", path, "--target", "stable", "--margin", "0.5", "--beta", "1"]))
    >>> result.code, result.data["status"], bool(abs(result.data["mu"][0] - 0.875) < 1e-4)
    (0, 'optimal', True)
    >>> result = run_target(parse(["allocate", path, "--target", "stable", "--beta", "1", "--bounds", "0,0.7"]))
    >>> result.code, result.data["status"]
    (3, 'infeasible')
    >>> folder.cleanup()
    """
    if args.target is None:
        raise InputError("--margin", "applies to --target stable only")
    if args.protocol is not None:
        raise InputError("--protocol", "the paper's protocols (J* <= alpha) and --target (closed-loop design) are "
                                       "two questions: give one of them")
    if args.target == "stable" and args.alpha is not None:
        raise InputError("--alpha", "--target stable bounds the mean-square radius (--margin), not a cost")
    if args.target == "dp-cost" and args.alpha is None:
        raise InputError("--alpha", "--target dp-cost needs the bound on the DP law's stationary cost")
    if args.target == "dp-cost" and args.margin is not None:
        raise InputError("--margin", "applies to --target stable only (dp-cost bounds the cost: --alpha)")
    for flag in ("--power", "--power-scale", "--power-table", "--budget", "--power-max", "--ack-price", "--ack-power"):
        if getattr(args, flag[2:].replace("-", "_")) is not None:      # else ignored: a beta'mu design, unasked
            raise InputError(flag, "--target designs delivery probabilities priced by --beta; power and the "
                                   "acknowledgement link are options of --protocol")
    if args.beta is None:
        raise InputError("--beta", "required: the price of each channel's delivery probability, e.g. --beta 1,1")
    system = system_of(args)
    beta, bounds = prices_and_bounds(args, system.m)
    options: dict[str, Any] = {}
    if args.margin is not None:
        options["margin"] = number(args.margin, "--margin")
    if args.alpha is not None:
        options["alpha"] = number(args.alpha, "--alpha")
    options.update(search_options(args))
    constraints = [parse_constraint(text, system.m, "--constraint") for text in args.constraint or []]
    try:
        result = stability_allocate(system, args.target, beta, bounds=tuple(bounds), constraints=constraints,
                                    progress=progress_of(args), **options)
    except InputError as err:
        raise err.renamed(FLAGS[err.field]) if err.field in FLAGS else err from None
    except InfeasibleError as err:
        data = {"target": args.target, "mu": None, "cost": None, "lower_bound": None, "gap": None,
                "status": "infeasible", "radius": None, "radius_bound": options.get("margin"), "gain": None,
                "dp_cost": None, "dp_cost_kind": None, "alpha": options.get("alpha"), "beta": beta, "boxes": None,
                "method": None}
        return CommandResult(data, f"infeasible: {err}", 3)
    data = result.to_dict()
    goal = (f"mean-square radius < {fmt.num(result.radius_bound)}" if args.target == "stable"
            else f"DP law's loop cost <= alpha = {fmt.num(result.alpha)}")
    rows = [("mu*", fmt.numbers(result.mu)), ("beta'mu", fmt.num(result.cost)),
            ("lower bound", f"{fmt.num(result.lower_bound)} on beta'mu (proved)"),
            ("gap", f"{result.gap:.1e}"),
            ("radius", f"{fmt.num(result.radius, 10)} < {fmt.num(result.radius_bound)} ("
                       + ("the least-radius gain" if args.target == "stable" else "the DP law") + ", checked)"),
            ("DP cost, loop", (result.dp_cost_note or "not reported") if result.dp_cost_kind == "" else
             f"{fmt.num(result.dp_cost, 10)} ({result.dp_cost_kind})"),
            attained_rows(result)[0],
            ("method", result.method if result.method.startswith(LINE_METHOD) else
             f"{result.method}, {result.boxes} box" + ("es" if result.boxes != 1 else ""))]
    name = fmt.name(system.name or args.file)
    if result.status == "optimal":
        return CommandResult(data, "\n".join([f"design for {goal}: optimal channel for {name}"] + fmt.fields(rows)))
    heading = (f"design for {goal}: GAP NOT CERTIFIED, channel for {name} (gap reached {result.gap:.1e} > the "
               "requested gap)")
    advice = ("--gap at the gap reached accepts this channel: the memberships in the band are undecided, and more "
              "time does not decide them" if result.method.startswith(LINE_METHOD) and "undecided" in result.method
              else "raise --max-boxes or --time-limit, or --gap")
    return CommandResult(data, "\n".join([heading] + fmt.fields(rows + [("advice", advice)])), 4)
