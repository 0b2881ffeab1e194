"""``packetloss-cvx region`` (cli/region.py): JSON keys, files, exit codes. References: the scalar threshold
1 - 1/a^2 and the decoupled plant's per-channel thresholds (hand values)."""

import json
from pathlib import Path

import numpy as np
import pytest

import packetloss_cvx
from packetloss_cvx import System
from packetloss_cvx.cli import main
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import save_system


@pytest.fixture
def decoupled_file(tmp_path):
    s = System(A=np.diag([2.0, 1.5]), B=np.eye(2), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
               mu=[0.9, 0.9], x0=[1.0, 1.0])
    return str(save_system(s, tmp_path / "decoupled.toml"))


def test_region_json_per_law_critical_mu_and_t(decoupled_file, capsys):
    assert main(["region", decoupled_file, "--law", "dp", "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"dp"}
    assert data["dp"]["t"] == pytest.approx(0.75, abs=1e-6)             # max(1 - 1/4, 1 - 1/2.25)
    assert data["dp"]["critical_mu"] == pytest.approx([0.75, 0.75], abs=1e-6)
    assert main(["region", decoupled_file, "--law", "dp", "--direction", "0.8,1", "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["dp"]["t"] == pytest.approx(0.75 / 0.8, abs=1e-6)       # channel 1 needs 0.8 t > 0.75
    assert main(["region", decoupled_file, "--law", "dp", "--direction", "0.5,1", "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["dp"]["t"] is None                     # 0.75 / 0.5 > 1 = the ray's end
    assert data["dp"]["critical_mu"] is None


def test_region_grid_json_and_out_folder(decoupled_file, tmp_path, capsys):
    out = tmp_path / "region-out"
    code = main(["region", decoupled_file, "--law", "all", "--grid", "5", "--channels", "1,2", "--out", str(out),
                 "--json", "-q"])
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"dp", "tcp", "udp", "fixed", "files"}
    grid = data["dp"]["grid"]
    axis = np.array(grid["axis"])
    expected = (axis[None, :] > 0.75) & (axis[:, None] > 1 - 1 / 2.25)   # rows mu_2, columns mu_1
    assert np.array_equal(np.array(grid["stable"], dtype=bool), expected)
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "region.csv", "region.npz", "region.png"]
    with np.load(out / "region.npz") as npz:
        assert npz["stable"].shape == (4, 5, 5)
        assert list(npz["laws"]) == ["dp", "tcp", "udp", "fixed"]


@pytest.mark.parametrize(("argv", "field"), [
    (["--direction", "1,-1"], "--direction"), (["--direction", "1"], "--direction"),
    (["--grid", "4", "--channels", "1,3"], "--channels"), (["--grid", "4", "--channels", "2,2"], "--channels"),
    (["--channels", "1,2"], "--channels"), (["--grid", "1"], "--grid"), (["--law", "mpc"], "--law"),
    (["--dask", "local"], "--dask"), (["--grid", "3", "--dask", "nowhere"], "--dask"),
    (["--grid", "3", "--workers", "2"], "--workers"),
])
def test_region_bad_input_exits_2_with_one_line(decoupled_file, capsys, argv, field):
    assert main(["region", decoupled_file, *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert field in err[0]


def test_region_one_channel_has_no_grid_and_a_huge_grid_is_refused(decoupled_file, capsys):
    assert main(["region", "pendulum", "--grid", "5"]) == 2
    assert "--grid" in capsys.readouterr().err
    assert main(["region", decoupled_file, "--grid", "100000"]) == 2       # over the region_points budget
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "--grid" in err[0]
    assert "PACKETLOSS_CVX_BUDGET_REGION_POINTS" in err[0]


def test_region_maps_a_gilbert_elliott_file_over_its_mean_rates(capsys, tmp_path):
    """Behind a chain: the mode-dependent set (simulation.markov_region) at the file's chain and over its mean rate
    at the file's burstiness; the paper's laws and a ray over Bernoulli mu are refused (exit 2, one line)."""
    assert main(["region", "pendulum_bursty", "--law", "dp", "--grid", "3", "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)["dp"]
    assert data["verdict"] == "stable"
    assert data["radius"] < 1
    assert data["lambda"] == pytest.approx(data["radius"])
    assert data["grid"]["axis"] == [0.0, 0.5, 1.0]
    assert data["grid"]["stable"] == [[False, False, True]]
    for argv, flag in ((["--law", "tcp"], "--law"), (["--direction", "-1"], "--direction")):
        assert main(["region", "pendulum_bursty", *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1
        assert flag in err[0]
    assert main(["region", "pendulum_bursty", "--grid", "200000"]) == 2           # over the region_points budget
    assert "PACKETLOSS_CVX_BUDGET_REGION_POINTS" in capsys.readouterr().err
    out = tmp_path / "chain"
    assert main(["region", "pendulum_bursty", "--grid", "2", "--out", str(out), "-q"]) == 0
    assert {"region.npz", "region.csv"} <= {p.name for p in out.iterdir()}


def test_region_names_a_missing_fixed_law(capsys):
    """'fixed' needs a DP law at the file's mu, which mu = 0.01 (outside S: critical t 0.061 on two_actuator)
    does not have (exit 1, one line)."""
    assert main(["region", "two_actuator", "--mu", "0.01", "--law", "fixed"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "fixed" in err[0]
    assert "does not exist" in err[0]
    assert main(["region", "two_actuator", "--mu", "0.01", "--law", "dp", "--json"]) == 0


def test_region_all_laws_leaves_out_a_missing_fixed_law_with_a_note(capsys, tmp_path):
    """--law all (the default) on a plant no mu stabilises (x2' = 3 x2 has no input): 'fixed' has no DP gain to
    design, so it is left out with the reason, and the other laws still answer 'never' (exit 0): one law without a
    design does not stop the command."""
    s = System(A=[[2.0, 0.0], [0.0, 3.0]], B=[[1.0], [0.0]], horizon=5, state_weight=[1.0, 1.0],
               input_weight=[1.0], mu=[0.9], x0=[1.0, 1.0])
    path = str(save_system(s, tmp_path / "unstabilisable.toml"))
    assert main(["region", path, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert "fixed" not in data
    assert set(data) >= {"dp", "tcp", "udp"}
    assert all(data[law]["critical_mu"] is None and data[law]["t"] is None for law in ("dp", "tcp", "udp"))
    assert len(data["notes"]) == 1
    assert "'fixed' left out" in data["notes"][0]


def test_region_gives_the_critical_mean_rate_behind_a_chain_where_it_is_proved(capsys, tmp_path):
    """A one-state plant behind a Gilbert channel (h_bad = 0, burstiness 0.2): stabilisable iff r > 1 - 1/a^2, and
    r = 0.8 rate at this burstiness, so the critical mean rate is (5/9) / 0.8 = 25/36 (hand), bracketed to 1e-6;
    with h_bad > 0 no bisection is offered: critical_mu null and the reason (the monotonicity is not proved there)."""
    s = System(A=[[1.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.4], r=[0.4]))
    path = str(save_system(s, tmp_path / "gilbert.toml"))
    assert main(["region", path, "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)["dp"]
    assert data["lower"] <= 25 / 36 <= data["t"] <= data["lower"] + 1e-6
    assert data["critical_mu"] == [data["t"]]
    assert data["direction"] == [1.0]
    fractional = System(A=[[1.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                        channel=GilbertElliott(p=[0.4], r=[0.4], h_good=[0.9], h_bad=[0.1]))
    path = str(save_system(fractional, tmp_path / "fractional.toml"))
    assert main(["region", path, "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)["dp"]
    assert data["critical_mu"] is None
    assert data["t"] is None
    assert "h_bad = 0" in data["critical_mu_reason"]


@pytest.mark.parametrize("p", [0.0, 1e-17])
def test_region_on_a_chain_that_never_moves_answers_and_gives_no_critical_mean_rate(capsys, tmp_path, p):
    """p + r = 0 with a given state (or p so small that 1 - p - r rounds to 1): a valid file whose burstiness is 1,
    so no mean rate can be varied at fixed burstiness. The membership still answers (by hand: at p = 0 the chain
    stays good and every packet arrives, so x+ = (1.5 - K) x is stabilised; at p = 1e-17 it reaches the bad state,
    absorbing, where nothing is delivered and x+ = 1.5 x, so no mode-dependent law stabilises the loop) and
    critical_mu is null with the reason: never exit 2 on a file the model accepts."""
    s = System(A=[[1.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[p], r=[0.0], state=["good"]))
    path = str(save_system(s, tmp_path / "still.toml"))
    assert main(["region", path, "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)["dp"]
    assert data["verdict"] == ("stable" if p == 0.0 else "unstable")
    assert data["critical_mu"] is None
    assert data["t"] is None
    assert "never move" in data["critical_mu_reason"]


def test_region_on_a_chain_with_a_channel_that_never_delivers_answers_without_a_critical_mean_rate(capsys, tmp_path):
    """h_good = h_bad = 0 on channel 2 (a file the model accepts): its mean rate is 0 whatever the chain, so there is
    no ray of mean rates through it; region answers the membership (by hand: channel 2 never delivers, so the second,
    decoupled mode x2+ = 1.2 x2 is never controlled) and gives critical_mu null with the reason, never exit 2."""
    s = System(A=np.diag([1.5, 1.2]), B=np.eye(2), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
               x0=[1.0, 1.0], channel=GilbertElliott(p=[0.4, 0.2], r=[0.4, 0.3], h_good=[1.0, 0.0]))
    path = str(save_system(s, tmp_path / "dead.toml"))
    for argv in ([], ["--direction", "1,0"]):
        assert main(["region", path, "--json", "-q", *argv]) == 0
        data = json.loads(capsys.readouterr().out)["dp"]
        assert data["verdict"] == "unstable"
        assert data["critical_mu"] is None
        assert "never deliver" in data["critical_mu_reason"]


def test_a_chain_lambda_is_printed_to_the_digits_its_own_accuracy_supports(tmp_path, capsys):
    """The one chain of tests/closedloop/test_markov_region.py's seeded chains at the ends of their mean rates (k = 97) whose
    coupled map has a defective root: lambda, and the coupled radius of its own gains (which lambda claims to be) by
    the dense eigenvalues and by ARPACK on the matrix-free map, spread over about 6e-6 (on the other chains they agree
    within 1e-9 of lambda). The text shows lambda to the digits that supports with ``±`` beside it, JSON and CSV round
    it so and give ``lambda_error``; 0.8352448407578126 claimed 16 digits. Reference: the two eigenvalue routines'
    spread on the same gains."""
    from packetloss_cvx.closedloop.markov_region import homogeneous_coupled_riccati
    from packetloss_cvx.closedloop.mjls import mean_square_radius

    from ..closedloop.test_markov_region import _chain_at_an_end

    A, B, chain, _ = _chain_at_an_end(97)
    path = str(save_system(System(A=A, B=B, horizon=2, state_weight=np.ones(4), input_weight=[1.0, 1.0],
                                  x0=np.ones(4), channel=chain), tmp_path / "defective.toml"))
    lam, _, K = homogeneous_coupled_riccati(A, B, chain, "next")
    radii = [mean_square_radius(A, B, chain, K, "next", method=method) for method in ("dense", "krylov")]
    spread = max(abs(lam - r) for r in radii)
    assert 1e-6 < spread < 1e-4                                  # known to about five digits
    argv = ["region", path, "--law", "dp", "--direction", "1,0", "-q"]
    assert main([*argv, "--json", "--out", str(tmp_path / "out")]) == 0
    data = json.loads(capsys.readouterr().out)["dp"]
    assert spread / 2 <= data["lambda_error"] <= spread
    assert data["lambda"] == float(f"{data['lambda']:.5g}")      # no more digits than the error supports
    half_unit = 0.5 * 10.0 ** (np.floor(np.log10(abs(data["lambda"]))) - 4)      # the fifth digit's rounding
    assert abs(data["lambda"] - lam) <= data["lambda_error"] + half_unit
    assert (tmp_path / "out" / "region.csv").read_text().splitlines()[1] == f"stable,{data['lambda']!r}"
    assert main(argv) == 0
    assert f"radius: {data['lambda']:.5g} ± {data['lambda_error']:.1g})" in capsys.readouterr().out


def test_a_chain_rate_map_prints_each_lambda_to_the_digits_its_own_accuracy_supports(tmp_path, capsys):
    """``region --grid`` behind the defective chain above (k = 97, mean rates (0, 0.5), from its stationary law: channel
    1 bad for ever): the grid point at the chain's own rates is that chain, whose lambda the dense and ARPACK radii of
    its gains know only to about 1.5e-5.
    Every grid lambda in JSON carries ``lambda_error`` beside it and no more digits than that supports; at the
    chain's own point the error brackets the two routines' spread (the reference, computed here on the chain
    itself) and lambda is within it of the eigenpair's value. Full digits (0.8352448407578126) failed this."""
    from packetloss_cvx.closedloop.markov_region import homogeneous_coupled_riccati
    from packetloss_cvx.closedloop.mjls import mean_square_radius

    from ..closedloop.test_markov_region import _chain_at_an_end

    A, B, chain, _ = _chain_at_an_end(97, everywhere=False)
    assert chain.mean_rate.tolist() == [0.0, 0.5]
    path = str(save_system(System(A=A, B=B, horizon=2, state_weight=np.ones(4), input_weight=[1.0, 1.0],
                                  x0=np.ones(4), channel=chain), tmp_path / "defective.toml"))
    lam, _, K = homogeneous_coupled_riccati(A, B, chain, "next")
    spread = max(abs(lam - mean_square_radius(A, B, chain, K, "next", method=method)) for method in ("dense", "krylov"))
    assert main(["region", path, "--law", "dp", "--grid", "3", "--direction", "1,0", "--json", "-q"]) == 0
    grid = json.loads(capsys.readouterr().out)["dp"]["grid"]
    assert grid["axis"] == [0.0, 0.5, 1.0]
    for row, errors in zip(grid["lambda"], grid["lambda_error"], strict=True):
        for value, error in zip(row, errors, strict=True):
            digits = max(1, min(17, int(np.floor(np.log10(abs(value) / error))))) if error else 17
            assert value == float(f"{value:.{digits}g}")          # no digit beyond what its own error supports
    value, error = grid["lambda"][1][0], grid["lambda_error"][1][0]  # rows: channel 2's rate; columns: channel 1's
    assert spread / 2 <= error <= spread
    digits = int(np.floor(np.log10(abs(value) / error)))         # 4 here: lambda_error 1.5e-5
    assert abs(value - lam) <= error + 0.5 * 10.0 ** (np.floor(np.log10(abs(value))) - digits + 1)   # its last digit
    assert len(repr(value).lstrip("0.")) <= 6                     # about five digits, not sixteen


def test_region_behind_a_chain_of_more_than_two_states_says_what_to_use_in_one_short_line(tmp_path, capsys):
    path = tmp_path / "three.toml"
    path.write_text((Path(packetloss_cvx.__file__).parent / "model" / "examples" / "two_actuator.toml").read_text()
                    .split("[channel]")[0] + """
[channel]
model = "markov"
transition = [[[0.9, 0.1, 0.0], [0.2, 0.6, 0.2], [0.0, 0.5, 0.5]], [[0.98, 0.02], [0.18, 0.82]]]
delivery = [[1.0, 0.5, 0.0], [1.0, 0.0]]
state = [2, 0]

[state]
x0 = [1.0, 1.0]
""")
    code = main(["region", str(path)])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1
    assert "channels of 3, 2 states" in err
    assert "MarkovChannel(" not in err
    assert len(err) < 300
