"""Work budgets (budgets.py): every count and size a user can type, and every size a system and a method imply,
is refused before work starts beyond its budget (BudgetError, exit 2 naming the option and the variable that raises
it), input files are regular files within their cap, the last exit-1 inputs are exit 2, and a name on a refused
command's line is printed with its control characters escaped (docs/design.md §4, "Work budgets").

The command-line cases run as processes of their own where the exit code and the single stderr line are the
contract (forked from a parent that imported ``packetloss_cvx.cli`` and NumPy: tests/processes.py); each
references an independent expectation (a hand-computed work count, the operating system's own verdict on a file)
rather than the code under test.
"""

import json
import os
import time

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.claims import audit
from packetloss_cvx.montecarlo.simulate import simulate
from packetloss_cvx.studies import sweep
from packetloss_cvx.studies.burstiness import burstiness_sweep

from ..processes import Zygote

#: a 5,001-digit integer in a TOML matrix (Python refuses int-from-text beyond 4300 digits)
BIG_INT_TOML = """[plant]
A = [[1{zeros}]]
B = [[1.0]]
[cost]
horizon = 3
state_weight = [1.0]
input_weight = [1.0]
[channel]
mu = [0.5]
[state]
x0 = [1.0]
""".replace("{zeros}", "0" * 5000)


@pytest.fixture(scope="module")
def zygote():
    """The parent the command-line cases fork from: the start-up and these imports are not what they test."""
    with Zygote(["packetloss_cvx.cli", "packetloss_cvx.cli.common", "numpy"]) as parent:
        yield parent


def cli(zygote, *argv, env=None):
    """``python -m packetloss_cvx argv`` (forked from ``zygote``): (exit code, stdout, stderr)."""
    proc = zygote.run(list(argv), module="packetloss_cvx", timeout=120, env={**os.environ, **(env or {})})
    return proc.returncode, proc.stdout, proc.stderr


def one_error_line(err):
    """The one stderr line of a refused command (no traceback, nothing else)."""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("packetloss-cvx: error: "), err
    return lines[0]


# --- the API refuses before any work ---------------------------------------------------------------------


def test_simulate_refuses_a_huge_sample_count_at_once(two_actuator):
    start = time.process_time()
    with pytest.raises(pl.ResourceError) as info:
        simulate(two_actuator, 2 ** 63)
    assert time.process_time() - start < 1.0          # refused, not started (it ran past 300 s)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.field == "samples"
    # 2^63 samples x (N = 10 steps x 2 plans) x n (n + m) = 2 x 2 x 4: the work counted by hand
    assert err.needed == pytest.approx(2.0 ** 63 * 20 * 8)
    assert err.env == "PACKETLOSS_CVX_BUDGET_SIMULATE_WORK"


def test_simulate_closed_loop_counts_steps_and_laws(two_actuator):
    with pytest.raises(pl.ResourceError) as info:
        simulate(two_actuator, 10_000, steps=10_000_000, closed_loop=True, progress=False)
    # 1e4 samples x (10 x 2 plans + 1e7 steps x 3 loops) x 8
    assert info.value.needed == pytest.approx(1e4 * (20 + 3e7) * 8)


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"mu_grid": 2000}, "mu_grid"),                        # 2-D: 4e6 points
    ({"mu_grid": 10 ** 7, "shared": True}, "mu_grid"),      # 1-D: 1e7 points, before linspace
    ({"x0_scales": np.zeros(1_000_001)}, "x0_scales"),
    ({"horizons": np.full(1_000_001, 10)}, "horizons"),
])
def test_sweep_refuses_points_beyond_the_budget(two_actuator, kwargs, field):
    with pytest.raises(pl.ResourceError) as info:
        sweep(two_actuator, progress=False, **kwargs)
    assert info.value.field == field
    assert info.value.budget == 1e6


def test_sweep_refuses_work_beyond_the_budget():
    # 200 different horizons of about 1e5 on a stable 2 x 2 plant: 2e7 point-steps, each horizon its own batch
    s = pl.System(A=[[0.9, 0.1], [0.0, 0.8]], B=np.eye(2), horizon=10, state_weight=[1.0, 1.0],
                  input_weight=[1.0, 1.0], mu=[0.9, 0.5], x0=[1.0, 1.0])
    start = time.process_time()
    with pytest.raises(pl.ResourceError) as info:
        sweep(s, horizons=list(range(100_000, 100_200)), progress=False)
    assert time.process_time() - start < 2.0
    steps = sum(range(100_000, 100_200))
    assert info.value.field == "horizons"
    # per protocol: steps (n^3 + m^3 + 40) + 1000 per batched step (one batch per horizon), two protocols
    assert info.value.needed == pytest.approx(2 * (steps * 56 + 1000 * steps))


