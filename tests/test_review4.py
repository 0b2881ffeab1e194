"""Review of sweep / reproduce / the thread policy as a hostile user: each test is one defect found,
failing before its fix (bad input a typed error naming the field, one stderr line, exit 2)."""

import sys

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.errors import InputError
from packetloss_cvx.studies import read_mu_list, sweep, two_channel_sweep
from packetloss_cvx.threads import blas_threads, set_blas_threads


def _one_line_exit_2(capsys, argv, field):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert field in err[0], err
    assert "Traceback" not in err[0]
    return err[0]


def test_a_huge_mu_grid_is_refused_before_it_is_allocated(capsys, two_actuator):
    # was: MemoryError (71 PiB for the K x K meshgrid), exit 1 "unexpected"
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "100000000", "--quiet"], "--mu-grid")
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "1001", "--quiet"], "--mu-grid")
    with pytest.raises(InputError, match="mu_grid"):
        sweep(two_actuator, mu_grid=10**12, shared=True)


def test_a_huge_horizon_is_refused_by_its_own_flag(capsys):
    # was: "cost.horizon: expected an integer >= 1, found -9223372036854775808" (1e20 wrapped by astype(int))
    line = _one_line_exit_2(capsys, ["sweep", "two_actuator", "--horizons", "5,1e20", "--quiet"], "--horizons")
    assert "-9223372036854775808" not in line
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--horizons", "1000000000", "--quiet"], "--horizons")


def test_shared_outside_a_mu_grid_names_shared(capsys):
    # was: "--channel: channel and shared apply to mu_grid only" when only --shared was given
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--horizons", "3", "--shared", "--quiet"], "--shared")


def test_workers_without_dask_is_refused(capsys, two_actuator):
    # was: silently ignored (exit 0): the user believed the sweep ran on W workers
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--workers", "2", "--quiet"], "--workers")
    with pytest.raises(InputError, match="workers"):
        sweep(two_actuator, mu_grid=3, workers=2)


def test_mu_list_first_row_with_a_typo_is_not_skipped_as_a_header(tmp_path):
    # was: a first row "0.5,O.5" (letter O) silently dropped as if it were a header: one point fewer
    path = tmp_path / "typo.csv"
    path.write_text("0.5,O.5\n0.9,0.9\n")
    with pytest.raises(InputError, match="row 1"):
        read_mu_list(path, 2)
    header = tmp_path / "header.csv"
    header.write_text("mu1,mu2\n0.5,0.25\n")
    assert read_mu_list(header, 2).tolist() == [[0.5, 0.25]]


def test_mu_list_with_a_byte_order_mark_keeps_its_first_point(tmp_path):
    # was: "\ufeff0.5,0.5" failed float() and the first point was skipped as a header
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf0.5,0.5\n0.9,0.1\n")
    assert read_mu_list(path, 2).tolist() == [[0.5, 0.5], [0.9, 0.1]]


def test_mu_list_nan_names_its_row(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("mu1,mu2\n0.5,0.5\n0.9,nan\n")
    with pytest.raises(InputError, match="row 3"):
        read_mu_list(path, 2)


def test_netcdf_without_out_or_xarray_fails_before_the_sweep(capsys, monkeypatch, tmp_path):
    import packetloss_cvx.studies.design as design

    def boom(*args, **kwargs):
        raise AssertionError("the sweep ran before the flags were checked")

    monkeypatch.setattr(design, "run_in_process", boom)
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--netcdf", "--quiet"], "--netcdf")
    monkeypatch.setitem(sys.modules, "xarray", None)      # import xarray -> ImportError
    # was: the whole sweep, then "unexpected ModuleNotFoundError", exit 1
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--netcdf", "--out",
                              str(tmp_path / "o"), "--quiet"], "--netcdf")
    assert not (tmp_path / "o").exists()


def test_grid_difference_is_not_negative_at_the_deterministic_corners(two_actuator):
    # was: J_Delta = -2.9e-16 at mu = (0, 1) in reproduce's results.json (Theorem 2 visibly violated)
    result = two_channel_sweep(two_actuator, np.linspace(0, 1, 11))
    assert np.all(result.difference >= 0)
    assert result.difference[0, 0] == result.difference[-1, 0] == result.difference[0, -1] == 0
    assert result.difference[-1, -1] == 0
    # off the corners it is still J*_udp - J*_tcp (against the QP at one interior point)
    point = two_actuator.with_mu([0.3, 0.6])
    qp = pl.solve_qp(point, "udp").cost - pl.solve_qp(point, "tcp").cost
    assert result.difference[6, 3] == pytest.approx(qp, rel=1e-6)


def test_report_does_not_say_theorem_2_fails_because_of_rounding():
    from packetloss_cvx.cli.reproduce_report import _cost_mixed  # noqa: PLC2701 (test of a paragraph)

    axis = np.linspace(0, 1, 3)
    tcp = np.array([[3.0, 2.0, 1.0], [2.5, 1.5, 0.9], [2.0, 1.0, 0.5]])
    udp = tcp + 0.1
    udp[2, 0] = np.nextafter(tcp[2, 0], 0)                 # rounding at a deterministic corner
    diff = udp - tcp
    diff[2, 0] = 0.0                                      # the cancellation-free J_Delta there
    text, _ = _cost_mixed({"mixed": {"axis": axis, "tcp": tcp, "udp": udp, "diff": diff}}, "tcp")
    assert "NOT every grid point" not in text
    diff[1, 1] = -1.0                                    # a real violation is still reported
    text, _ = _cost_mixed({"mixed": {"axis": axis, "tcp": tcp, "udp": udp, "diff": diff}}, "tcp")
    assert "NOT every grid point" in text


