"""``packetloss-cvx audit [FILE ...]``: check every claim of the paper on its systems and random ones."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from ..claims import audit, markdown_report
from ..errors import InputError
from ..results import ClaimResult
from . import format as fmt
from .common import CommandResult, progress_of, systems_of

__all__ = ["run"]


def run(args: argparse.Namespace) -> CommandResult:
    """The claims' verdicts as a table (or the Markdown report with ``--report``).

    Examples
    --------
    Theorem 2 (`J*_udp` >= `J*_tcp`) on the paper's two systems and a one-step scalar one (2/3 <= 0.75):

    >>> import tempfile
    >>> from pathlib import Path
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> result = run(build_parser().parse_args(["audit", path, "--random", "0", "--claim", "theorem-2"]))
    >>> result.code, [(c["id"], c["verdict"], c["checked"]) for c in result.data["claims"]]
    (0, [('theorem-2', 'holds', 3)])
    >>> folder.cleanup()
    """
    if args.random < 0:
        raise InputError("--random", f"expected a count >= 0, found {args.random}")
    if args.seed < 0:
        raise InputError("--seed", f"expected an integer >= 0, found {args.seed}")
    systems = systems_of(args)
    only = list(dict.fromkeys(args.claim)) if args.claim else None   # a repeated --claim is checked once
    try:
        results = audit(systems, random=args.random, seed=args.seed, only=only, progress=progress_of(args))
    except InputError as err:
        raise err.renamed("--claim") if err.field == "claim" else err from None
    data = {"claims": [r.to_dict() for r in results]}
    text = markdown_report(results) if args.report else text_table(results, args.verbose)
    return CommandResult(data, text)


def text_table(results: Sequence[ClaimResult], verbose: int = 0) -> str:
    """One aligned row per claim (the JSON's order); with ``-v`` each claim's note below the table."""
    counts = {verdict: sum(r.verdict == verdict for r in results)
              for verdict in ("holds", "fails", "not-reproduced", "inconclusive")}
    heading = f"{len(results)} claims: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v)
    rows = [[r.id, r.verdict, r.checked, r.violations, r.errors, fmt.num(r.worst, 3), r.outcomes[:40]]
            for r in results]
    lines = [heading, ""] + fmt.table(["claim", "verdict", "checked", "violations", "errors", "worst margin",
                                       "cases (+ holds, - violated, . n/a, E error)"], rows,
                                      right=[False, False, True, True, True, True, False])
    if verbose:
        for r in results:
            lines += ["", f"{r.id}: {r.verdict}"] + fmt.fields([("claim", r.statement), ("note", r.note)])
    return "\n".join(lines)
