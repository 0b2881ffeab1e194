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
    """The claims' verdicts as a table (or the Markdown report with ``--report``)."""
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
