"""Command line: ``packetloss-cvx SUBCOMMAND ...`` (docs/design.md §4).

Exit codes: 0 success; 2 bad input (one stderr line naming the field); 3 a
well-posed problem with no solution (proved); 4 an allocation whose gap was not
certified within its caps (printed as usual); 1 anything else (one stderr line).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .allocation import allocate, parse_constraint
from .claims import audit, markdown_report, markdown_table
from .costs import closed_form
from .errors import CrossCheckError, InfeasibleError, InputError, NumericalError, ResourceError, SolverError
from .io import load_system
from .model import System
from .qp import solve_qp
from .results import eigenvalue_pairs

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise InputError("arguments", message)


def _floats(text: str, field: str) -> list[float]:
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        raise InputError(field, f"expected comma-separated numbers, found {text!r}") from None
    return values


def _with_overrides(system: System, args: argparse.Namespace) -> System:
    if args.mu is not None:
        try:
            system = system.with_mu(_floats(args.mu, "--mu"))
        except InputError as err:
            raise err.renamed("--mu") from None
    if args.x0 is not None:
        try:
            system = system.with_x0(_floats(args.x0, "--x0"))
        except InputError as err:
            raise err.renamed("--x0") from None
    return system


def _solve(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    system = _with_overrides(load_system(args.file), args)
    protocols = ("tcp", "udp") if args.protocol == "both" else (args.protocol,)
    out: dict[str, Any] = {
        "name": system.name, "n": system.n, "m": system.m, "horizon": system.horizon,
        "mu": system.mu_schedule[0].tolist() if system.is_stationary else system.mu_schedule.tolist(),
    }
    lines = [f"{system.name or args.file}: n={system.n}, m={system.m}, N={system.horizon}"]
    for protocol in protocols:
        sol = closed_form(system, protocol, method=args.method)
        entry: dict[str, Any] = {
            "cost": sol.cost, "inputs": sol.inputs.tolist(), "gain": sol.gain.tolist(),
            "closed_loop_eigenvalues": eigenvalue_pairs(sol.closed_loop_eigenvalues),
            "method": sol.method,
        }
        line = f"  {protocol.upper()}-like: J* = {sol.cost:.10g} ({sol.method})"
        if not args.no_qp:
            try:
                qp = solve_qp(system, protocol, args.formulation, with_gain=False, reference=sol)
            except (NumericalError, ResourceError) as err:   # a disagreement (CrossCheckError) is not caught
                entry["qp"] = {"status": "skipped", "reason": str(err)}
                line += f"; QP cross-check skipped: {err}"
            else:
                check = qp.cross_check
                entry["qp"] = {
                    "status": qp.status, "cost": qp.cost, "solve_time": qp.solve_time,
                    "formulation": qp.method.removeprefix("qp-"),
                    "max_input_diff": check.max_input_diff, "cost_rel_diff": check.cost_rel_diff,
                }
                line += (f"; QP {qp.status}, J = {qp.cost:.10g}, max|Vbar dU| = {check.max_input_diff:.2e}, "
                         f"rel dJ = {check.cost_rel_diff:.2e}")
        out[protocol] = entry
        eig = ", ".join(f"{z.real:.4f}{z.imag:+.4f}j" for z in sol.closed_loop_eigenvalues)
        lines += [line, f"    K = {np.array2string(sol.gain, precision=4)}", f"    eig(A - B K) = {eig}"]
    return out, "\n".join(lines)


def _audit(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    if args.random < 0:
        raise InputError("--random", f"expected a count >= 0, found {args.random}")
    if args.seed < 0:
        raise InputError("--seed", f"expected an integer >= 0, found {args.seed}")
    systems = [load_system(path) for path in args.files]
    only = list(dict.fromkeys(args.claim)) if args.claim else None   # a repeated --claim is checked once
    try:
        results = audit(systems, random=args.random, seed=args.seed, only=only)
    except InputError as err:
        raise err.renamed("--claim") if err.field == "claim" else err from None
    data = {"claims": [r.to_dict() for r in results]}
    text = markdown_report(results) if args.report else markdown_table(results)
    return data, text


def _allocate(args: argparse.Namespace) -> tuple[dict[str, Any], str] | tuple[dict[str, Any], str, int]:
    """Exit 0 with status "optimal"; 4 with status "gap_not_certified" (a cap was hit: the
    allocation is feasible and its lower bound proven, but the gap is larger than asked; the
    result is printed on stdout as usual); 3 when proven infeasible."""
    def number(text: str, field: str) -> float:
        values = _floats(text, field)
        if len(values) != 1:
            raise InputError(field, f"expected one number, found {text[:40]!r}")
        return values[0]

    system = load_system(args.file)
    alpha = number(args.alpha, "--alpha")
    beta = _floats(args.beta, "--beta")
    if len(beta) != system.m:
        raise InputError("--beta", f"expected {system.m} comma-separated numbers, found {len(beta)}")
    bounds = _floats(args.bounds, "--bounds")
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
    flags = {"alpha": "--alpha", "beta": "--beta", "bounds": "--bounds", "gap": "--gap", "max_boxes": "--max-boxes",
             "time_limit": "--time-limit"}
    try:
        result = allocate(system, args.protocol, alpha, beta, bounds=tuple(bounds), constraints=constraints,
                          **options)
    except InputError as err:
        raise err.renamed(flags[err.field]) if err.field in flags else err from None
    except InfeasibleError as err:
        data = {"protocol": args.protocol, "alpha": alpha, "beta": beta, "mu": None, "communication_cost": None,
                "cost": None, "lower_bound": None, "gap": None, "status": "infeasible", "method": None,
                "boxes": None, "min_cost": err.min_cost}
        return data, f"infeasible: {err}", 3
    data = {**result.to_dict(), "min_cost": None}
    line = (f"mu* = {np.round(result.mu, 6).tolist()}, beta'mu = {result.communication_cost:.6g}, J*(mu*) = "
            f"{result.cost:.6g} <= {alpha:g}, lower bound {result.lower_bound:.6g}")
    if result.status == "optimal":
        text = f"{args.protocol.upper()}-like: {line} (gap {result.gap:.1e}; {result.method})"
        return data, text
    advice = ("raise --max-boxes or --time-limit, or --gap" if args.protocol == "udp" else
              "the TCP-like SOCP's certificate is limited by the solver's accuracy: ask for a larger --gap")
    text = (f"{args.protocol.upper()}-like: GAP NOT CERTIFIED: {line}; gap reached {result.gap:.1e} > the "
            f"requested gap ({result.method}); {advice}")
    return data, text, 4


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="packetloss-cvx", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    solve = sub.add_parser("solve", help="optimal plans, costs and gains, cross-checked by a QP")
    solve.add_argument("file")
    solve.add_argument("--protocol", choices=("tcp", "udp", "both"), default="both")
    solve.add_argument("--mu", help="override the channel: comma-separated, one per actuator")
    solve.add_argument("--x0", help="override the initial state: comma-separated")
    solve.add_argument("--method", choices=("dense", "recursion", "auto"), default="auto")
    solve.add_argument("--formulation", choices=("condensed", "sparse", "auto"), default="auto")
    solve.add_argument("--no-qp", action="store_true", help="skip the solver cross-check")
    solve.add_argument("--json", action="store_true", help="print one JSON object")
    solve.set_defaults(run=_solve)

    aud = sub.add_parser("audit", help="check every claim of the paper on its systems and random ones")
    aud.add_argument("files", nargs="*", metavar="FILE", help="more systems to check the claims on")
    aud.add_argument("--random", type=int, default=50, help="seeded random systems (default 50)")
    aud.add_argument("--seed", type=int, default=0,
                     help="seeds the random systems, the samples and the shrinking (integer >= 0, default 0)")
    aud.add_argument("--claim", action="append", help="check only this claim id (repeatable)")
    aud.add_argument("--report", action="store_true", help="Markdown report with notes and counterexamples")
    aud.add_argument("--json", action="store_true", help="print one JSON object")
    aud.set_defaults(run=_audit)

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
    alloc.set_defaults(run=_allocate)
    return parser


def _emit(result: tuple[dict[str, Any], str], as_json: bool) -> None:
    data, text = result
    if as_json:
        print(json.dumps(data, allow_nan=False))
    else:
        print(text)


#: Options whose value is a comma-separated list of numbers that may start with a minus sign.
_NUMBER_LISTS = ("--mu", "--x0", "--beta", "--bounds", "--alpha")


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--x0 -1,1`` -> ``--x0=-1,1``: argparse would read ``-1,1`` as an unknown option."""
    out: list[str] = []
    k = 0
    while k < len(argv):
        if argv[k] in _NUMBER_LISTS and k + 1 < len(argv) and re.match(r"-[\d.]", argv[k + 1]):
            out.append(f"{argv[k]}={argv[k + 1]}")
            k += 2
        else:
            out.append(argv[k])
            k += 1
    return out


