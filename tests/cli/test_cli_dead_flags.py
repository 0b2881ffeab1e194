"""An option that would change nothing is refused with exit 2 and one line naming it and what it needs, before any
work (docs/cli-contracts.md, "Options that change nothing"): figure options without the option that writes the
figure, and ``simulate --mpc-samples`` on a FILE without a constrained loop."""

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.cli.common import check_dead_flags
from packetloss_cvx.cli.parser import build_parser

DEAD = [
    (["simulate", "two_actuator", "--mpc-samples", "400"], "--mpc-samples", "a [constraints] table"),
    (["simulate", "two_actuator", "--yscale", "log"], "--yscale", "--plot FILE"),
    (["simulate", "two_actuator", "--dpi", "300"], "--dpi", "--plot FILE"),
    (["simulate", "two_actuator", "--format", "svg"], "--format", "--plot FILE"),
    (["sweep", "two_actuator", "--mu-grid", "3", "--format", "svg"], "--format", "--out DIR"),
    (["sweep", "two_actuator", "--mu-grid", "3", "--dpi", "50"], "--dpi", "--out DIR"),
    (["sweep", "pendulum_bursty", "--burstiness", "0,0.5", "--format", "pdf"], "--format", "--out DIR"),
    (["region", "two_actuator", "--grid", "21", "--format", "pdf"], "--format", "--out DIR"),
    (["region", "two_actuator", "--out", "OUT", "--dpi", "300"], "--dpi", "--grid K"),
]


@pytest.mark.parametrize(("argv", "flag", "needs"), DEAD, ids=[" ".join(a) for a, _, _ in DEAD])
def test_an_option_that_would_change_nothing_is_exit_2_naming_it(argv, flag, needs, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [str(out) if a == "OUT" else a for a in argv]
    assert main([*argv, "-q"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1
    assert f"{flag}: needs {needs}" in lines[0]
    assert not out.exists()          # refused before the run folder was claimed


@pytest.mark.parametrize("argv", [
    ["simulate", "two_actuator", "--mpc-samples", "0"],                  # 0 skips the loop: true of any FILE
    ["simulate", "two_actuator", "--mpc-samples", "40", "--u-max", "1"],  # a constraint flag makes the loop
    ["simulate", "two_actuator", "--closed-loop", "--plot", "loop", "--yscale", "log", "--format", "svg",
     "--dpi", "300"],
    ["sweep", "two_actuator", "--mu-grid", "3", "--out", "sw", "--format", "svg", "--dpi", "50"],
    ["region", "two_actuator", "--grid", "5", "--out", "rg", "--format", "pdf"],
])
def test_the_same_options_where_they_act_are_accepted(argv):
    check_dead_flags(build_parser().parse_args(argv))


@pytest.mark.parametrize("name", ["c.jpg", "x.tiff", "x.eps", "x.webp"])
def test_a_plot_outside_png_pdf_svg_is_exit_2_and_nothing_is_written(name, tmp_path, capsys):
    path = tmp_path / name
    assert main(["simulate", "two_actuator", "--closed-loop", "--plot", str(path), "--samples", "20", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "--plot: cannot write" in err[0]
    assert ".png, .pdf or .svg" in err[0]
    assert not path.exists()


@pytest.mark.parametrize("name", ["c.PNG", "c.pdf", "c.svg"])
def test_a_plot_in_png_pdf_or_svg_passes_the_check(name):
    check_dead_flags(build_parser().parse_args(["simulate", "two_actuator", "--closed-loop", "--plot", name]))
    from packetloss_cvx.cli.common import figure_file
    assert figure_file(build_parser().parse_args(["simulate", "two_actuator", "--plot", name]), name) == name


def test_a_fractional_dpi_is_exit_2(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["sweep", "two_actuator", "--mu-grid", "3", "--out", str(out), "--dpi", "100.5", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "--dpi: expected a whole number" in err[0]
    assert not out.exists()

