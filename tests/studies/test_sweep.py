"""Design sweeps: every kind of sweep against the QP twin at sample points, the grid's orientation,
files that read back exactly, chunking that does not change a bit, and the command line."""

import csv
import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.studies import read_mu_list, save_sweep, sweep


def _qp(system, protocol):
    return pl.solve_qp(system, protocol, with_gain=False, cross_check=False).cost


def test_two_channel_grid_orientation_against_the_qp(two_actuator):
    result = sweep(two_actuator, mu_grid=5, progress=False)
    assert result.dims == ("mu2", "mu1")
    assert result.shape == (5, 5)
    assert result.mu.shape == (25, 2)
    grid = {p: v.reshape(result.shape) for p, v in result.costs.items()}
    axis = np.linspace(0, 1, 5)
    for i, j in [(4, 1), (1, 4), (2, 3)]:             # grid[j, i] = J*(mu1 = axis[i], mu2 = axis[j])
        s = two_actuator.with_mu([axis[i], axis[j]])
        for p in ("tcp", "udp"):
            assert grid[p][j, i] == pytest.approx(_qp(s, p), rel=1e-6)
    deterministic = np.all((result.mu == 0) | (result.mu == 1), axis=1)
    plain = result.costs["udp"] - result.costs["tcp"]
    assert np.array_equal(result.difference[~deterministic], plain[~deterministic])
    assert np.all(result.difference[deterministic] == 0)   # the two problems coincide there
    assert np.all(result.difference[~deterministic] > 0)   # Theorem 2


def test_one_channel_grid_keeps_the_others(two_actuator):
    result = sweep(two_actuator, mu_grid=[0.2, 0.7], channel=1, protocols=("udp",), progress=False)
    assert result.dims == ("mu2",)
    assert result.difference is None
    assert result.mu.tolist() == [[0.9, 0.2], [0.9, 0.7]]
    assert result.costs["udp"][0] == pytest.approx(_qp(two_actuator.with_mu([0.9, 0.2]), "udp"), rel=1e-6)


def test_shared_channel_grid(two_actuator, pendulum):
    shared = sweep(two_actuator, mu_grid=3, shared=True, progress=False)
    assert shared.dims == ("nu",)
    assert shared.mu.tolist() == [[0, 0], [0.5, 0.5], [1, 1]]
    single = sweep(pendulum, mu_grid=[0.3], protocols=("tcp",), progress=False)
    assert single.costs["tcp"][0] == pytest.approx(_qp(pendulum.with_mu([0.3]), "tcp"), rel=1e-6)


def test_x0_scales_scale_the_noise_free_cost_quadratically(two_actuator):
    result = sweep(two_actuator, x0_scales=[0.0, 1.0, -3.0], progress=False)
    assert result.x0.tolist() == [[0, 0], [1, 1], [-3, -3]]
    for p in ("tcp", "udp"):
        zero, one, three = result.costs[p]
        assert zero == 0.0                           # no noise, Q = 0: nothing to pay from x0 = 0
        assert three == pytest.approx(9 * one, rel=1e-12)
        assert one == pytest.approx(_qp(two_actuator, p), rel=1e-6)


def test_horizons_against_the_qp(two_actuator):
    result = sweep(two_actuator, horizons=[3, 10], progress=False)
    assert result.horizon.tolist() == [3, 10]
    data = two_actuator.to_dict()
    data["cost"]["horizon"] = 3
    short = system_from_dict(data)
    assert result.costs["udp"][0] == pytest.approx(_qp(short, "udp"), rel=1e-6)
    assert result.costs["udp"][1] == pytest.approx(_qp(two_actuator, "udp"), rel=1e-6)


def test_chunk_size_does_not_change_a_bit(two_actuator):
    whole = sweep(two_actuator, mu_grid=9, progress=False)
    pieces = sweep(two_actuator, mu_grid=9, chunk_size=7, progress=False)
    for key, value in whole.arrays().items():
        assert np.array_equal(value, pieces.arrays()[key]), key


def test_files_read_back_exactly(two_actuator, tmp_path):
    result = sweep(two_actuator, mu_grid=4, progress=False)
    paths = save_sweep(result, tmp_path / "out", netcdf=True)
    with np.load(paths["npz"]) as npz:
        for key, value in result.arrays().items():
            assert np.array_equal(npz[key], value), key
        assert npz["dims"].tolist() == ["mu2", "mu1"]
    with open(paths["csv"]) as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["mu1", "mu2", "x0_1", "x0_2", "horizon", "cost_tcp", "cost_udp", "cost_diff"]
    table = np.array(rows[1:], dtype=float)
    assert np.array_equal(table[:, 5], result.costs["tcp"])
    assert np.array_equal(table[:, :2], result.mu)
    xr = pytest.importorskip("xarray")
    with xr.open_dataset(paths["netcdf"], engine="scipy") as ds:
        assert float(ds.cost_udp.sel(mu1=1.0, mu2=0.0)) == result.costs["udp"].reshape(4, 4)[0, 3]
        assert np.array_equal(ds.cost_diff.values.ravel(), result.difference)