def _say(message: str) -> None:
    """One stderr line, whatever the message holds (a key or a path with a newline in it)."""
    print(message.replace("\r", "\\r").replace("\n", "\\n"), file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    for stream in (sys.stdout, sys.stderr):   # a terminal that cannot show a name gets an escape, not a crash
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    parser = _build_parser()
    try:
        args = parser.parse_args(_join_negative_values(list(sys.argv[1:] if argv is None else argv)))
        run: Callable[[argparse.Namespace], tuple] = args.run
        with warnings.catch_warnings():   # one stderr line, always: numerical warnings are checked, not printed
            warnings.simplefilter("ignore")
            result = run(args)
        code = result[2] if len(result) == 3 else 0
        if code == 3 and not getattr(args, "json", False):
            _say(f"packetloss-cvx: {result[1]}")
        else:
            _emit(result[:2], getattr(args, "json", False))
        return code
    except InputError as err:
        _say(f"packetloss-cvx: error: {err}")
        return 2
    except InfeasibleError as err:
        _say(f"packetloss-cvx: infeasible: {err}")
        return 3
    except (SolverError, NumericalError, CrossCheckError, ResourceError) as err:
        _say(f"packetloss-cvx: {type(err).__name__}: {err}")
        return 1
    except BrokenPipeError:  # the reader went away (e.g. `| head`): stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Exception as err:  # noqa: BLE001 - last line of defence: one line, no traceback
        _say(f"packetloss-cvx: unexpected {type(err).__name__}: {err}")
        return 1
