"""Audit results as Markdown: a table, and a report with each claim's note and counterexample
(the body of docs/claims.md)."""

from __future__ import annotations

import json
from collections.abc import Sequence

from ..results import ClaimResult

__all__ = ["markdown_report", "markdown_table"]


def markdown_report(results: Sequence[ClaimResult], header: str = "") -> str:
    """The table, then one section per claim with its note and counterexample (JSON)."""
    parts = [header, markdown_table(results), ""]
    for r in results:
        parts += [f"### {r.id}: {r.verdict}", "", f"*Claim.* {r.statement}", "",
                  f"Checked {r.checked}, violations {r.violations}, worst margin "
                  f"{'n/a' if r.worst is None else f'{r.worst:.4g}'}. {r.note}", ""]
        if r.counterexample is not None:
            parts += ["Counterexample (System in the TOML schema's structure):", "",
                      "```json", json.dumps(r.counterexample), "```", ""]
    return "\n".join(parts)


def markdown_table(results: Sequence[ClaimResult]) -> str:
    """One row per claim: id, verdict, checked, violations, worst margin."""
    lines = ["| claim | verdict | checked | violations | worst margin |", "|---|---|---|---|---|"]
    for r in results:
        worst = "" if r.worst is None else f"{r.worst:.3g}"
        lines.append(f"| {r.id} | {r.verdict} | {r.checked} | {r.violations} | {worst} |")
    return "\n".join(lines)
