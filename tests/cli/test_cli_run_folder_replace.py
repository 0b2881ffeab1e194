"""A run folder holding a complete run of another command is not replaced without --force (docs/design.md, "Files
and runs"): the reviewer's case, a sweep in pdf over an earlier sweep in svg, deleted the svg figures."""

from packetloss_cvx.cli import main


def test_a_sweep_in_another_format_over_an_earlier_run_is_refused_without_force(tmp_path, capsys):
    out = tmp_path / "sw1"
    base = ["sweep", "two_actuator", "--mu-grid", "3", "--out", str(out)]
    assert main([*base, "--format", "svg", "-q"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {"sweep.npz", "sweep.csv", "sweep_tcp.svg"} <= set(before)
    capsys.readouterr()
    assert main([*base, "--format", "pdf", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "--out: refusing to replace the run" in err[0]
    assert "--force" in err[0]
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before      # the svg figures and the data kept
    assert main([*base, "--format", "svg"]) == 0                         # the same command again: a re-run
