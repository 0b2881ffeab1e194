"""Audit results as Markdown: a table, and a report with each claim's note, outcome per case
and counterexample (the body of docs/claims.md)."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence

from ..results import ClaimResult

__all__ = ["markdown_report", "markdown_table", "markdown_text"]

#: a starred symbol of the paper (``J*``, ``J*_udp``, ``J*(mu1)``, ``J*_tcp(nu2)``, ``U*``): two of them in one
#: paragraph would open and close Markdown emphasis
STARRED = re.compile(r"(?<![\w`*])[A-Za-z][A-Za-z0-9]*\*(?!\*)(?:_[A-Za-z0-9]+)?(?:\([^()\s]*\))?")


def markdown_text(text: str) -> str:
    """``text`` (a claim's statement or note, plain text) for a Markdown page: each starred symbol as code, so
    ``J*_udp - J*_tcp`` stays as written instead of turning into emphasis; code spans are left as they are.

    Examples
    --------
    >>> markdown_text("J*_udp - J*_tcp > 0 and J*(M1) > J*(M2); `J*` kept")
    '`J*_udp` - `J*_tcp` > 0 and `J*(M1)` > `J*(M2)`; `J*` kept'
    """
    parts = text.split("`")
    return "`".join(STARRED.sub(lambda m: f"`{m[0]}`", part) if i % 2 == 0 else part
                    for i, part in enumerate(parts))


def markdown_report(results: Sequence[ClaimResult], header: str = "") -> str:
    """The table, then one section per claim: its counts and note, its outcome per case
    (``+`` holds, ``-`` violated, ``.`` not applicable, ``E`` errored) and its counterexample (JSON).

    Examples
    --------
    >>> r = ClaimResult("theorem-2", "J*_udp > J*_tcp", "holds", 1, 0, 0.125, None, "One case.", outcomes="+")
    >>> text = markdown_report([r], header="# Audit")
    >>> text.startswith("# Audit"), "### theorem-2: holds" in text, "Cases: `+`" in text
    (True, True, True)
    """
    parts = [header, markdown_table(results), ""]
    for r in results:
        parts += [f"### {r.id}: {r.verdict}", "", f"*Claim.* {markdown_text(r.statement)}", "",
                  f"Checked {r.checked}, violations {r.violations}, errors {r.errors}, worst margin "
                  f"{'n/a' if r.worst is None else f'{r.worst:.4g}'}. {markdown_text(r.note)}", ""]
        if r.outcomes:
            parts += [f"Cases: `{r.outcomes}`", ""]
        if r.counterexample is not None:
            parts += ["Counterexample (System in the TOML schema's structure):", "",
                      "```json", json.dumps(r.counterexample), "```", ""]
    return "\n".join(parts)


def markdown_table(results: Sequence[ClaimResult]) -> str:
    """One row per claim: id, verdict, checked, violations, errors, worst margin.

    Examples
    --------
    >>> r = ClaimResult("theorem-2", "J*_udp > J*_tcp", "holds", 1, 0, 0.125, None, "")
    >>> print(markdown_table([r]).splitlines()[-1])
    | theorem-2 | holds | 1 | 0 | 0 | 0.125 |
    """
    lines = ["| claim | verdict | checked | violations | errors | worst margin |", "|---|---|---|---|---|---|"]
    for r in results:
        worst = "" if r.worst is None else f"{r.worst:.3g}"
        lines.append(f"| {r.id} | {r.verdict} | {r.checked} | {r.violations} | {r.errors} | {worst} |")
    return "\n".join(lines)