def test_burstiness_sweep_refuses_a_million_values():
    bursty = pl.load_example("pendulum_bursty")
    with pytest.raises(pl.ResourceError) as info:
        burstiness_sweep(bursty, np.linspace(0, 0.9, 10 ** 6), progress=False)
    assert info.value.field == "correlations"


def test_audit_and_allocation_refuse_huge_counts(two_actuator):
    with pytest.raises(pl.ResourceError, match="PACKETLOSS_CVX_BUDGET_AUDIT_CASES"):
        audit(random=10 ** 12, progress=False)
    with pytest.raises(pl.ResourceError, match="PACKETLOSS_CVX_BUDGET_ALLOCATION_BOXES") as info:
        pl.allocate(two_actuator, "udp", 8.0, [1.0, 0.05], max_boxes=10 ** 12)
    assert info.value.field == "max_boxes"


def test_a_budget_is_raised_or_lowered_by_its_variable(monkeypatch):
    from packetloss_cvx.budgets import check, limit
    assert limit("audit_cases") == 1e4
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_AUDIT_CASES", "2e12")
    check("audit_cases", 1e12, "random", "1e12 cases")                  # raised on purpose: allowed
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_AUDIT_CASES", "inf")
    check("audit_cases", 1e300, "random", "1e300 cases")
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_SIMULATE_WORK", "100")    # lowered: a small run is refused
    with pytest.raises(pl.ResourceError, match="SIMULATE_WORK=1.6e"):
        simulate(pl.load_example("two_actuator"), 1000, progress=False)
    for bad in ("abc", "-1", "0", "nan", "1e400x"):
        monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_AUDIT_CASES", bad)
        with pytest.raises(pl.InputError) as info:
            limit("audit_cases")
        assert info.value.field == "PACKETLOSS_CVX_BUDGET_AUDIT_CASES"


def test_budget_error_pickles_and_renames():
    import pickle

    from packetloss_cvx.errors import BudgetError
    err = BudgetError("samples", "too many", 3.0, 2.0, "PACKETLOSS_CVX_BUDGET_SIMULATE_WORK")
    again = pickle.loads(pickle.dumps(err))
    assert (type(again), again.field, again.needed, again.budget, again.env) == (
        BudgetError, "samples", 3.0, 2.0, "PACKETLOSS_CVX_BUDGET_SIMULATE_WORK")
    renamed = err.renamed("--samples")
    assert str(renamed) == "--samples: too many"
    assert isinstance(renamed, pl.ResourceError)


# --- input files: regular files within their cap ----------------------------------------------------------


def test_input_files_must_be_regular_and_within_the_cap(tmp_path):
    from packetloss_cvx.cli.common import read_schedule
    from packetloss_cvx.studies import read_mu_list
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)                 # opening it for reading would block for ever without a writer
    huge = tmp_path / "huge.csv"
    with open(huge, "wb") as handle:           # sparse: 17 MiB by st_size, nothing written
        handle.truncate(17 * 2 ** 20)
    readers = [lambda p: read_mu_list(p, 2), read_schedule, pl.load_system]
    for read in readers:
        for path in ("/dev/zero", fifo):
            with pytest.raises(pl.InputError, match="not a regular file"):
                read(str(path))
        with pytest.raises(pl.InputError, match="is a directory"):
            read(str(tmp_path))
        with pytest.raises(pl.ResourceError, match="PACKETLOSS_CVX_BUDGET_FILE_BYTES"):
            read(str(huge))


def test_mu_list_rows_count_against_the_point_budget(tmp_path, monkeypatch):
    from packetloss_cvx.studies import read_mu_list
    path = tmp_path / "mu.csv"
    path.write_text("mu1,mu2\n" + "0.5,0.25\n" * 1001)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_SWEEP_POINTS", "1000")
    with pytest.raises(pl.ResourceError, match="more than 1000 rows") as info:
        read_mu_list(path, 2)
    assert info.value.field == "mu_list"
    path.write_text("mu1,mu2\n" + "0.5,0.25\n" * 1000)        # the header is not a point
    assert read_mu_list(path, 2).shape == (1000, 2)


def test_an_unbounded_file_budget_still_reads_a_small_file(tmp_path, monkeypatch):
    from packetloss_cvx.studies import read_mu_list
    path = tmp_path / "mu.csv"
    path.write_text("mu1,mu2\n0.5,0.25\n")
    for value in ("inf", "1e15"):           # a read sized by the budget allocated it: MemoryError
        monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_FILE_BYTES", value)
        assert read_mu_list(path, 2).tolist() == [[0.5, 0.25]]