def test_set_blas_threads_takes_numpy_integers():
    # was: set_blas_threads(np.int64(2)) -> InputError "expected an integer >= 1 or None, found np.int64(2)"
    try:
        set_blas_threads(np.int64(2))
        assert blas_threads() == 2
        assert type(blas_threads()) is int
        for bad in (0, -1, 1.5, True, "abc", np.float64(2.0)):
            with pytest.raises(InputError, match="threads"):
                set_blas_threads(bad)
    finally:
        set_blas_threads(1)


@pytest.mark.parametrize("argv", [["sweep", "two_actuator", "--mu-grid", "3"],
                                  ["sweep", "pendulum_bursty", "--burstiness", "0,0.5"],
                                  ["reproduce", "--quick"]])
def test_an_empty_out_is_refused_not_the_current_folder(capsys, monkeypatch, tmp_path, argv):
    # was: --out "" (an unset $DIR) wrote every file into the current folder
    monkeypatch.chdir(tmp_path)
    _one_line_exit_2(capsys, [*argv, "--out", "", "--quiet"], "--out")
    assert not list(tmp_path.iterdir())


def test_a_dask_address_of_an_unusable_scheme_is_a_one_line_error(capsys):
    pytest.importorskip("distributed")
    # was: "unexpected TypeError: Can't instantiate abstract class UCXConnector", exit 1
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--dask", "ucx://x:1", "--quiet"], "--dask")


def test_the_dask_docs_example_grid_is_within_the_sweep_cap():
    # was: docs/dask.md ran sweep(system, mu_grid=1001, ...): 1001^2 > MAX_SWEEP_POINTS, an InputError
    import re
    from pathlib import Path

    from packetloss_cvx.studies.design import MAX_SWEEP_POINTS

    text = (Path(__file__).resolve().parents[1] / "docs" / "dask.md").read_text()
    sizes = [int(k) for k in re.findall(r"mu_grid=(\d+)", text) + re.findall(r"--mu-grid (\d+)", text)]
    assert sizes
    assert all(k * k <= MAX_SWEEP_POINTS for k in sizes), sizes


def test_the_grid_sweeps_run_under_the_blas_policy(monkeypatch, two_actuator):
    # was: shared_channel_sweep / two_channel_sweep looped analysis.cost_difference (dense (N m)^3 per point)
    # with the process's BLAS threads: the pendulum's 298-point sweep took 0.45 s threaded, 0.19 s on one
    from threadpoolctl import threadpool_info, threadpool_limits

    import packetloss_cvx.studies.sweeps as sweeps

    seen = []
    original = sweeps.cost_difference

    def spy(*args, **kwargs):
        seen.append(max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
        return original(*args, **kwargs)

    monkeypatch.setattr(sweeps, "cost_difference", spy)
    with threadpool_limits(2, user_api="blas"):
        sweeps.shared_channel_sweep(two_actuator, [0.2, 0.7])
        sweeps.two_channel_sweep(two_actuator, [0.2, 0.7])
        after = max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
    assert seen == [1] * 6
    assert after == 2          # the caller's setting is restored


def test_reproduce_computes_under_the_blas_policy(monkeypatch):
    # was: its steps outside the sweeps (the maximisers, tables) ran with the process's BLAS threads
    from threadpoolctl import threadpool_info, threadpool_limits

    import packetloss_cvx.cli.reproduce as rep

    seen = []

    def spy(*args, **kwargs):
        seen.append(max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
        return {}

    for name in ("log_cost_pendulum", "mixed_grids", "mixed_allocations", "eigenvalue_tables"):
        monkeypatch.setattr(rep.pf, name, spy)
    monkeypatch.setattr(rep, "audit", spy)
    with threadpool_limits(2, user_api="blas"):
        rep._compute(rep.SETTINGS["quick"], False, {})      # noqa: SLF001
    assert seen == [1] * 6


@pytest.mark.parametrize("extra", [["--shared"], ["--channel", "1"], ["--workers", "2"], ["--chunk-size", "5"]])
def test_burstiness_refuses_the_grid_flags_it_would_ignore(capsys, extra):
    # was: exit 0 with each of these flags silently ignored
    _one_line_exit_2(capsys, ["sweep", "pendulum_bursty", "--burstiness", "0,0.5", *extra, "--quiet"], extra[0])


def test_a_horizon_sweep_converts_to_xarray_and_netcdf(capsys, tmp_path, two_actuator):
    xr = pytest.importorskip("xarray")
    # was: ValueError "variables {'horizon'} are found in both data_vars and coords"; CLI exit 1 "unexpected"
    result = sweep(two_actuator, horizons=[3, 5], progress=False)
    dataset = result.to_xarray()
    assert dataset["horizon"].values.tolist() == [3, 5]
    assert dataset["cost_tcp"].sel(horizon=5).item() == result.costs["tcp"][1]
    assert main(["sweep", "two_actuator", "--horizons", "3,5", "--out", str(tmp_path), "--netcdf", "--quiet"]) == 0
    back = xr.open_dataset(tmp_path / "sweep.nc", engine="scipy")
    assert back["cost_udp"].values.tolist() == result.costs["udp"].tolist()


def test_a_failed_dask_address_leaves_no_default_client_behind(capsys):
    distributed = pytest.importorskip("distributed")
    # was: the half-built Client('ucx://x:1') stayed the process's default client, so the next
    # xarray / dask call in the same process (e.g. sweep --netcdf) failed with its TypeError
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--dask", "ucx://x:1", "--quiet"], "--dask")
    with pytest.raises(ValueError, match="No clients found"):
        distributed.default_client()
