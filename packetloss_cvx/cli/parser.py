"""The command line's grammar: argparse only, no numerical import (``--help`` stays fast).

Each subcommand names the module of this package that runs it (``command="solve"`` ->
``packetloss_cvx.cli.solve.run``); :func:`packetloss_cvx.cli.main` imports that module only
when the command runs. A new subcommand adds its ``add_parser`` block here and its module.
"""

from __future__ import annotations

import argparse
import re

from ..errors import InputError

__all__ = ["NUMBER_LISTS", "build_parser", "join_negative_values"]

#: Options whose value is a comma-separated list of numbers that may start with a minus sign.
NUMBER_LISTS = ("--mu", "--x0", "--beta", "--bounds", "--alpha")


class Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise InputError("arguments", message)


def build_parser() -> argparse.ArgumentParser:
    """The whole grammar; ``args.command`` names the module that runs the subcommand."""
    parser = Parser(prog="packetloss-cvx",
                    description="Optimal control over multichannel packet-loss links, cross-checked (docs/design.md).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    solve = sub.add_parser("solve", help="optimal plans, costs and gains, cross-checked by a QP")
    solve.add_argument("file")
    solve.add_argument("--protocol", choices=("tcp", "udp", "both"), default="both")
    solve.add_argument("--mu", help="override the channel: comma-separated, one per actuator")
    solve.add_argument("--x0", help="override the initial state: comma-separated")
    solve.add_argument("--method", choices=("dense", "recursion", "auto"), default="auto")
    solve.add_argument("--formulation", choices=("condensed", "sparse", "auto"), default="auto")
    solve.add_argument("--no-qp", action="store_true", help="skip the solver cross-check")
    solve.add_argument("--json", action="store_true", help="print one JSON object")

    aud = sub.add_parser("audit", help="check every claim of the paper on its systems and random ones")
    aud.add_argument("files", nargs="*", metavar="FILE", help="more systems to check the claims on")
    aud.add_argument("--random", type=int, default=50, help="seeded random systems (default 50)")
    aud.add_argument("--seed", type=int, default=0,
                     help="seeds the random systems, the samples and the shrinking (integer >= 0, default 0)")
    aud.add_argument("--claim", action="append", help="check only this claim id (repeatable)")
    aud.add_argument("--report", action="store_true", help="Markdown report with notes and counterexamples")
    aud.add_argument("--json", action="store_true", help="print one JSON object")

    alloc = sub.add_parser("allocate", help="cheapest channel qualities with J*(mu) <= alpha")
    alloc.add_argument("file")
    alloc.add_argument("--protocol", choices=("tcp", "udp"), required=True)
    alloc.add_argument("--alpha", required=True, help="bound on the optimal expected cost")
    alloc.add_argument("--beta", required=True, help="price of each channel, comma-separated")
    alloc.add_argument("--bounds", default="0,1", help="lo,hi for every mu_i (default 0,1)")
    alloc.add_argument("--constraint", action="append",
                       help='linear constraint, e.g. "mu1 + 2*mu2 <= 1.5" or "mu1 >= mu2" (repeatable)')
    alloc.add_argument("--gap", help="relative optimality gap to certify, 1e-9 <= G < 1 (default 1e-4)")
    alloc.add_argument("--max-boxes", type=int,
                       help="cap on the UDP-like branch and bound's boxes (default 20000); at the cap: exit 4")
    alloc.add_argument("--time-limit", help="cap in seconds on the UDP-like branch and bound; at the cap: exit 4")
    alloc.add_argument("--json", action="store_true", help="print one JSON object")

    sim = sub.add_parser("simulate", help="Monte Carlo against the exact expectations, open and closed loop")
    sim.add_argument("file")
    sim.add_argument("--samples", type=int, default=10000, help="sampled runs (>= 2, default 10000)")
    sim.add_argument("--steps", type=int, default=50, help="closed-loop steps T (default 50)")
    sim.add_argument("--seed", type=int, default=0, help="seeds every random stream (integer >= 0, default 0)")
    sim.add_argument("--closed-loop", action="store_true",
                     help="also run the laws u = -K x in closed loop (stationary channel)")
    sim.add_argument("--law", choices=("tcp", "udp", "dp", "all"), default="all",
                     help="receding-horizon law of a protocol, the DP optimum (closed loop only), or all")
    sim.add_argument("--mu", help="override the channel: comma-separated, one per actuator")
    sim.add_argument("--x0", help="override the initial state: comma-separated")
    sim.add_argument("--save", metavar="FILE.npz", help="save closed-loop trajectories (first 1000 runs) and curves")
    sim.add_argument("--plot", metavar="FILE", help="figure of the closed loop: mean +- band of ||x_t||, cost")
    sim.add_argument("--quiet", action="store_true", help="no progress bar")
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    return parser


def join_negative_values(argv: list[str]) -> list[str]:
    """``--x0 -1,1`` -> ``--x0=-1,1``: argparse would read ``-1,1`` as an unknown option."""
    out: list[str] = []
    k = 0
    while k < len(argv):
        if argv[k] in NUMBER_LISTS and k + 1 < len(argv) and re.match(r"-[\d.]", argv[k + 1]):
            out.append(f"{argv[k]}={argv[k + 1]}")
            k += 2
        else:
            out.append(argv[k])
            k += 1
    return out