def test_a_toml_integer_beyond_python_limit_is_bad_input(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text(BIG_INT_TOML)
    with pytest.raises(pl.InputError) as info:
        pl.load_system(path)
    assert info.value.field == "file"
    assert "4300 digits" in str(info.value)


# --- names printed with control characters escaped ---------------------------------------------------------


def test_solve_prints_a_hostile_name_escaped(tmp_path, capsys, zygote):
    from packetloss_cvx.cli import main
    path = tmp_path / "evil.toml"
    path.write_text('name = "ev\\u001b[31mil\\nline\\u0007"\n' + BIG_INT_TOML.replace("1" + "0" * 5000, "1.1"))
    assert main(["solve", str(path), "--no-qp", "-q"]) == 0
    out = capsys.readouterr().out
    assert not any(ch in out for ch in "\x1b\x07"), out
    assert out.splitlines()[0].startswith("ev\\x1b[31mil\\nline\\x07: n=1")
    code, _, err = cli(zygote, "solve", str(tmp_path / "x\x1b[31m\x07.toml"))     # a path on the error line
    assert code == 2
    assert "\x1b" not in err
    assert "x\\x1b[31m\\x07.toml" in one_error_line(err)


# --- the command line: exit 2, one line ------------------------------------------------------------------


def main_line(argv, capsys):
    """``main(argv)`` in this process: (exit code, its one stderr line); nothing on stdout."""
    from packetloss_cvx.cli import main
    code = main(argv)
    out, err = capsys.readouterr()
    assert out == ""
    return code, one_error_line(err)


@pytest.mark.parametrize(("argv", "option", "variable"), [
    (["simulate", "two_actuator", "--samples", "1000000000000"], "--samples", "SIMULATE_WORK=1.6e+14"),
    (["sweep", "two_actuator", "--mu-grid", "3", "--dask", "local", "--workers", "1000000"], "--workers",
     "DASK_WORKERS=1e+06"),
    # 1e6 values x 2 protocols x N = 80 x (2 D^3 + 2500), D = n (1 + m) = 8: 5.6384e11, shown rounded up
    (["sweep", "pendulum_bursty", "--burstiness", "0:0.9:1000000"], "--burstiness", "SWEEP_WORK=5.64e+11"),
])
def test_cli_refuses_counts_beyond_their_budget(zygote, argv, option, variable):
    start = time.perf_counter()
    code, out, err = cli(zygote, *argv)
    line = one_error_line(err)
    assert code == 2
    assert out == ""
    assert line.startswith(f"packetloss-cvx: error: {option}: ")
    assert f"PACKETLOSS_CVX_BUDGET_{variable}" in line
    assert time.perf_counter() - start < 30          # refused upfront (each climbed for minutes before)


@pytest.mark.parametrize(("argv", "option", "variable"), [
    (["simulate", "two_actuator", "--closed-loop", "--steps", "10000000"], "--samples", "SIMULATE_WORK=2.41e+12"),
    (["audit", "--random", "1000000000000"], "--random", "AUDIT_CASES=1e+12"),
    (["allocate", "two_actuator", "--protocol", "udp", "--alpha", "8", "--beta", "1,0.05", "--max-boxes",
      "1000000000000"], "--max-boxes", "ALLOCATION_BOXES=1e+12"),
    (["sweep", "two_actuator", "--x0-scales", "0:1:1000000000000"], "--x0-scales", "SWEEP_POINTS=1e+12"),
    (["sweep", "two_actuator", "--mu-grid", "2000"], "--mu-grid", "SWEEP_POINTS=4e+06"),
    # integers beyond the double range (401 digits): OverflowError, exit 1, before
    (["simulate", "two_actuator", "--samples", "1" + "0" * 400], "--samples", "SIMULATE_WORK=inf"),
    (["simulate", "two_actuator", "--closed-loop", "--steps", "1" + "0" * 400], "--samples", "SIMULATE_WORK=inf"),
    (["audit", "--random", "1" + "0" * 400], "--random", "AUDIT_CASES=inf"),
    (["sweep", "two_actuator", "--mu-grid", "1" + "0" * 400], "--mu-grid", "SWEEP_POINTS=inf"),
    (["allocate", "two_actuator", "--protocol", "udp", "--alpha", "8", "--beta", "1,0.05", "--max-boxes",
      "1" + "0" * 400], "--max-boxes", "ALLOCATION_BOXES=inf"),
])
def test_cli_in_process_refuses_counts_beyond_their_budget(argv, option, variable, capsys):
    code, line = main_line(argv, capsys)
    assert code == 2
    assert line.startswith(f"packetloss-cvx: error: {option}: ")
    assert f"PACKETLOSS_CVX_BUDGET_{variable}" in line
    assert len(line) < 400          # a 401-digit count is shown by its size, not echoed


@pytest.mark.parametrize(("argv", "option"), [
    (["sweep", "two_actuator", "--horizons", "inf"], "--horizons"),
    (["solve", "two_actuator", "--out", "a" * 5000], "--out"),
    (["solve", "a" * 100_000], "file"),
    (["sweep", "two_actuator", "--mu-list", "/dev/zero"], "--mu-list"),
])
def test_cli_exits_2_with_one_line(zygote, argv, option):
    code, out, err = cli(zygote, *argv)
    assert code == 2
    assert out == ""
    assert one_error_line(err).startswith(f"packetloss-cvx: error: {option}: ")


@pytest.mark.parametrize(("argv", "option"), [
    # --channels inf,1 was an OverflowError and nan,1 a ValueError (int() of the parsed float): exit 1
    (["region", "two_actuator", "--grid", "3", "--channels", "inf,1"], "--channels"),
    (["region", "two_actuator", "--grid", "3", "--channels", "nan,1"], "--channels"),
    (["region", "two_actuator", "--grid", "3", "--channels", "1,-inf"], "--channels"),
    (["region", "pendulum_bursty", "--grid", "3", "--channels", "inf"], "--channels"),
    (["sweep", "two_actuator", "--horizons", "nan"], "--horizons"),
    (["sweep", "two_actuator", "--horizons", "5,2.5"], "--horizons"),
    (["sweep", "two_actuator", "--x0-scales", "0:1:inf"], "--x0-scales"),
    (["sweep", "two_actuator", "--burstiness", "0:0.9:nan"], "--burstiness"),
    (["sweep", "two_actuator", "--mu-grid", "3", "--out", "d" * 5000], "--out"),
    (["simulate", "two_actuator", "--closed-loop", "--plot", "p" * 300 + ".png"], "--plot"),
    (["solve", "two_actuator", "--mu-schedule", "/dev/zero"], "--mu-schedule"),
    (["audit", "/dev/zero", "--random", "0"], "file"),
])
def test_cli_in_process_exits_2_with_one_line(argv, option, capsys):
    code, line = main_line(argv, capsys)
    assert code == 2
    assert line.startswith(f"packetloss-cvx: error: {option}: ")


def test_cli_refuses_a_fifo_and_a_huge_integer(tmp_path, zygote):
    fifo = tmp_path / "mu.csv"
    os.mkfifo(fifo)
    code, _, err = cli(zygote, "solve", "two_actuator", "--mu-schedule", str(fifo))
    assert code == 2
    assert "not a regular file" in one_error_line(err)
    big = tmp_path / "big.toml"
    big.write_text(BIG_INT_TOML)
    code, _, err = cli(zygote, "audit", str(big), "--random", "0")
    assert code == 2
    assert one_error_line(err).startswith("packetloss-cvx: error: file: ")


# --- horizons and memory priced before the work: solve, simulate's closed loop, allocate --------------------


def scalar_file(tmp_path, horizon):
    """A stable scalar plant (a = 0.9, b = 1) over ``horizon`` steps, as a TOML file."""
    path = tmp_path / f"scalar-{horizon}.toml"
    path.write_text(f"[plant]\nA = [[0.9]]\nB = [[1.0]]\n[cost]\nhorizon = {horizon}\nstate_weight = [1.0]\n"
                    "input_weight = [1.0]\n[channel]\nmu = [0.5]\n[state]\nx0 = [1.0]\n")
    return str(path)


def test_solve_prices_its_horizon_with_and_without_the_qp_cross_check(tmp_path, capsys, monkeypatch):
    """``solve`` of a scalar plant over 1e6 steps with the default QP cross-check ran past 120 s at 3.1 GiB; over
    5e7 steps with ``--no-qp`` it ended in "unexpected MemoryError" (exit 1) after 45 s. Its horizon is priced
    before the work: 1e6 steps with the cross-check are refused (exit 2, one line naming the horizon, ``--no-qp``
    and the variable), the closed forms alone are answered; the memory is priced too (here a budget of 1e8 bytes
    stands in for a quarter of a small machine)."""
    path = scalar_file(tmp_path, 10 ** 6)
    start = time.perf_counter()
    code, line = main_line(["solve", path], capsys)
    assert time.perf_counter() - start < 20
    # by hand: 2 protocols x 1e6 steps x (0.45 + 0.0175 + 28 + 1.1 + 1.5) = 6.2135e7 > 6e7
    assert code == 2
    assert line.startswith("packetloss-cvx: error: cost.horizon: N = 1000000 (n = 1, m = 1) with the QP cross-check")
    assert "--no-qp" in line
    assert line.endswith("PACKETLOSS_CVX_BUDGET_SOLVE_WORK=6.22e+07")
    from packetloss_cvx.cli import main
    assert main(["solve", path, "--no-qp", "-q", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["horizon"] == 10 ** 6
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e8")
    code, line = main_line(["solve", path, "--no-qp"], capsys)
    # by hand: 1e6 steps x (260 + 15 + 40) bytes = 3.15e8
    assert code == 2
    assert line.startswith("packetloss-cvx: error: cost.horizon: N = 1000000 (n = 1, m = 1) (about 0.293 GiB)")
    assert line.endswith("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES=3.15e+08")


def test_a_closed_loop_beyond_its_memory_budget_is_a_budget_refusal(capsys, monkeypatch):
    """A closed-loop simulation whose block arrays exceed the memory budget exited 1 ("ResourceError") where the
    help promises 2 for a count beyond its budget: it is refused under ``--steps`` with the variable."""
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "4e9")      # the same verdict on any machine
    code, line = main_line(["simulate", "pendulum", "--closed-loop", "--steps", "10000000", "--samples", "10"], capsys)
    # by hand: a block of 10 runs x 10000001 steps x (2 m + 16 n + 16 laws) = 10 x 10000001 x 114 = 1.14e10 bytes
    assert code == 2
    assert line.startswith("packetloss-cvx: error: --steps: ")
    assert line.endswith("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES=1.15e+10")


def test_parse_constraint_prices_its_dimension():
    """``parse_constraint("mu1 <= 1", 10**9)`` raised a bare MemoryError allocating dense rows of 1e9 coefficients:
    the rows' memory is priced first (by hand: 5 arrays x 8 bytes x 1e9 = 4e10 bytes), refused under ``m``; a
    dimension within the budget still parses."""
    from packetloss_cvx.allocation.grammar import parse_constraint
    start = time.perf_counter()
    with pytest.raises(pl.ResourceError, match="^m: .*PACKETLOSS_CVX_BUDGET_MEMORY_BYTES=4e\\+10$") as info:
        parse_constraint("mu1 <= 1", 10 ** 9)
    assert isinstance(info.value, pl.InputError)
    assert time.perf_counter() - start < 1
    G, h = parse_constraint("mu1 + mu3 <= 1", 3)
    assert G.tolist() == [[1.0, 0.0, 1.0]]
    assert h.tolist() == [1.0]


def two_channel_file(tmp_path, horizon):
    """A stable scalar plant with two channels (b = (2, 1)) over ``horizon`` steps, as a TOML file."""
    path = tmp_path / f"two-channel-{horizon}.toml"
    path.write_text(f"[plant]\nA = [[0.9]]\nB = [[2.0, 1.0]]\n[cost]\nhorizon = {horizon}\nstate_weight = [1.0]\n"
                    "input_weight = [1.0, 1.0]\n[channel]\nmu = [0.6, 0.6]\n[state]\nx0 = [1.0]\n")
    return str(path)


def test_the_udp_like_search_prices_its_boxes_by_their_horizon(tmp_path, capsys, monkeypatch):
    """A box of the UDP-like branch and bound costs O(N) (its cost evaluations): at N = 1e5 the default cap of 2e4
    boxes was about 17 hours, and the search ran for minutes. A cap the caller gives is priced (refused under
    ``--max-boxes``: by hand, 2e4 boxes x (1000 + 30 (100 + 3e4 x 1.02)) = 1.8422e10 units at N = 3e4); the default
    cap is what the ``allocation_work`` budget affords, so the search answers within the budget's time (here a
    budget of 2.5 boxes at N = 3000 stops a search that needs more at 2 boxes, 'gap_not_certified')."""
    code, line = main_line(["allocate", two_channel_file(tmp_path, 30_000), "--protocol", "udp", "--alpha", "0.5",
                            "--beta", "1,0.5", "--max-boxes", "20000"], capsys)
    assert code == 2
    assert line.startswith("packetloss-cvx: error: --max-boxes: 20000 boxes at N = 30000 (n = 1, m = 2: ")
    assert line.endswith("PACKETLOSS_CVX_BUDGET_ALLOCATION_WORK=1.85e+10")
    system = pl.load_system(two_channel_file(tmp_path, 3000))
    full = pl.allocate(system, "udp", alpha=0.5, beta=[1.0, 0.5], progress=False)
    assert full.status == "optimal"
    assert full.boxes > 2
    box = 1000 + 30 * (100 + 3000 * 1.02)              # by hand: a box at N = 3000, n = 1, m = 2
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_ALLOCATION_WORK", str(2.5 * box))
    capped = pl.allocate(system, "udp", alpha=0.5, beta=[1.0, 0.5], progress=False)
    assert capped.status == "gap_not_certified"
    assert capped.boxes == 2
    assert "cap of 2 boxes" in capped.method
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_ALLOCATION_WORK", str(0.5 * box))
    with pytest.raises(pl.ResourceError, match="^horizon: one box of the UDP-like search at N = 3000"):
        pl.allocate(system, "udp", alpha=0.5, beta=[1.0, 0.5], progress=False)


# --- sizes a system and a method imply: refused upfront as bad input (a ValueError), exit 2 and one line ------------


def wide_file(tmp_path):
    """Twenty channels on a scalar plant over 5000 steps: the sparse QP's own bytes exceed solve's fitted peak."""
    s = pl.System(A=[[0.9]], B=np.ones((1, 20)), horizon=5000, state_weight=[1.0], input_weight=np.ones(20),
                  mu=np.full(20, 0.5), x0=[1.0])
    return str(pl.save_system(s, tmp_path / "wide.toml"))


@pytest.mark.parametrize(("argv", "env", "start", "instead", "variable"), [
    # by hand: 8 x (3 (N n)(N m) + 2 (N m)^2 + 4 N n^2) = 8 x (1200 + 800 + 160) = 17280 bytes, N = 10, n = m = 2
    (["solve", "two_actuator", "--method", "dense", "--no-qp"], {"MEMORY_BYTES": "1e4"},
     "method: method 'dense' for N = 10, n = 2, m = 2", "use method='recursion'", "MEMORY_BYTES=1.73e+04"),
    # by hand: 2 modes x n^2 = 2 x 16 = 32 rows of the coupled operator
    (["region", "pendulum_bursty", "--law", "dp", "--grid", "3"], {"OPERATOR_ROWS": "10"},
     "channel: the MJLS second-moment operator, dense with 2^m n^2 = 2 * 4^2 = 32 rows", "use fewer chain states",
     "OPERATOR_ROWS=32"),
    # by hand: the closed forms 5000 x 1075 + the sparse QP 5000 x (260 + 8000 + 13000) + 1e7 = 1.2168e8 bytes
    (["solve", "{wide}", "--protocol", "tcp"], {"MEMORY_BYTES": "1e8"},
     "cost.horizon: N = 5000 (n = 1, m = 20) with the QP cross-check", "--no-qp skips the cross-check",
     "MEMORY_BYTES=1.22e+08"),
])
def test_cli_refuses_system_derived_sizes_with_exit_2_and_one_line(zygote, tmp_path, argv, env, start, instead,
                                                                    variable):
    """The dense method's memory, the MJLS operator's rows and the QP's memory are refused before any work like a
    count the caller typed: exit 2 and one line saying what to use instead (they were ResourceErrors, exit 1: the
    dense method on the command line, the QP's inside an audit)."""
    argv = [word.replace("{wide}", wide_file(tmp_path)) if word == "{wide}" else word for word in argv]
    code, out, err = cli(zygote, *argv, env={f"PACKETLOSS_CVX_BUDGET_{k}": v for k, v in env.items()})
    line = one_error_line(err)
    assert (code, out) == (2, "")
    assert line.startswith(f"packetloss-cvx: error: {start}")
    assert f"; {instead}" in line
    assert line.endswith(f", or to run it on purpose set PACKETLOSS_CVX_BUDGET_{variable}")


def test_api_refuses_system_derived_sizes_as_typed_bad_input(monkeypatch):
    """The same refusals in the API: a BudgetError, which is a ValueError (InputError) and a ResourceError (the
    name callers already catch), with the bytes or rows asked for counted by hand."""
    from packetloss_cvx.closedloop.mjls import second_moment_operator
    from packetloss_cvx.errors import BudgetError
    from packetloss_cvx.lq.markov_cost import exact_closed_form
    from packetloss_cvx.model.channel import GilbertElliott

    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e4")
    two = pl.load_example("two_actuator")
    with pytest.raises(BudgetError) as info:
        pl.closed_form(two, "tcp", method="dense")
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, pl.ResourceError)
    assert (info.value.field, info.value.needed) == ("method", 17280.0)
    # the exact Markov cost's dense route, N = 80, n = 4, m = 1: 8 x (6 x 80^2 + 3 x 320 x 80 + 4 x 80 x 16)
    with pytest.raises(BudgetError) as info:
        exact_closed_form(pl.load_example("pendulum_bursty"), method="dense")
    assert isinstance(info.value, ValueError)
    assert (info.value.field, info.value.needed) == ("method", 962560.0)
    # the sparse QP, N = 10, n = m = 2: 260 x 40 + 400 x 40 + 650 x 20 + 1e7 bytes
    with pytest.raises(BudgetError) as info:
        pl.ExpectedCostQP(two, "tcp", "sparse")
    assert isinstance(info.value, ValueError)
    assert (info.value.field, info.value.needed) == ("horizon", 10039400.0)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_OPERATOR_ROWS", "35")
    one_channel = GilbertElliott(p=[0.5], r=[0.5])                    # 2 modes x 4^2 = 32 rows: within 35
    assert second_moment_operator(np.eye(4), np.ones((4, 1)), one_channel, np.ones((1, 4))).shape == (32, 32)
    two_channels = GilbertElliott(p=[0.5, 0.5], r=[0.5, 0.5])         # 4 modes x 3^2 = 36 rows: refused
    with pytest.raises(BudgetError) as info:
        second_moment_operator(np.eye(3), np.ones((3, 2)), two_channels, np.ones((2, 3)))
    assert isinstance(info.value, ValueError)
    assert (info.value.field, info.value.needed) == ("channel", 36.0)


# --- chance rows exact under a Markov chain: priced as the chain's ------------------------------------------------


def _scalar_behind_gilbert(horizon):
    """A stable scalar plant (a = 0.9, b = 1) behind a bursty Gilbert channel (p = 0.02, r = 0.18) over ``horizon``
    steps, and its limits: an input box (2 rows a step) and one chance row on the state."""
    from packetloss_cvx.model.channel import GilbertElliott
    system = pl.System(A=[[0.9]], B=[[1.0]], horizon=horizon, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                       channel=GilbertElliott(p=[0.02], r=[0.18]))
    return system, pl.Constraints(u_min=[-2.0], u_max=[2.0], chance=[([1.0], 1.75, 0.2)])


@pytest.mark.parametrize(("args", "work", "size", "memory"), [
    # N = 10, n = m = 1, one chance row, 20 linear rows. work: 6.8e-4 x 100 x 10 x 2 / 2 + 0.65 x 1000 = 650.68, and
    # behind a Gilbert channel (K = 2) 1 x 1 x (0.56 x 1000 + 3.2e-3 x 1e4) = 592 more; a solve: 1600 + 30 + 5.5 + 70
    # + 120 us (+ 32 behind the chain); bytes: 8 x (300 + 200 + 900) + 1000 x 100 + qp (2600 + 4000 + 6500 + 1e7),
    # behind the chain 1000 x (115 + 50) more
    ((10, 1, 1, 20, 1, 0), 650.68, 1825.5, 10124300.0),
    ((10, 1, 1, 20, 1, 2), 1242.68, 1857.5, 10289300.0),
    # a 3-state chain behind two channels, N = 10, n = 2: the chain's terms times m^2 (K - 1) = 8 and (K - 1) = 2;
    # work 6.8e-4 x 400 x 10 x 4 / 2 + 0.65 x 1000 x 4 = 2605.44, + 8 x 592; a solve 1600 + 120 + 22 + 70 + 240
    # (+ 8 x 32); bytes 8 x (1200 + 400 + 3600) + 1000 x (240 + 80) + qp (10400 + 16000 + 13000 + 1e7), + 2 x 1000
    # x (460 + 100)
    ((10, 2, 2, 20, 1, 3), 2605.44 + 8 * 592, 2052 + 256, 10401000.0 + 1120000),
    # a Bernoulli program (states 0) and a chain without chance rows are priced alike
    ((10, 1, 1, 20, 0, 2), 0.68, 1705.5, 10024300.0),
])
def test_chance_rows_behind_a_chain_are_priced_at_the_hand_values(args, work, size, memory):
    from packetloss_cvx.budgets import constrained_bytes, constrained_work, mpc_solve_size
    N, n, m, rows, chance, states = args
    assert constrained_work(N, n, m, chance, states) == pytest.approx(work, rel=1e-12)
    assert mpc_solve_size(N, n, m, rows, chance, states) == pytest.approx(size / 5000, rel=1e-12)
    assert constrained_bytes(N, n, m, rows, chance, states) == pytest.approx(memory, rel=1e-12)


def test_chain_states_are_the_largest_channel():
    from packetloss_cvx.budgets import chain_states
    from packetloss_cvx.model.channel import MarkovChannel
    three = MarkovChannel(transition=[[[0.9, 0.1], [0.4, 0.6]], [[0.8, 0.2, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]]],
                          delivery=[[1.0, 0.0], [1.0, 0.5, 0.0]])
    assert chain_states(three) == 3
    assert chain_states(None) == 0


@pytest.mark.parametrize(("variable", "price"), [("SOLVE_WORK", 1242.68), ("MEMORY_BYTES", 10289300.0)])
@pytest.mark.parametrize("factor", [0.999, 1.001])
def test_a_constrained_program_behind_a_chain_is_priced_with_its_chain_rows(monkeypatch, variable, price, factor):
    """``ConstrainedQP`` behind a Gilbert channel poses its chance row exact under the chain: refused just under
    the chain's hand price (the plug-in row's, 650.68 work units and 10124300 bytes, is within it), built just
    over it."""
    from packetloss_cvx.errors import BudgetError
    from packetloss_cvx.qp.constrained import ConstrainedQP
    system, limits = _scalar_behind_gilbert(10)
    monkeypatch.setenv(f"PACKETLOSS_CVX_BUDGET_{variable}", repr(factor * price))
    if factor < 1:
        start = time.perf_counter()
        with pytest.raises(BudgetError, match=r"^horizon: the constrained program of N = 10 \(n = 1, m = 1; 20 linear "
                                              r"rows, 1 chance row exact under a 2-state chain\)") as info:
            ConstrainedQP(system, "tcp", limits)
        assert time.perf_counter() - start < 1
        assert info.value.needed == pytest.approx(price, rel=1e-12)
        assert str(info.value).endswith(f"or to run it on purpose set PACKETLOSS_CVX_BUDGET_{variable}="
                                        + ("1.25e+03" if variable == "SOLVE_WORK" else "1.03e+07"))
        ConstrainedQP(system.with_mu(system.mu_schedule), "tcp", limits)    # the plug-in twin: within the budget
    else:
        assert ConstrainedQP(system, "tcp", limits).chain is not None


@pytest.mark.parametrize("factor", [0.999, 1.001])
def test_solve_prices_its_constrained_programs_behind_a_chain(tmp_path, capsys, monkeypatch, factor):
    """``solve`` on a file behind a Gilbert channel with a chance row: its two programs (one per protocol) are priced
    with their chain rows, 2 x 1242.68 work units by hand: refused just under (exit 2, one line), run just over."""
    system, limits = _scalar_behind_gilbert(10)
    path = tmp_path / "gilbert.toml"
    from packetloss_cvx.model.files import save_system
    save_system(system, path, constraints=limits)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_SOLVE_WORK", repr(factor * 2 * 1242.68))
    if factor < 1:
        code, line = main_line(["solve", str(path)], capsys)
        assert code == 2
        assert line.startswith("packetloss-cvx: error: cost.horizon: the constrained program of N = 10 (n = 1, m = 1; "
                               "20 linear rows, 1 chance row exact under a 2-state chain) x 2")
        assert line.endswith("PACKETLOSS_CVX_BUDGET_SOLVE_WORK=2.49e+03")
    else:
        from packetloss_cvx.cli import main
        assert main(["solve", str(path), "-q", "--json"]) == 0
        out = json.loads(capsys.readouterr().out)
        assert "exact under the chain" in json.dumps(out)


class _Admitted(Exception):
    """Raised where the constrained loop would draw its paths: its budget let it through."""


def _admitted(*args, **kwargs):
    raise _Admitted


#: 10 runs x 4 steps of the loop behind a Gilbert channel, N = 40, one chance row, 80 linear rows: the certainty-
#: equivalent program at 1600 + 120 + 88 + 280 + 1920 = 4008 us, the two expected-cost ones with their chance rows
#: exact under the chain at 3.2e-3 x 40^4 = 8192 us more, the two clipped laws at 2e-3 of a 5 ms solve
MPC_PRICE = 10 * 4 * (4008 / 5000 + 2 * 12200 / 5000 + 2 * 2e-3)


@pytest.mark.parametrize("factor", [0.999, 1.001])
def test_the_constrained_loop_behind_a_chain_prices_its_exact_rows(monkeypatch, factor):
    """``simulate_mpc`` behind a chain: the expected-cost programs' solves priced with their chain rows (227.424
    solves of 5 ms by hand; priced as plug-in rows, 96.352): refused just under, admitted just over."""
    from packetloss_cvx.errors import BudgetError
    from packetloss_cvx.montecarlo import mpc
    system, limits = _scalar_behind_gilbert(40)
    monkeypatch.setattr(mpc, "loop_paths", _admitted)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MPC_SOLVES", repr(factor * MPC_PRICE))
    if factor < 1:
        with pytest.raises(BudgetError, match=r"^samples: 10 runs of 4 steps x 3 programs and 2 clipped laws \(2 with "
                                              r"the rows exact under the 2-state chain at 2\.4 of a 5 ms solve each, "
                                              r"the others at 0\.8: N = 40, n = 1, m = 1, 80 linear rows, 1 chance "
                                              r"row\) is over the budget of 227 solves") as info:
            mpc.simulate_mpc(system, limits, samples=10, steps=4)
        assert info.value.needed == pytest.approx(MPC_PRICE, rel=1e-12)
    else:
        with pytest.raises(_Admitted):
            mpc.simulate_mpc(system, limits, samples=10, steps=4)


@pytest.mark.parametrize("factor", [0.999, 1.001])
def test_simulate_prices_the_constrained_loop_behind_a_chain(tmp_path, capsys, monkeypatch, factor):
    """``simulate --mpc-samples`` on a file behind a Gilbert channel: the same hand price (MPC_PRICE) in the command
    line's preflight, refused just under with one line, past the preflight just over."""
    from packetloss_cvx.model.files import save_system
    system, limits = _scalar_behind_gilbert(40)
    path = tmp_path / "gilbert.toml"
    save_system(system, path, constraints=limits)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MPC_SOLVES", repr(factor * MPC_PRICE))
    argv = ["simulate", str(path), "--samples", "2", "--mpc-samples", "10", "--steps", "4"]
    if factor < 1:
        code, line = main_line(argv, capsys)
        assert code == 2
        assert line.startswith("packetloss-cvx: error: --mpc-samples: 10 runs of 4 steps x 3 programs (the constrained "
                               "loop; 2 with the rows exact under the 2-state chain at 2.4 of a 5 ms solve each, the "
                               "others at 0.8: N = 40, n = 1, m = 1, 80 linear rows, 1 chance row)")
    else:
        from packetloss_cvx.montecarlo import mpc
        monkeypatch.setattr(mpc, "loop_paths", _admitted)
        from packetloss_cvx.cli import main
        assert main(argv) == 1        # past the preflight: the loop reached its paths (stubbed to raise)
        assert capsys.readouterr().err.strip() == "packetloss-cvx: unexpected _Admitted:"