def test_read_mu_list(tmp_path, two_actuator):
    path = tmp_path / "points.csv"
    path.write_text("mu1,mu2\n0.1,0.2\n\n1,0.5\n")
    assert read_mu_list(path, 2).tolist() == [[0.1, 0.2], [1.0, 0.5]]
    result = sweep(two_actuator, mu_list=read_mu_list(path, 2), progress=False)
    assert result.dims == ("point",)
    assert result.mu.tolist() == [[0.1, 0.2], [1.0, 0.5]]
    for text, match in [("0.1\n", "line 1: expected 2"), ("0.1,2\n", "line 1: expected probabilities"),
                        ("a,b\nx,0.2\n", "line 2: expected numbers"), ("mu1,mu2\n", "no rows")]:
        path.write_text(text)
        with pytest.raises(pl.InputError, match=match) as info:
            read_mu_list(path, 2)
        assert info.value.field == "mu_list"
    with pytest.raises(pl.InputError, match="cannot read"):
        read_mu_list(tmp_path / "missing.csv", 2)


@pytest.mark.parametrize(("kwargs", "field"), [
    ({}, "sweep"), ({"mu_grid": 3, "horizons": [2]}, "sweep"), ({"mu_grid": 1}, "mu_grid"),
    ({"mu_grid": [1.5]}, "mu_grid"), ({"mu_grid": 3, "channel": 2}, "channel"),
    ({"mu_grid": 3, "channel": 0, "shared": True}, "channel"), ({"horizons": [0]}, "horizons"),
    ({"horizons": [2.5]}, "horizons"), ({"x0_scales": []}, "x0_scales"),
    ({"mu_grid": 3, "chunk_size": 0}, "chunk_size"),
    ({"mu_grid": 3, "protocols": ()}, "protocols"), ({"mu_list": [[0.5]]}, "mu_list"),
    ({"x0_scales": [1.0], "channel": 0}, "channel"),
])
def test_bad_input_names_the_field(two_actuator, kwargs, field):
    with pytest.raises(pl.InputError) as info:
        sweep(two_actuator, progress=False, **kwargs)
    assert info.value.field == field


def test_three_channels_need_a_channel_or_shared():
    s = pl.System(A=np.eye(2), B=np.ones((2, 3)), horizon=2, state_weight=[1, 1], input_weight=[1, 1, 1],
                  mu=[0.5, 0.5, 0.5], x0=[1, 0])
    with pytest.raises(pl.InputError, match="give channel="):
        sweep(s, mu_grid=3)
    assert sweep(s, mu_grid=3, channel=2, progress=False).mu[:, 2].tolist() == [0, 0.5, 1]


def test_cli_sweep_writes_files_and_no_bar_when_not_a_terminal(capsys, tmp_path):
    out = tmp_path / "out"
    code = main(["sweep", "two_actuator", "--mu-grid", "3", "--out", str(out), "--json"])
    captured = capsys.readouterr()
    assert code == 0
    assert captured.err == ""
    data = json.loads(captured.out)
    assert data["shape"] == [3, 3]
    assert data["cost_diff"]["min"] == 0.0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["manifest.json", "sweep.csv", "sweep.npz", "sweep_diff.png", "sweep_tcp.png", "sweep_udp.png"]
    assert main(["sweep", "pendulum", "--x0-scales", "-1:1:3", "--out", str(tmp_path / "x0"), "--quiet"]) == 0
    assert (tmp_path / "x0" / "sweep.png").exists()


@pytest.mark.parametrize(("argv", "flag"), [
    (["--mu-grid", "3", "--channel", "3"], "--channel"), (["--mu-grid", "3", "--netcdf"], "--netcdf"),
    (["--x0-scales", "0:1"], "--x0-scales"), (["--horizons", "2.5"], "--horizons"),
    (["--mu-list", "missing.csv"], "--mu-list"), (["--mu-grid", "1"], "--mu-grid"),
    (["--mu-grid", "3", "--dask", "nowhere"], "--dask"),
])
def test_cli_bad_input_exit_2_naming_the_flag(capsys, tmp_path, monkeypatch, argv, flag):
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "two_actuator", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"error: {flag}:" in err


