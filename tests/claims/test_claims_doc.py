"""docs/claims.md's generated block matches a fresh audit, and the audit's verdicts are recomputed.

The block is ``audit --random 200 --seed 1 --report``: :func:`test_the_block_is_the_full_audit` runs
that command (about 4 s) and compares its output with the block by value (:func:`text_mismatches`): every
word, id, verdict, count, case outcome and counterexample exactly, every other number within what it is trusted
to across BLAS kernels (tolerances.KERNEL_*, as tests/kernels.py compares reproduce's results: a holding claim's
worst margin, its tolerance less a rounding-level error, moves in its third digit). The same
seed draws the same random systems in the same order, so ``audit(random=K, seed=1)`` checks the
first K of them as the full run does (every margin depends only on its case and the seed).
The test re-runs that smaller audit once and checks everything it covers, by value likewise:

- every table row agrees with its claim's ``Cases:`` line (checked = ``+`` and ``-``, violations =
  ``-``, errors = ``E``) and with the verdict rule, so the table cannot drift from its outcomes;
- every ``Cases:`` line starts with the fresh run's outcomes;
- where the fresh run covers all of a claim's cases (the Monte Carlo claims' selection is complete
  within the first K systems; Tables I–II and the pendulum do not depend on the random systems),
  the document's whole section equals the fresh one, note and counterexample included;
- the document's worst margin is no larger than the fresh run's (it is a minimum over more cases);
- the allocation claim (18 brute-force allocations, 7 s) is recomputed on three of its (beta, alpha)
  cases, one per beta, through the function the claim itself uses: their outcomes and their
  entries in the note must match, and so must the cost range and the number of cases.
"""

import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from packetloss_cvx.claims import CLAIMS, audit, markdown_report
from packetloss_cvx.claims.channel_allocation import alpha_levels, perfect_channel_case
from packetloss_cvx.claims.evaluate import verdict
from packetloss_cvx.claims.paper import ALLOCATION_BETAS
from packetloss_cvx.cli import main
from packetloss_cvx.model.files import load_example, system_from_dict
from packetloss_cvx.tolerances import KERNEL_MARGIN_RTOL, KERNEL_POINT_RTOL, KERNEL_VALUE_RTOL

DOC = (Path(__file__).resolve().parents[2] / "docs" / "claims.md").read_text()
SEED = 1
RANDOM = 24   # the 8th small random system of seed 1 is number 24: the Monte Carlo claims are covered

ROW = re.compile(r"^\| ([a-z0-9-]+) \| ([a-z-]+) \| (\d+) \| (\d+) \| (\d+) \| (\S*) \|$", flags=re.M)


ALLOCATION = "allocation-udp-perfect-channel"
ALLOCATION_CASES = (0, 5, 13)  # beta (1, 1) at 4.78, (1, 1) at 1.01 J*(0), (1, 0.05) at 6: +, -, -


@dataclass(frozen=True)
class Fresh:
    """A fresh, smaller audit: the results without the allocation claim, and that claim's cost
    range, cases and three recomputed cases (index -> margin, note entry)."""

    results: list
    cost_range: tuple[float, float]
    pairs: list
    allocation: dict


@pytest.fixture(scope="module")
def fresh() -> Fresh:
    results = audit(random=RANDOM, seed=SEED, only=[claim_id for claim_id in CLAIMS if claim_id != ALLOCATION])
    system = load_example("two_actuator")
    alphas, full, none = alpha_levels(system)
    pairs = [(beta, alpha) for beta in ALLOCATION_BETAS for alpha in alphas]
    return Fresh(results, (full, none), pairs, {i: perfect_channel_case(system, *pairs[i]) for i in ALLOCATION_CASES})


NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
INTEGER = re.compile(r"[-+]?\d+")


def _unit(token: str) -> float:
    """One unit in the last printed digit of a number token ('9.96e-06': 1e-08; an integer: 0, compared exactly)."""
    if INTEGER.fullmatch(token):
        return 0.0
    mantissa, _, exponent = token.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def numbers_agree(doc: str, fresh: str, rtol: float = KERNEL_VALUE_RTOL) -> bool:
    """Two printed numbers of one quantity agree: integers (counts, sizes) as text; otherwise within ``rtol`` of
    the larger plus one unit in the last digit both print (a value on a rounding boundary; %g drops trailing
    zeros, so the finer of the two units is the format's)."""
    if INTEGER.fullmatch(doc) and INTEGER.fullmatch(fresh):
        return doc == fresh
    a, b = float(doc), float(fresh)
    return abs(a - b) <= min(_unit(doc), _unit(fresh)) + rtol * max(abs(a), abs(b))


