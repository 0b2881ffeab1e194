"""``reproduce`` as a user meets it: a progress bar over every step (figures and the report included), the audit's
tally printed and leading the report, and a claims.md with docs/claims.md's sections around the run's audit.

References: the verdicts counted from results.json's audit list, docs/claims.md itself."""

import json
import re
from pathlib import Path

import pytest

from packetloss_cvx.claims import ClaimResult, claims_document, markdown_report, tally_text
from packetloss_cvx.cli import reproduce as reproduce_command
from packetloss_cvx.cli.parser import build_parser

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "claims.md"
PACKAGED = Path(reproduce_command.__file__).resolve().parent.parent / "claims" / "claims.md"


class RecordingBar:
    """A progress bar that records what it was told (the package's bars take the same calls)."""

    def __init__(self, total):
        self.total, self.updates, self.steps = total, 0, []

    def update(self, n=1):
        self.updates += n

    def set_postfix_str(self, text):
        self.steps.append(text)

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    bars = []

    def progress_bar(iterable=None, *, total=None, desc="", progress=None, estimate=None):
        bars.append(RecordingBar(total))
        return bars[-1]

    out = tmp_path_factory.mktemp("reproduce")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(reproduce_command, "progress_bar", progress_bar)
        result = reproduce_command.run(build_parser().parse_args(["reproduce", "--quick", "--out", str(out)]))
    return result, bars, out


def test_one_bar_covers_every_step_to_the_report(run):
    _, bars, _ = run
    (bar,) = bars                                         # compute uses run's bar, not a second one
    assert bar.total == bar.updates == 10
    assert bar.steps[-2:] == ["figures", "report"]


def test_the_tally_is_printed_and_leads_the_report(run):
    result, _, out = run
    verdicts = [claim["verdict"] for claim in json.loads((out / "results.json").read_text())["audit"]]
    counts = {v: verdicts.count(v) for v in ("holds", "fails", "not-reproduced", "inconclusive")}
    words = (f"{len(verdicts)} claims: {counts['holds']} hold, {counts['fails']} fail, "
             f"{counts['not-reproduced']} not reproduced, {counts['inconclusive']} inconclusive")
    assert result.text.splitlines()[1].startswith(f"  audit: {words}")
    assert result.data["audit"] == counts
    report = (out / "report.md").read_text().splitlines()
    assert report[0] == "# The paper, reproduced"
    assert report[2].startswith(f"**The audit: {words}**")


def _headings(text):
    return re.findall(r"^(#{1,2} .+)$", text, flags=re.M)


def test_claims_md_carries_the_sections_of_docs_claims(run):
    _, _, out = run
    assert _headings((out / "claims.md").read_text()) == _headings(DOC.read_text())
    text = (out / "claims.md").read_text()
    assert text.index("## In plain words") < text.index("## The audit") < text.index("## Findings in detail")


def test_the_packaged_words_are_docs_claims():
    assert PACKAGED.read_text() == DOC.read_text(), "refresh the copy: cp docs/claims.md packetloss_cvx/claims/"


def test_the_claims_document_holds_the_runs_audit_between_the_markers():
    results = [ClaimResult("theorem-2", "J*_udp > J*_tcp", "holds", 1, 0, 0.125, None, "One case.", outcomes="+"),
               ClaimResult("lemma-3", "a maximiser", "fails", 2, 1, -0.5, None, "Two cases.", outcomes="+-")]
    text = claims_document(results, "packetloss-cvx audit --random 0 --seed 1")
    block = text.split("<!-- audit:begin -->")[1].split("<!-- audit:end -->")[0]
    assert block.strip() == markdown_report(results).strip()
    assert "(`packetloss-cvx audit --random 0 --seed 1`): 2 claims: 1 holds, 1 fails" in text
    assert tally_text(results) == "2 claims: 1 holds, 1 fails, 0 not reproduced, 0 inconclusive"


def test_a_bar_shows_on_a_terminal_that_reports_no_size():
    """A pseudo-terminal without a window size (0 x 0, as pty.openpty makes it, and as some terminals and
    `docker exec -t` report) hid every tqdm bar: reproduce ran silent on a terminal."""
    import os
    import pty
    import subprocess
    import sys

    master, slave = pty.openpty()
    code = ("import time\nfrom packetloss_cvx.progress import progress_bar\n"
            "with progress_bar(total=2, desc='steps') as bar:\n    for _ in range(2):\n"
            "        time.sleep(0.15)\n        bar.update()\n")
    root = str(ROOT)
    proc = subprocess.run([sys.executable, "-c", code], stderr=slave, stdout=subprocess.DEVNULL, cwd=root,
                          env={**os.environ, "PYTHONPATH": root}, timeout=60, check=False)
    os.close(slave)
    seen = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:
            break
        if not chunk:
            break
        seen += chunk
    os.close(master)
    assert proc.returncode == 0
    assert b"steps:  50%" in seen
