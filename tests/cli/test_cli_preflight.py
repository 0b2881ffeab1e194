"""Bad output paths and figure formats are refused before the work (cli.common.preflight): exit 2, one
stderr line naming the flag, nothing written, the command's module not even imported."""

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.cli import simulate as simulate_command


@pytest.mark.parametrize(("argv", "field"), [
    (["solve", "two_actuator", "--out", "{tmp}/no-such-dir/out.json"], "--out"),
    (["solve", "two_actuator", "--out", "{tmp}"], "--out"),
    (["simulate", "two_actuator", "--closed-loop", "--save", "{tmp}/no-such-dir/runs.npz"], "--save"),
    (["simulate", "two_actuator", "--closed-loop", "--save", "{tmp}/runs.txt"], "--save"),
    (["simulate", "two_actuator", "--closed-loop", "--plot", "{tmp}/no-such-dir/loop.png"], "--plot"),
    (["simulate", "two_actuator", "--plot", "{tmp}/loop.png"], "--plot"),
    # two outputs of one run into one file: the figure would be replaced by the JSON (with --force silently)
    (["simulate", "two_actuator", "--closed-loop", "--plot", "{tmp}/q.png", "--out", "{tmp}/q.png", "--force"],
     "--plot"),
    (["simulate", "two_actuator", "--closed-loop", "--save", "{tmp}/x.npz", "--out", "{tmp}/./x.npz"], "--save"),
    # a FILE option given a folder that does not exist yet (a trailing '/'): it wrote a file named like the folder
    (["solve", "two_actuator", "--out", "{tmp}/newdir/"], "--out"),
    (["simulate", "two_actuator", "--closed-loop", "--plot", "{tmp}/figures/"], "--plot"),
])
def test_a_bad_output_path_is_refused_before_the_work(argv, field, tmp_path, capsys, monkeypatch):
    """These were refused only after the whole computation (a long audit or simulation lost to a typo)."""
    import importlib
    import sys
    for name in ("solve", "simulate"):
        monkeypatch.setitem(sys.modules, f"packetloss_cvx.cli.{name}", None)   # importing the command would fail
    importlib.invalidate_caches()
    code = main([a.replace("{tmp}", str(tmp_path)) for a in argv] + ["-q"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith(f"packetloss-cvx: error: {field}: ")
    assert len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())



def test_a_figure_format_matplotlib_cannot_write_is_refused_before_the_sampling(capsys, monkeypatch):
    # the --plot format is checked before any sampling: a refusal after the Monte Carlo would waste the run
    def never(*args, **kwargs):
        raise AssertionError("sampled before the --plot check")

    monkeypatch.setattr(simulate_command, "simulate", never)
    assert main(["simulate", "two_actuator", "--closed-loop", "--plot", "loop.pgn", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("packetloss-cvx: error: --plot: cannot write a 'pgn' figure"), err
