"""Audit results as Markdown: a table, and a report with each claim's note, outcome per case
and counterexample (the body of docs/claims.md); the tally of verdicts; and the whole claims document around a
run's audit (``claims_document``: docs/claims.md's title, "In plain words" and "Findings in detail", shipped with
the package as ``claims/claims.md``, a copy that tests/cli/test_reproduce_manners.py keeps equal to docs/claims.md)."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from importlib import resources

from ..results import ClaimResult

__all__ = ["VERDICTS", "claims_document", "markdown_report", "markdown_table", "markdown_text", "tally",
           "tally_text"]

#: the verdicts in the order a tally lists them
VERDICTS = ("holds", "fails", "not-reproduced", "inconclusive")
#: the markers around the generated block in docs/claims.md
BEGIN, END = "<!-- audit:begin -->", "<!-- audit:end -->"


def tally(results: Sequence[ClaimResult]) -> dict[str, int]:
    """Claims per verdict, every verdict listed (0 where none). O(claims).

    Examples
    --------
    >>> r = ClaimResult("theorem-2", "J*_udp > J*_tcp", "holds", 1, 0, 0.125, None, "")
    >>> tally([r, r])
    {'holds': 2, 'fails': 0, 'not-reproduced': 0, 'inconclusive': 0}
    """
    return {v: sum(r.verdict == v for r in results) for v in VERDICTS}


def tally_text(results: Sequence[ClaimResult]) -> str:
    """The tally in words: ``"22 claims: 10 hold, 9 fail, 3 not reproduced, 0 inconclusive"``. O(claims).

    Examples
    --------
    >>> r = ClaimResult("theorem-2", "J*_udp > J*_tcp", "holds", 1, 0, 0.125, None, "")
    >>> tally_text([r])
    '1 claim: 1 holds, 0 fail, 0 not reproduced, 0 inconclusive'
    """
    counts = tally(results)
    words = {"holds": "hold" if counts["holds"] != 1 else "holds", "fails": "fail" if counts["fails"] != 1 else "fails",
             "not-reproduced": "not reproduced", "inconclusive": "inconclusive"}
    total = len(results)
    return f"{total} claim{'s' if total != 1 else ''}: " + ", ".join(f"{counts[v]} {words[v]}" for v in VERDICTS)


def claims_document(results: Sequence[ClaimResult], command: str) -> str:
    """The claims document for a run's audit: docs/claims.md's title and introduction, its "In plain words"
    (which summarise the project's full audit, ``audit --random 200 --seed 1``), an "The audit" section with this
    run's tally and [`markdown_report`][packetloss_cvx.claims.report.markdown_report] (``command`` says how it was
    run), and its "Findings in detail".
    O(size of the report).

    Examples
    --------
    >>> r = ClaimResult("theorem-2", "J*_udp > J*_tcp", "holds", 1, 0, 0.125, None, "One case.", outcomes="+")
    >>> text = claims_document([r], "packetloss-cvx audit --random 0 --seed 1")
    >>> [line for line in text.splitlines() if line.startswith("## ")][:3]
    ['## In plain words', '## The audit', '## Findings in detail']
    """
    doc = resources.files(__package__).joinpath("claims.md").read_text(encoding="utf-8")
    head, _, rest = doc.partition("\n## The audit\n")
    findings = rest.partition(END)[2].partition("\n## Findings in detail\n")[2]
    audit = ["## The audit", "",
             f"This run's audit (`{command}`): {tally_text(results)}. The words above summarise the project's "
             "full audit (`packetloss-cvx audit --random 200 --seed 1`, which `packetloss-cvx reproduce` without "
             "`--quick` runs); each check computes a margin per case, negative exactly where the case violates the "
             "claim. `Cases:` gives each claim's outcome per case: `+` holds, `-` violated, `.` not applicable, "
             "`E` errored.", "", BEGIN, markdown_report(results).strip("\n"), END, ""]
    return "\n".join([head.rstrip("\n"), "", *audit, "## Findings in detail", "", findings.lstrip("\n")])


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
