"""``packetloss-cvx allocate FILE``: the cheapest channel qualities with J*(mu) <= alpha (§VI)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..allocation import allocate, parse_constraint
from ..errors import InfeasibleError, InputError
from ..io import load_system
from .common import CommandResult, floats, number

__all__ = ["run"]

#: the API's argument names -> the flags that set them (errors are renamed to the flag)
FLAGS = {"alpha": "--alpha", "beta": "--beta", "bounds": "--bounds", "gap": "--gap", "max_boxes": "--max-boxes",
         "time_limit": "--time-limit"}


def run(args: argparse.Namespace) -> CommandResult:
    """Exit 0 with status "optimal"; 4 with status "gap_not_certified" (a cap was hit: the
    allocation is feasible and its lower bound proven, but the gap is larger than asked; the
    result is printed on stdout as usual); 3 when proven infeasible."""
    system = load_system(args.file)
    alpha = number(args.alpha, "--alpha")
    beta = floats(args.beta, "--beta")
    if len(beta) != system.m:
        raise InputError("--beta", f"expected {system.m} comma-separated numbers, found {len(beta)}")
    bounds = floats(args.bounds, "--bounds")
    if len(bounds) != 2:
        raise InputError("--bounds", f"expected lo,hi, found {args.bounds[:40]!r}")
    options: dict[str, Any] = {}       # unset flags keep the API's defaults (one source of truth)
    if args.gap is not None:
        options["gap"] = number(args.gap, "--gap")
    if args.max_boxes is not None:
        options["max_boxes"] = args.max_boxes
    if args.time_limit is not None:
        options["time_limit"] = number(args.time_limit, "--time-limit")
    constraints = [parse_constraint(text, system.m) for text in args.constraint or []]
    try:
        result = allocate(system, args.protocol, alpha, beta, bounds=tuple(bounds), constraints=constraints,
                          **options)
    except InputError as err:
        raise err.renamed(FLAGS[err.field]) if err.field in FLAGS else err from None
    except InfeasibleError as err:
        data = {"protocol": args.protocol, "alpha": alpha, "beta": beta, "mu": None, "communication_cost": None,
                "cost": None, "lower_bound": None, "gap": None, "status": "infeasible", "method": None,
                "boxes": None, "min_cost": err.min_cost}
        return CommandResult(data, f"infeasible: {err}", 3)
    data = {**result.to_dict(), "min_cost": None}
    line = (f"mu* = {np.round(result.mu, 6).tolist()}, beta'mu = {result.communication_cost:.6g}, J*(mu*) = "
            f"{result.cost:.6g} <= {alpha:g}, lower bound {result.lower_bound:.6g}")
    if result.status == "optimal":
        return CommandResult(data, f"{args.protocol.upper()}-like: {line} (gap {result.gap:.1e}; {result.method})")
    advice = ("raise --max-boxes or --time-limit, or --gap" if args.protocol == "udp" else
              "the TCP-like SOCP's certificate is limited by the solver's accuracy: ask for a larger --gap")
    text = (f"{args.protocol.upper()}-like: GAP NOT CERTIFIED: {line}; gap reached {result.gap:.1e} > the "
            f"requested gap ({result.method}); {advice}")
    return CommandResult(data, text, 4)
