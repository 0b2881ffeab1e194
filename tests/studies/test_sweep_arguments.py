"""The arguments of sweep (its flags, its --mu-list files, and the --out it shares with reproduce): a typed
InputError naming the field in the API, exit 2 with one stderr line naming the flag on the command line,
refused before anything is allocated or computed; never a traceback, a MemoryError or a flag silently
ignored."""

import sys

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.errors import InputError
from packetloss_cvx.studies import read_mu_list, sweep


def _one_line_exit_2(capsys, argv, field):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert field in err[0], err
    assert "Traceback" not in err[0]
    return err[0]



def test_a_huge_mu_grid_is_refused_before_it_is_allocated(capsys, two_actuator):
    # the K x K grid's size is checked before the meshgrid is built (10^8 squared would be 71 PiB)
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "100000000", "--quiet"], "--mu-grid")
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "1001", "--quiet"], "--mu-grid")
    with pytest.raises(InputError, match="mu_grid"):
        sweep(two_actuator, mu_grid=10**12, shared=True)



def test_a_huge_horizon_is_refused_by_its_own_flag(capsys):
    # the flag's own name, and the number as given: 1e20 must not wrap to a negative int64 on the way
    line = _one_line_exit_2(capsys, ["sweep", "two_actuator", "--horizons", "5,1e20", "--quiet"], "--horizons")
    assert "-9223372036854775808" not in line
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--horizons", "1000000000", "--quiet"], "--horizons")



def test_shared_outside_a_mu_grid_names_shared(capsys):
    # the error names the flag that was given (--shared), not a neighbouring one
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--horizons", "3", "--shared", "--quiet"], "--shared")



def test_workers_without_dask_is_refused(capsys, two_actuator):
    # --workers without --dask would be ignored: refused, so nobody believes the sweep ran on W workers
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--workers", "2", "--quiet"], "--workers")
    with pytest.raises(InputError, match="workers"):
        sweep(two_actuator, mu_grid=3, workers=2)



def test_mu_list_first_row_with_a_typo_is_not_skipped_as_a_header(tmp_path):
    # a header is a row of names: a first row that is a mistyped number is an error, not a header to skip
    path = tmp_path / "typo.csv"
    path.write_text("0.5,O.5\n0.9,0.9\n")
    with pytest.raises(InputError, match="line 1"):
        read_mu_list(path, 2)
    header = tmp_path / "header.csv"
    header.write_text("mu1,mu2\n0.5,0.25\n")
    assert read_mu_list(header, 2).tolist() == [[0.5, 0.25]]



def test_mu_list_with_a_byte_order_mark_keeps_its_first_point(tmp_path):
    # a byte order mark (as spreadsheets write it) is not part of the first number
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf0.5,0.5\n0.9,0.1\n")
    assert read_mu_list(path, 2).tolist() == [[0.5, 0.5], [0.9, 0.1]]



def test_mu_list_nan_names_its_row(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("mu1,mu2\n0.5,0.5\n0.9,nan\n")
    with pytest.raises(InputError, match="line 3"):
        read_mu_list(path, 2)



def test_netcdf_without_out_or_xarray_fails_before_the_sweep(capsys, monkeypatch, tmp_path):
    import packetloss_cvx.studies.design as design

    def boom(*args, **kwargs):
        raise AssertionError("the sweep ran before the flags were checked")

    monkeypatch.setattr(design, "run_in_process", boom)
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--netcdf", "--quiet"], "--netcdf")
    monkeypatch.setitem(sys.modules, "xarray", None)      # import xarray -> ImportError
    # a missing xarray is found before the sweep runs, and named by the flag that needs it
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--netcdf", "--out",
                              str(tmp_path / "o"), "--quiet"], "--netcdf")
    assert not (tmp_path / "o").exists()



@pytest.mark.parametrize("argv", [["sweep", "two_actuator", "--mu-grid", "3"],
                                  ["sweep", "pendulum_bursty", "--burstiness", "0,0.5"],
                                  ["reproduce", "--quick"]])
def test_an_empty_out_is_refused_not_the_current_folder(capsys, monkeypatch, tmp_path, argv):
    # --out "" (an unset $DIR) must not mean the current folder
    monkeypatch.chdir(tmp_path)
    _one_line_exit_2(capsys, [*argv, "--out", "", "--quiet"], "--out")
    assert not list(tmp_path.iterdir())



def test_a_dask_address_of_an_unusable_scheme_is_a_one_line_error(capsys):
    pytest.importorskip("distributed")
    # a scheme Dask knows but cannot use here (ucx without its package) is the --dask flag's one-line error
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--dask", "ucx://x:1", "--quiet"], "--dask")



@pytest.mark.parametrize("extra", [["--shared"], ["--channel", "1"], ["--workers", "2"], ["--chunk-size", "5"]])
def test_burstiness_refuses_the_grid_flags_it_would_ignore(capsys, extra):
    # a grid flag a burstiness sweep would ignore is refused, not silently dropped
    _one_line_exit_2(capsys, ["sweep", "pendulum_bursty", "--burstiness", "0,0.5", *extra, "--quiet"], extra[0])



def test_a_failed_dask_address_leaves_no_default_client_behind(capsys):
    distributed = pytest.importorskip("distributed")
    # a half-built Client must not stay the process's default client: the next xarray / dask call in the same
    # process (e.g. sweep --netcdf) would pick it up and fail
    _one_line_exit_2(capsys, ["sweep", "two_actuator", "--mu-grid", "3", "--dask", "ucx://x:1", "--quiet"], "--dask")
    with pytest.raises(ValueError, match="No clients found"):
        distributed.default_client()