def _kronecker_radius(A, B, K, mu):
    """Independent reference: vec E[x x'] evolves by kron(Abar, Abar) + sum_i mu_i (1 - mu_i) kron(b_i k_i, b_i k_i)."""
    Abar = A - B @ np.diag(mu) @ K
    L = np.kron(Abar, Abar)
    for i in range(len(mu)):
        bk = np.outer(B[:, i], K[i])
        L = L + mu[i] * (1 - mu[i]) * np.kron(bk, bk)
    return float(np.max(np.abs(np.linalg.eigvals(L))))


def test_stability_column_against_the_kronecker_matrix_and_sampling(two_actuator):
    result = sweep(two_actuator, mu_list=[[0.25, 0.0], [0.9, 0.5], [1.0, 1.0]], stability=True, progress=False)
    assert sorted(result.radii) == ["tcp", "udp"]
    for k, mu in enumerate(result.mu):
        for p in ("tcp", "udp"):
            K = pl.closed_form(two_actuator.with_mu(mu), p).gain
            assert result.radii[p][k] == pytest.approx(_kronecker_radius(two_actuator.A, two_actuator.B, K, mu),
                                                       rel=1e-10)
    # at mu = (1, 1) both laws are the nominal one and the radius is rho(A - B K)^2
    K = pl.closed_form(two_actuator.with_mu([1.0, 1.0]), "tcp").gain
    rho = max(abs(np.linalg.eigvals(two_actuator.A - two_actuator.B @ K)))
    assert result.radii["tcp"][2] == pytest.approx(rho**2, rel=1e-10)
    # at (0.25, 0) the TCP-like law is mean-square unstable: E||x_t||^2 grows like radius^t when sampled
    rng = np.random.default_rng(0)
    K = pl.closed_form(two_actuator.with_mu([0.25, 0.0]), "tcp").gain
    x = np.tile([1.0, 1.0], (20000, 1))
    second = []
    for _ in range(12):
        v = rng.random((20000, 2)) < [0.25, 0.0]
        x = x @ two_actuator.A.T - ((x @ K.T) * v) @ two_actuator.B.T
        second.append(np.mean(np.sum(x**2, axis=1)))
    assert second[-1] / second[-2] == pytest.approx(result.radii["tcp"][0], rel=0.1)
    assert result.radii["tcp"][0] > 1


