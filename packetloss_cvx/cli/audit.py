"""``packetloss-cvx audit [FILE ...]``: check every claim of the paper on its systems and random ones."""

from __future__ import annotations

import argparse

from ..claims import audit, markdown_report, markdown_table
from ..errors import InputError
from ..io import load_system
from .common import CommandResult

__all__ = ["run"]


def run(args: argparse.Namespace) -> CommandResult:
    """The claims' verdicts as a table (or the Markdown report with ``--report``)."""
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
    return CommandResult(data, text)
