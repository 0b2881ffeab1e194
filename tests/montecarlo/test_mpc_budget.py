"""The ``mpc_solves`` budget prices each solve of the constrained loop by its program's size (`mpc_solve_size`, the
formula fitted by benchmarks/mpc_solve_time.py): the formula's hand values, and the loop refused just above and
admitted just below the hand-computed price, through the API and the command line."""

import pytest

from packetloss_cvx import Constraints, System
from packetloss_cvx.budgets import mpc_solve_size, mpc_solves
from packetloss_cvx.cli import main
from packetloss_cvx.errors import BudgetError
from packetloss_cvx.model.files import save_system
from packetloss_cvx.montecarlo import mpc

VARIABLE = "PACKETLOSS_CVX_BUDGET_MPC_SOLVES"


@pytest.mark.parametrize(("size", "micro"), [
    # 1600 + 0.75 N (n + m)^2 + 0.055 N^2 n m + 3.5 rows + 0.6 chance N^2 (n + m), in us
    ((10, 2, 1, 20, 0), 1600 + 67.5 + 11 + 70),
    ((200, 8, 3, 4400, 0), 1600 + 18150 + 52800 + 15400),
    ((100, 4, 2, 400, 1), 1600 + 2700 + 4400 + 1400 + 36000),
    ((4, 2, 2, 40, 1), 1600 + 48 + 3.52 + 140 + 38.4),
])
def test_a_solve_is_priced_by_its_program_size_in_5_ms_solves(size, micro):
    assert mpc_solve_size(*size) == pytest.approx(micro / 5000, rel=1e-12)


def test_the_loop_counts_runs_steps_and_programs_at_that_price():
    assert mpc_solves(10, 4, 3, size=0.5) == 60.0
    assert mpc_solves(10, 4, 3, clipped=2, size=0.5) == pytest.approx(60.0 + 40 * 2 * 2e-3, rel=1e-12)


def _plant() -> System:
    return System(A=[[1.1, 0.2], [0.0, 0.8]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=4, state_weight=[1.0, 2.0],
                  input_weight=[1.0, 0.5], x0=[1.0, -0.5], noise_cov=[[0.02, 0.0], [0.0, 0.01]], mu=[0.7, 0.6])


#: 2 + 2 input bounds, 2 x 2 rate rows, 2 state limits a step (40 rows over N = 4) and one chance row
LIMITS = Constraints(u_min=[-1.0, -1.0], u_max=[1.0, 1.0], du_max=[0.15, 0.15], x_max=[1.02, 1e3],
                     chance=[([1.0, 0.0], 1.1, 0.2)])
#: 10 runs x 4 steps x (3 programs (2 expected-cost, 1 certainty-equivalent) at 1829.92 us / 5 ms each and 2 clipped
#: laws at 2e-3 of a solve each)
PRICE = 10 * 4 * (3 * 1829.92 / 5000 + 2 * 2e-3)


class _Admitted(Exception):
    """Raised where the loop would draw its paths: the budget let it through."""


def _admitted(*args, **kwargs):
    raise _Admitted


@pytest.mark.parametrize(("budget", "refused"), [(PRICE * 0.999, True), (PRICE * 1.001, False)])
def test_simulate_mpc_is_refused_above_the_price_and_admitted_below(monkeypatch, budget, refused):
    monkeypatch.setattr(mpc, "loop_paths", _admitted)
    monkeypatch.setenv(VARIABLE, repr(budget))
    if refused:
        with pytest.raises(BudgetError, match=r"samples: 10 runs of 4 steps x 3 programs and 2 clipped laws \(0\.37 of "
                                              r"a 5 ms solve each: N = 4, n = 2, m = 2, 40 linear rows, 1 chance "
                                              r"row\) is over the budget of 44 solves of 5 ms"):
            mpc.simulate_mpc(_plant(), LIMITS, samples=10, steps=4)
    else:
        with pytest.raises(_Admitted):
            mpc.simulate_mpc(_plant(), LIMITS, samples=10, steps=4)


def test_a_longer_horizon_is_priced_higher():
    # the same runs and limits over N = 40: 400 linear rows; 1600 + 480 + 352 + 1400 + 3840 = 7672 us a solve
    assert mpc_solve_size(40, 2, 2, LIMITS.program_rows(40), 1) == pytest.approx(7672 / 5000, rel=1e-12)
    assert LIMITS.program_rows(40) == 400


@pytest.mark.parametrize(("budget", "code"), [(0.999, 2), (1.001, 0)])
def test_simulate_refuses_the_loop_above_the_price_and_runs_it_below(tmp_path, capsys, monkeypatch, budget, code):
    # a scalar plant, N = 3, |u| <= 0.3: 6 linear rows; 1600 + 0.75 * 3 * 4 + 0.055 * 9 + 3.5 * 6 = 1630.495 us;
    # --law all under zero: 3 programs (expected-cost per protocol, certainty-equivalent once), 2 clipped laws
    system = System(A=[[0.9]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.8], x0=[1.0])
    path = tmp_path / "scalar.toml"
    save_system(system, path, constraints=Constraints(u_min=[-0.3], u_max=[0.3]))
    price = 5 * 2 * (3 * 1630.495 / 5000 + 2 * 2e-3)
    monkeypatch.setenv(VARIABLE, repr(budget * price))
    argv = ["simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "5", "--steps", "2"]
    assert main(argv) == code
    captured = capsys.readouterr()
    if code:
        assert "error: --mpc-samples: 5 runs of 2 steps x 3 programs (the constrained loop; 0.33 of a 5 ms solve " \
               "each: N = 3, n = 1, m = 1, 6 linear rows, 0 chance rows)" in captured.err
    else:
        assert "constrained_loop" in captured.out