def test_stability_in_the_files_and_on_the_command_line(two_actuator, tmp_path, capsys):
    result = sweep(two_actuator, mu_grid=3, stability=True, progress=False)
    with np.load(save_sweep(result, tmp_path / "s")["npz"]) as npz:
        assert np.array_equal(npz["radius_udp"], result.radii["udp"])
    assert main(["sweep", "two_actuator", "--mu-grid", "3", "--stability", "--json", "--quiet"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["radius_tcp"]["max"] == pytest.approx(float(np.max(result.radii["tcp"])), rel=1e-12)


def test_a_markov_channel_is_refused():
    bursty = pl.load_example("pendulum_bursty")
    assert bursty.channel is not None
    with pytest.raises(pl.InputError, match="Gilbert-Elliott") as info:
        sweep(bursty, x0_scales=[1.0])
    assert info.value.field == "system"


def test_a_sweep_of_zero_costs_saves_its_data_and_skips_only_the_log_figures(capsys, tmp_path):
    # x0 = 0 without noise: every cost is 0, valid input; the log contours have nothing to draw
    path = pl.save_system(pl.load_example("two_actuator").with_x0([0.0, 0.0]), tmp_path / "zero.toml")
    assert main(["sweep", str(path), "--mu-grid", "3", "--out", str(tmp_path / "z"), "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["figures_not_drawn"] == ["sweep_tcp.png", "sweep_udp.png", "sweep_diff.png"]
    assert sorted(p.name for p in (tmp_path / "z").iterdir()) == ["manifest.json", "sweep.csv", "sweep.npz"]
    assert data["cost_tcp"]["max"] == 0.0


def test_a_horizon_sweep_converts_to_xarray_and_netcdf(capsys, tmp_path, two_actuator):
    xr = pytest.importorskip("xarray")
    # horizon is a coordinate of the dataset, not also a data variable (xarray refuses a name in both)
    result = sweep(two_actuator, horizons=[3, 5], progress=False)
    dataset = result.to_xarray()
    assert dataset["horizon"].values.tolist() == [3, 5]
    assert dataset["cost_tcp"].sel(horizon=5).item() == result.costs["tcp"][1]
    assert main(["sweep", "two_actuator", "--horizons", "3,5", "--out", str(tmp_path), "--netcdf", "--quiet"]) == 0
    back = xr.open_dataset(tmp_path / "sweep.nc", engine="scipy")
    assert back["cost_udp"].values.tolist() == result.costs["udp"].tolist()



def test_a_sweep_of_one_point_says_point(capsys):
    assert main(["sweep", "two_actuator", "--horizons", "3", "--quiet"]) == 0
    assert capsys.readouterr().out.splitlines()[0] == "two-actuator: horizon sweep, 1 point (1 over horizon)"



def test_to_xarray_without_the_extra_says_how_to_install_it():
    """After the README's `pip install .` (no xarray), the README's design-study block ended in a bare
    ModuleNotFoundError traceback."""
    import sys
    from unittest import mock

    from packetloss_cvx.errors import InputError
    from packetloss_cvx.studies import sweep

    result = sweep(pl.load_example("two_actuator"), mu_grid=3, progress=False)
    with mock.patch.dict(sys.modules, {"xarray": None}), pytest.raises(InputError, match=r"packetloss-cvx\[xarray\]"):
        result.to_xarray()


def test_cli_sweep_json_carries_every_point_against_the_qp(capsys, two_actuator):
    assert main(["sweep", "two_actuator", "--mu-grid", "3", "--json", "-q"]) == 0
    data = json.loads(capsys.readouterr().out)
    table = data["table"]
    assert list(table) == ["mu1", "mu2", "x0_1", "x0_2", "horizon", "cost_tcp", "cost_udp", "cost_diff"]
    assert data["axes"] == {"mu2": [0.0, 0.5, 1.0], "mu1": [0.0, 0.5, 1.0]}
    assert all(len(column) == 9 for column in table.values())
    # rows follow mu2 (slowest), then mu1: the axes' Cartesian product in C order
    assert [(table["mu2"][k], table["mu1"][k]) for k in range(9)] == [(a, b) for a in (0, 0.5, 1) for b in (0, 0.5, 1)]
    assert table["horizon"] == [two_actuator.horizon] * 9
    assert all(type(v) is int for v in table["horizon"])
    assert table["x0_1"] == [two_actuator.x0[0]] * 9
    for k in (1, 4, 5):
        s = two_actuator.with_mu([table["mu1"][k], table["mu2"][k]])
        for p in ("tcp", "udp"):
            assert table[f"cost_{p}"][k] == pytest.approx(_qp(s, p), rel=1e-6)
        assert table["cost_diff"][k] == pytest.approx(table["cost_udp"][k] - table["cost_tcp"][k], rel=1e-9)


def test_cli_sweep_json_names_the_file_above_its_size(capsys, tmp_path, monkeypatch):
    from packetloss_cvx.cli import sweep as sweep_command

    monkeypatch.setattr(sweep_command, "JSON_MAX_POINTS", 8)       # a 3 x 3 grid is over the size
    out = tmp_path / "out"
    assert main(["sweep", "two_actuator", "--mu-grid", "3", "--json", "-q", "--out", str(out)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["table"] is None
    assert data["table_file"] == str(out / "sweep.csv")
    assert "9 points" in data["note"]
    assert "sweep.csv" in data["note"]
    with open(data["table_file"]) as handle:
        assert len(list(csv.reader(handle))) == 1 + 9
    assert main(["sweep", "two_actuator", "--mu-grid", "3", "--json", "-q"]) == 0       # no --out: how to get them
    data = json.loads(capsys.readouterr().out)
    assert data["table"] is None
    assert data["table_file"] is None
    assert "--out DIR" in data["note"]
    monkeypatch.setattr(sweep_command, "JSON_MAX_POINTS", 9)       # at the size: carried
    assert main(["sweep", "two_actuator", "--mu-grid", "3", "--json", "-q"]) == 0
    assert len(json.loads(capsys.readouterr().out)["table"]["cost_tcp"]) == 9


def test_mu_schedule_and_mu_list_are_read_by_one_reader_with_one_set_of_rules(tmp_path):
    """--mu-schedule (np.loadtxt: '#' comments, no header) and --mu-list (csv: a header, no comments) had
    different rules; both now read a header row, '#' comments, blank lines and a byte-order mark alike."""
    from packetloss_cvx.cli.common import read_schedule

    rows = np.random.default_rng(0).uniform(0, 1, (10, 2)).round(3)
    text = "\ufeffmu1,mu2\n# an Excel export with a note\n" + "\n".join(f"{a},{b}" for a, b in rows) + "\n\n"
    path = tmp_path / "channels.csv"
    path.write_text(text, encoding="utf-8")
    assert read_schedule(str(path)).tolist() == rows.tolist()
    assert read_mu_list(path, 2).tolist() == rows.tolist()
    path.write_text("0.5,0.5\n0.5\n")
    for read in (lambda: read_schedule(str(path)), lambda: read_mu_list(path, 2)):
        with pytest.raises(pl.InputError, match="line 2: expected 2 numbers, found 1"):
            read()
