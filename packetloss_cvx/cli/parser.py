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
NUMBER_LISTS = ("--mu", "--x0", "--beta", "--bounds", "--alpha", "--x0-scales")


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

    swp = sub.add_parser("sweep", help="J* of both protocols over a grid of channels, x0 scales or horizons")
    swp.add_argument("file")
    swp.add_argument("--protocol", choices=("tcp", "udp", "both"), default="both")
    what = swp.add_mutually_exclusive_group(required=True)
    what.add_argument("--mu-grid", type=int, metavar="K",
                      help="K points per channel on [0, 1]: 1-D for one channel, 2-D for two")
    what.add_argument("--mu-list", metavar="FILE.csv", help="m-channel points, one row each (a header is skipped)")
    what.add_argument("--x0-scales", metavar="S1,S2,..|LO:HI:K", help="x0 times each scale (or K scales LO..HI)")
    what.add_argument("--horizons", metavar="N1,N2,..", help="each horizon N")
    swp.add_argument("--channel", type=int, metavar="I", help="with --mu-grid: sweep channel I only (1-based)")
    swp.add_argument("--shared", action="store_true", help="with --mu-grid: every actuator behind one channel")
    swp.add_argument("--chunk-size", type=int, default=2048, help="points per batched evaluation / Dask task")
    swp.add_argument("--dask", metavar="local|ADDRESS", help="evaluate on Dask: a LocalCluster or a scheduler")
    swp.add_argument("--workers", type=int, help="workers of --dask local (default 2)")
    swp.add_argument("--out", metavar="DIR", help="write sweep.npz, sweep.csv and a figure into DIR")
    swp.add_argument("--netcdf", action="store_true", help="also write DIR/sweep.nc (needs xarray)")
    swp.add_argument("--quiet", action="store_true", help="no progress bar")
    swp.add_argument("--json", action="store_true", help="print one JSON object")

    rep = sub.add_parser("reproduce", help="every figure and table of the paper, with a report against it")
    rep.add_argument("--out", metavar="DIR", default="results", help="output folder (default results/)")
    rep.add_argument("--quick", action="store_true", help="coarser grids and fewer alphas (a smoke test)")
    rep.add_argument("--quiet", action="store_true", help="no progress bar")
    rep.add_argument("--json", action="store_true", help="print one JSON object")
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