def margin_rtol(verdict: str) -> float:
    """What a claim's worst margin is trusted to across kernels (tolerances.py): a holding claim's is its tolerance
    less a rounding-level error (KERNEL_MARGIN_RTOL), another's a violation's size or a maximiser's location
    (KERNEL_POINT_RTOL)."""
    return KERNEL_MARGIN_RTOL if verdict == "holds" else KERNEL_POINT_RTOL


def text_mismatches(doc: str, fresh: str, where: str = "") -> list[str]:
    """Every line where ``doc`` and ``fresh`` differ in their words (exact) or numbers (:func:`numbers_agree`:
    worst margins, in the table's last column and a section's 'Checked' line, within :func:`margin_rtol` of their
    claim's verdict, every other number within KERNEL_VALUE_RTOL); a counterexample (a system's data in a JSON
    fence: exact floats, no rounding) exactly."""
    doc_lines, fresh_lines = doc.strip().splitlines(), fresh.strip().splitlines()
    if len(doc_lines) != len(fresh_lines):
        return [f"{where}{len(doc_lines)} lines against the fresh run's {len(fresh_lines)}"]
    out, data, verdict = [], False, ""
    for k, (d, f) in enumerate(zip(doc_lines, fresh_lines, strict=True)):
        data = d.startswith("```json") or (data and not d.startswith("```"))
        if data:
            if d != f:
                out.append(f"{where}line {k + 1}: the data differ: {d[:120]!r} against {f[:120]!r}")
            continue
        if NUMBER.split(d) != NUMBER.split(f):
            out.append(f"{where}line {k + 1}: the words differ: {d[:120]!r} against {f[:120]!r}")
            continue
        numbers = list(zip(NUMBER.findall(d), NUMBER.findall(f), strict=True))
        if title := re.match(r"(?:### )?[a-z0-9-]+: ([a-z-]+)$", d):
            verdict = title.group(1)
        margin = None
        if row := ROW.match(d):
            verdict, margin = row.group(2), len(numbers) - 1
        elif d.startswith("Checked "):
            margin = 3                               # Checked c, violations v, errors e, worst margin w.
        for j, (x, y) in enumerate(numbers):
            if not numbers_agree(x, y, margin_rtol(verdict) if j == margin else KERNEL_VALUE_RTOL):
                out.append(f"{where}line {k + 1}: {x} against the fresh run's {y}")
    return out


def _block(doc: str) -> str:
    return doc.split("<!-- audit:begin -->")[1].split("<!-- audit:end -->")[0]


def _sections(report: str) -> dict[str, str]:
    """Claim id -> its section of a Markdown report (from '### id:' to the next section)."""
    parts = re.split(r"^### ", report, flags=re.M)[1:]
    return {part.split(":", 1)[0]: part.strip() for part in parts}


def _outcomes(section: str) -> str | None:
    found = re.search(r"^Cases: `([-+.E]*)`$", section, flags=re.M)
    return found.group(1) if found else None


