"""Each claim of the paper as a check on the paper's systems and on seeded random ones.

A check computes a *margin* per case: >= 0 where the claim holds for that case,
< 0 where it fails (for equalities, tolerance minus error). The verdict is
"holds" (no violation), "fails" (a violation, with a shrunk counterexample: the
smallest n, m, N with the simplest numbers that still violates), or
"not-reproduced" (the paper's printed numbers could not be recovered under any
convention tried). Monte Carlo checks use 4 standard errors (two-sided 99.994 %
per case).
"""

from ..results import ClaimResult
from .registry import CLAIMS, audit
from .report import claims_document, markdown_report, markdown_table, tally, tally_text

__all__ = ["CLAIMS", "ClaimResult", "audit", "claims_document", "markdown_report", "markdown_table", "tally",
           "tally_text"]
