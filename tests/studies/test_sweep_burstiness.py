"""``sweep --burstiness``: the plug-in laws against the exact minimum under Gilbert channels of the
file's average rates, on the command line."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.lq.markov_cost import exact_closed_form

from ..conftest import EXAMPLES


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_memoryless_point_is_the_bernoulli_optimum_and_bursts_cost_more(capsys, tmp_path):
    code, out, err = _run(capsys, "sweep", "two_actuator", "--burstiness", "0,0.5,0.9", "--json", "-q",
                          "--out", str(tmp_path))
    assert code == 0, err
    data = json.loads(out)
    system = pl.load_example("two_actuator")
    for protocol in ("tcp", "udp"):
        bernoulli = pl.closed_form(system, protocol, method="recursion").cost   # another algorithm
        assert data[protocol]["plugin"][0] == pytest.approx(bernoulli, rel=1e-10)
        assert data[protocol]["exact"][0] == pytest.approx(bernoulli, rel=1e-10)
        plugin, exact = np.array(data[protocol]["plugin"]), np.array(data[protocol]["exact"])
        assert np.all(plugin >= exact * (1 - 1e-12))                  # the exact minimiser is a minimum
    # the TCP-like cost holds first moments only: its plug-in law is exact at every lambda
    assert np.allclose(data["tcp"]["plugin"], data["tcp"]["exact"], rtol=1e-10)
    # the UDP-like one is not: bursts cost its plug-in law more, increasingly
    loss = np.array(data["udp"]["relative_loss"])
    assert loss[0] < 1e-10 < loss[1] < loss[2]
    rows = np.loadtxt(tmp_path / "burstiness.csv", delimiter=",", skiprows=1)
    assert rows.shape == (3, 5)
    assert np.array_equal(rows[:, 0], [0.0, 0.5, 0.9])
    assert np.array_equal(rows[:, 3], data["udp"]["plugin"])           # the shortest repr reads back exactly
    lambdas = [line.split(",")[0] for line in (tmp_path / "burstiness.csv").read_text().splitlines()[1:]]
    assert lambdas == ["0", "0.5", "0.9"]                              # not 0.90000000000000002 (%.17g)
    assert (tmp_path / "burstiness.png").stat().st_size > 1000


def test_text_says_the_tcp_like_law_is_exact(capsys):
    code, out, _ = _run(capsys, "sweep", "pendulum", "--burstiness", "0:0.9:3", "-q")
    assert code == 0
    assert "TCP-like: the plug-in law is the exact minimiser at every lambda" in out
    assert "UDP-like: the plug-in law loses up to" in out


@pytest.mark.parametrize(("argv", "field"), [
    (["--burstiness", "0,1.5"], "--burstiness"),
    (["--burstiness", "0,abc"], "--burstiness"),
    (["--burstiness", "0:1:0"], "--burstiness"),
    (["--burstiness", "0,0.5", "--dask", "local"], "--burstiness"),
])
def test_bad_burstiness_is_one_line_and_exit_2(capsys, argv, field):
    code, out, err = _run(capsys, "sweep", "two_actuator", *argv)
    assert code == 2
    assert not out
    assert err.count("\n") == 1
    assert field in err


@pytest.mark.parametrize("argv", [
    ["sweep", "pendulum_bursty", "--mu-grid", "3"],     # (allocate takes chain files)
])
def test_a_chain_file_outside_burstiness_points_to_the_option(capsys, argv):
    # on the command line the way out is an option, not a Python function
    code, _, err = _run(capsys, *argv)
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert "packetloss-cvx sweep pendulum_bursty --burstiness" in err
    assert "packetloss_cvx." not in err


def test_the_rate_is_the_files_not_a_rounded_mean(capsys):
    # a mean of N equal rows of 0.9 is 0.9000000000000001; the sweep holds the file's 0.9 fixed
    code, out, _ = _run(capsys, "sweep", "two_actuator", "--burstiness", "0,0.5", "--json", "-q")
    assert code == 0
    assert json.loads(out)["rate"] == pl.load_example("two_actuator").mu_schedule[0].tolist()


def test_a_burstiness_sweep_of_zero_costs_is_not_nan(capsys, tmp_path):
    # x0 = 0 without noise (valid input): every cost is 0 and plugin / exact - 1 is 0/0: the loss must read 0 (as
    # solve's chain section takes a zero minimum's loss, markov.compare), not "nan%" in the text nor a JSON error
    path = tmp_path / "zero.toml"
    path.write_text((EXAMPLES / "two_actuator.toml").read_text().replace("x0 = [1.0, 1.0]", "x0 = [0.0, 0.0]"))
    assert main(["sweep", str(path), "--burstiness", "0,0.5", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "nan" not in text
    assert "TCP-like: the plug-in law is the exact minimiser at every lambda" in text
    assert "UDP-like: the plug-in law is the exact minimiser at every lambda" in text
    assert main(["sweep", str(path), "--burstiness", "0,0.5", "--quiet", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["udp"]["relative_loss"] == [0.0, 0.0]
    assert data["udp"]["exact"] == [0.0, 0.0]



def test_burstiness_errors_name_the_flag_and_accept_a_leading_minus(capsys):
    from packetloss_cvx.cli import main

    assert main(["sweep", "two_actuator", "--burstiness", "-0.2,0.5", "-q"]) == 2   # parsed, then refused
    err = capsys.readouterr().err
    assert err.startswith("packetloss-cvx: error: --burstiness: lambda = -0.2 needs p or r above 1")
    assert "0.9000000000000001" not in err
    assert main(["sweep", "two_actuator", "--burstiness", "-0.05,0.5", "-q", "--json"]) == 0   # p, r stay in [0, 1]
    capsys.readouterr()


def test_a_long_horizon_sweeps_by_the_recursion(capsys, tmp_path):
    """Issue 23 item 6: N = 10,000, where the dense route is refused (13 GiB), runs within the work budget; the
    memoryless point equals the Bernoulli recursion's optimum (another algorithm), bursts cost more."""
    base = pl.load_example("pendulum_bursty")
    A = base.A / max(abs(np.linalg.eigvals(base.A))) * 0.99          # stabilised: the cost stays in range
    system = pl.System(A=A, B=base.B, horizon=10_000, state_weight=np.diag(base.state_weights[0]),
                       input_weight=base.input_weights[0], x0=base.x0, channel=base.channel)
    with pytest.raises(pl.ResourceError):
        exact_closed_form(system, method="dense")
    path = pl.save_system(system, tmp_path / "long.toml")
    code, out, err = _run(capsys, "sweep", str(path), "--burstiness", "0,0.9", "--json", "-q")
    assert code == 0, err
    data = json.loads(out)
    bernoulli = pl.closed_form(system.with_mu(system.mu_schedule), "udp", method="recursion").cost
    assert data["udp"]["exact"][0] == pytest.approx(bernoulli, rel=1e-10)
    assert data["udp"]["plugin"][0] == pytest.approx(bernoulli, rel=1e-10)
    assert data["udp"]["plugin"][1] > data["udp"]["exact"][1] > data["udp"]["exact"][0]