def doc_mismatches(doc: str, fresh: Fresh) -> list[str]:
    """Every way ``doc``'s audit block disagrees with itself, the verdict rule or the fresh results
    (empty when it is current)."""
    out = []
    command = re.search(r"audit --random (\d+) --seed (\d+) --report", doc)
    if command is None or int(command.group(2)) != SEED:
        return [f"the document does not state the command 'audit --random N --seed {SEED} --report'"]
    n_cases = 2 + int(command.group(1))
    block = _block(doc)
    rows = {m[0]: m[1:] for m in ROW.findall(block)}
    sections = _sections(block)
    if list(rows) != list(CLAIMS) or list(sections) != list(CLAIMS):
        return [f"table rows {list(rows)} or sections {list(sections)} are not the claims {list(CLAIMS)}"]
    for claim_id, (verdict_doc, checked, violations, errors, _) in rows.items():
        counts = (int(checked), int(violations), int(errors))
        if not sections[claim_id].startswith(f"{claim_id}: {verdict_doc}\n"):
            out.append(f"{claim_id}: the section's verdict is not the row's {verdict_doc!r}")
        cases = _outcomes(sections[claim_id])
        if cases is not None:
            counted = (cases.count("+") + cases.count("-"), cases.count("-"), cases.count("E"))
            if counted != counts:
                out.append(f"{claim_id}: the row says checked/violations/errors {counts}, its Cases line {counted}")
            if verdict_doc != verdict(*counted):
                out.append(f"{claim_id}: verdict {verdict_doc!r} but the rule gives {verdict(*counted)!r}")
    fresh_sections = _sections(markdown_report(fresh.results))
    for r in fresh.results:
        cases = _outcomes(sections[r.id])
        worst = rows[r.id][-1]
        if (cases is None) != (not r.outcomes):
            out.append(f"{r.id}: a Cases line where none is expected, or none where one is")
        if cases is not None:
            if len(r.outcomes) == 2 + RANDOM and len(cases) != n_cases:
                out.append(f"{r.id}: {len(cases)} cases, the stated command checks {n_cases}")
            if not cases.startswith(r.outcomes):
                out.append(f"{r.id}: the fresh outcomes {r.outcomes} are not where the document's begin: "
                           f"{cases[:len(r.outcomes)]}")
        covered = cases is None or len(cases) == len(r.outcomes)
        if covered:
            out += text_mismatches(sections[r.id], fresh_sections[r.id], f"{r.id}, against a fresh run: ")
        if (worst and r.worst is not None and float(worst) > r.worst
                and not numbers_agree(worst, f"{r.worst:.3g}", margin_rtol(rows[r.id][0]))):
            out.append(f"{r.id}: documented worst margin {worst} exceeds the fresh run's {r.worst:.3g}")
    return out + _allocation_mismatches(sections[ALLOCATION], fresh)


ENTRY = re.compile(r"beta=\([^)]*\), alpha=[^:]*: mu\*=\([^)]*\)")


def _allocation_mismatches(section: str, fresh: Fresh) -> list[str]:
    cases = _outcomes(section) or ""
    full, none = fresh.cost_range
    out = []
    cost_range = re.search(r"J\*_udp ranges from .*? \(mu = 1\) to .*? \(mu = 0\)", section)
    if cost_range is None or text_mismatches(cost_range.group(0), f"J*_udp ranges from {full:.3f} (mu = 1) to "
                                                                  f"{none:.3f} (mu = 0)"):
        out.append(f"{ALLOCATION}: the cost range is not {full:.3f} to {none:.3f}")
    entries = ENTRY.findall(section)
    if len(cases) != len(fresh.pairs) or len(entries) != len(fresh.pairs):
        return out + [f"{ALLOCATION}: {len(cases)} cases and {len(entries)} entries, the claim has {len(fresh.pairs)}"]
    for i, (value, entry) in fresh.allocation.items():
        expected = "." if value is None else "-" if value < 0 else "+"
        if cases[i] != expected or (value is not None and text_mismatches(entries[i], entry)):
            out.append(f"{ALLOCATION}: case {i} ({entry}, outcome {expected!r}) is not the document's")
    return out


