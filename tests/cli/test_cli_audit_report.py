"""``audit --report`` is the Markdown report, a text: with ``--json`` (which prints the JSON object instead of the
text) it would be dropped without a word, so the pair is refused, exit 2 with one stderr line naming --report,
before any claim is checked. ``--out FILE`` keeps the JSON beside the report."""

import json

import pytest

import packetloss_cvx.cli.audit as command
from packetloss_cvx.cli import main


def test_report_with_json_is_refused_before_any_work(capsys, monkeypatch):
    monkeypatch.setattr(command, "audit", None)         # refused before the audit runs
    assert main(["audit", "--random", "0", "--claim", "theorem-2", "--report", "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("packetloss-cvx: error: --report: not with --json")


def test_report_with_out_prints_the_report_and_writes_the_json(tmp_path, capsys):
    out = tmp_path / "audit.json"
    assert main(["audit", "--random", "0", "--claim", "theorem-2", "--report", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert [c["id"] for c in data["claims"]] == ["theorem-2"]
    assert "theorem-2" in text
    with pytest.raises(json.JSONDecodeError):            # stdout is the Markdown report, not JSON
        json.loads(text)