@pytest.mark.parametrize(("factor", "exact_words"), [(3.0, False), (0.3, True)])
def test_a_plug_in_loss_within_self_check_rtol_reads_as_the_exact_minimiser(capsys, monkeypatch, factor, exact_words):
    """The summary calls the plug-in law the exact minimiser only where its loss is within SELF_CHECK_RTOL, the
    precision each cost is checked to: a loss of 3 times the band is printed as a loss, of 0.3 times as equality
    (the sweep's costs planted, so that the loss is known)."""
    import packetloss_cvx.cli.sweep as sweep_command
    from packetloss_cvx.results import BurstinessSweep
    from packetloss_cvx.tolerances import SELF_CHECK_RTOL

    exact = np.array([2.0, 3.0])
    planted = BurstinessSweep(correlation=np.array([0.0, 0.5]), rate=np.array([0.9, 0.5]),
                              plugin={p: exact * (1 + factor * SELF_CHECK_RTOL) for p in ("tcp", "udp")},
                              exact={p: exact for p in ("tcp", "udp")})
    monkeypatch.setattr(sweep_command, "burstiness_sweep", lambda *a, **k: planted)
    code, out, err = _run(capsys, "sweep", "two_actuator", "--burstiness", "0,0.5", "-q")
    assert code == 0, err
    assert ("the plug-in law is the exact minimiser at every lambda" in out) is exact_words
    assert ("the plug-in law loses up to" in out) is not exact_words