def test_the_block_is_the_full_audit(capsys):
    """The block is what the command it names prints today: every verdict, count, outcome, note and
    counterexample of all 202 cases (no subset), its numbers within the registry's KERNEL_* tolerances
    (:func:`text_mismatches`)."""
    assert main(["audit", "--random", "200", "--seed", str(SEED), "--report", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "--random 200 --seed 1 --report" in DOC
    assert text_mismatches(_block(DOC), printed) == []


# (printed under one kernel, printed under another): holding claims' worst margins measured across OpenBLAS's kernels
KERNEL_PAIRS = [("9.96e-06", "9.97e-06"), ("9.96e-06", "9.969e-06"), ("9.99e-10", "1e-09"), ("9.991e-10", "9.98e-10"),
                ("9.991e-10", "9.996e-10")]
# the same moves in the document's block: SkylakeX's printing against Haswell's and Sandybridge's
KERNEL_MOVES = [("| 9.96e-06 |", "| 9.97e-06 |"), ("worst margin 9.96e-06.", "worst margin 9.969e-06."),
                ("| 9.99e-10 |", "| 1e-09 |"), ("worst margin 9.991e-10.", "worst margin 9.98e-10.")]


@pytest.mark.parametrize(("doc", "fresh"), KERNEL_PAIRS)
def test_margins_that_move_with_the_kernel_agree(doc, fresh):
    assert numbers_agree(doc, fresh, margin_rtol("holds"))
    assert numbers_agree(fresh, doc, margin_rtol("holds"))


def test_the_full_block_comparison_passes_what_the_kernels_move():
    block = moved = _block(DOC)
    for old, new in KERNEL_MOVES:
        assert old in moved
        moved = moved.replace(old, new, 1)
    assert text_mismatches(block, moved) == []
    assert text_mismatches(moved, block) == []


@pytest.mark.parametrize(("old", "new"), [
    ("| theorem-2 | holds | 107 |", "| theorem-2 | holds | 108 |"),                      # a count
    ("| corollary-1 | fails | 107 | 2 |", "| corollary-1 | holds | 107 | 2 |"),          # a verdict
    ("Cases: `+-----+", "Cases: `-+----+"),                                               # an outcome
    ("in 18 of the 128 cases", "in 19 of the 128 cases"),                                 # a count in a note
    ("| table-1 | not-reproduced | 42 | 1 | 0 | 0.506 |",
     "| table-1 | not-reproduced | 42 | 1 | 0 | 0.516 |"),                                 # a margin, 2 %
    ("worst margin 9.96e-06.", "worst margin 1.02e-05."),                                 # a holding margin, 2.4 %
    ("worst margin 0.002832.", "worst margin 0.002834."),                                 # a failing margin, 2 units
    ("(pendulum: z = 0.86;", "(pendulum: z = 0.88;"),                                     # a note's number
    ("worst margin -1.77e+05", "worst margin -1.81e+05"),                                 # a margin, 2.3 %
    ('"mu": [0.1, 0.7]', '"mu": [0.1, 0.71]'),                                            # a counterexample
])
def test_the_full_block_comparison_catches_a_changed_word_count_or_number(old, new):
    """text_mismatches, the full block's check, on the document against itself with one change planted: a count,
    a verdict or an outcome changed, or a number moved beyond what it is trusted to."""
    block = _block(DOC)
    assert old in block
    assert text_mismatches(block, block) == []
    assert text_mismatches(block, block.replace(old, new, 1)) != []
    assert text_mismatches(block.replace(old, new, 1), block) != []


def test_doc_block_matches_a_fresh_audit(fresh):
    assert doc_mismatches(DOC, fresh) == []


@pytest.mark.parametrize(("old", "new"), [
    ("| theorem-2 | holds | 107 |", "| theorem-2 | holds | 108 |"),                      # a count
    ("| corollary-1 | fails | 107 | 2 |", "| corollary-1 | holds | 107 | 2 |"),          # a verdict
    ("### lemma-2: holds", "### lemma-2: fails"),                                         # a section's verdict
    ("Cases: `+-----+", "Cases: `-+----+"),                                               # order, counts kept
    ("Monte Carlo, 20000 samples a case", "Monte Carlo, 2000 samples a case"),            # a covered note
    ("alpha=4.78: mu*=(1.000, 0.680)", "alpha=4.78: mu*=(1.000, 0.690)"),                 # a recomputed case
    ("Cases: `+++---+++", "Cases: `-+++--+++"),                                           # its outcome
    ("--random 200 --seed 1 --report", "--random 200 --seed 2 --report"),                 # the command
])
def test_a_stale_document_is_caught(fresh, old, new):
    assert old in DOC
    assert doc_mismatches(DOC.replace(old, new, 1), fresh) != []


def test_audit_recomputes_verdicts(fresh):
    """On the same run: verdicts follow their counts, and the known findings are found again."""
    results = {r.id: r for r in fresh.results}
    assert list(results) == [claim_id for claim_id in CLAIMS if claim_id != ALLOCATION]
    for r in results.values():
        assert r.verdict in ("holds", "fails", "not-reproduced", "inconclusive")
        assert r.checked > 0
        assert r.errors == 0
        assert (r.violations == 0) == (r.verdict == "holds")
        if r.outcomes:
            assert (r.outcomes.count("+") + r.outcomes.count("-"), r.outcomes.count("-")) == (r.checked, r.violations)
    for claim_id in ("theorem-1-costs", "lemma-3", "theorem-4", "expected-cost-tcp"):
        r = results[claim_id]
        assert r.verdict == "fails"
        assert r.counterexample is not None
        system_from_dict(r.counterexample)  # a valid System
    for claim_id in ("theorem-1-laws", "theorem-3", "lemma-2", "lemma-quad-expectation"):
        assert results[claim_id].verdict == "holds"
    assert "### theorem-4: fails" in markdown_report(list(results.values()))
