"""Never silently wrong: every default path returns the right number or raises a typed error.

Each case is one where a wrong number could be returned without an error.
References are independent of the path under test: the exact O(N) recursion where it passes
its own check, the Clarabel QP twin, a hand value, or the forward pass of the mean state.
"""

from fractions import Fraction

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.lq.recursion import plan_cost, recursion_cost
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.tolerances import PLAN_COST_RTOL

from ..references import exact_plan_cost


def _readme(N: int) -> pl.System:
    return pl.System(A=[[1.1, 0.2], [0, 0.9]], B=[[1], [0.5]], state_weight=[1, 1], input_weight=[0.5],
                     mu=[0.8], x0=[1, 0], horizon=N)


def _unstable(rho: float, N: int) -> pl.System:
    return random_system(np.random.default_rng(0), n=2, m=2, horizon=N, spectral_radius=rho, full_weights=False,
                         time_varying=False, non_stationary=False, noise=False, edge_mu=False)


def _pendulum(N: int, mu: float = 1.0) -> pl.System:
    data = pl.load_example("pendulum").with_mu([mu]).to_dict()
    data["cost"]["horizon"] = N
    return system_from_dict(data)


def _weighted(w: float) -> pl.System:
    data = pl.load_example("two_actuator").to_dict()
    data["cost"]["state_weight"] = [w, 1.0]
    return system_from_dict(data)


def test_default_method_is_auto_everywhere():
    import inspect

    for fn, name in ((pl.closed_form, "method"), (pl.expected_cost, "method"), (pl.solve_qp, "formulation")):
        assert inspect.signature(fn).parameters[name].default == "auto"


def test_readme_system_at_long_horizon_matches_the_qp():
    """Was 128.0 from the dense default; the QP twin and the recursion give 1.3044."""
    s = _readme(200)
    sol = pl.closed_form(s, "tcp")
    qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
    assert abs(sol.cost - qp.cost) <= 1e-7 * qp.cost
    assert 1.30 < sol.cost < 1.31


@pytest.mark.parametrize(("rho", "N"), [(3.0, 20), (1.5, 200)])
def test_dense_refuses_unstable_plants_up_front(rho, N):
    """Was -4096 (true 9.5587 class) and -6.1e56: refused before anything dense is built."""
    s = _unstable(rho, N)
    with pytest.raises(pl.NumericalError, match="condition estimate"):
        pl.closed_form(s, "tcp", method="dense")
    with pytest.raises(pl.NumericalError, match="use method='recursion'"):
        pl.expected_cost(s, np.zeros((N, 2)), "tcp", method="dense")
    sol = pl.closed_form(s, "tcp")               # auto: the right number
    qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
    assert abs(sol.cost - qp.cost) <= 1e-7 * max(1.0, qp.cost)


@pytest.mark.parametrize("N", [200, 300, 2000])
def test_pendulum_at_mu_one_long_horizons(N):
    """Dense was off by 3e-6 (N=200), 220% (N=300) and 5.9e90 (N=2000); auto is right. The forward pass of the plan
    alone (open loop) referees up to N = 300; at N = 2000 it does not: rho(A) = 1.06 amplifies the plan's rounding
    (the exact open-loop cost of the plan in floats, summed to 300 digits: 3.1e76 rolled out step by step, whose
    rounding a float forward pass repeats to give 25175; 2.9e78 by powers and a scan, 3.1e78 in floats), so there
    the referee is scipy's DARE: the pass has settled by step 1."""
    s = _pendulum(N)
    with pytest.raises(pl.NumericalError):
        pl.closed_form(s, "tcp", method="dense")
    sol = pl.closed_form(s, "tcp")
    assert sol.method == "recursion"
    assert max(abs(sol.closed_loop_eigenvalues)) < 1.0        # the mean closed loop is stable
    if N == 2000:                   # P_1 is the DARE solution; step 0 adds no state weight
        from scipy.linalg import solve_discrete_are

        R = np.diag(s.input_weights[0])
        P1 = solve_discrete_are(s.A, s.B, s.state_weights[0], R)
        BPA = s.B.T @ P1 @ s.A
        K0 = np.linalg.solve(s.B.T @ P1 @ s.B + R, BPA)
        P0 = s.A.T @ P1 @ s.A - BPA.T @ K0
        assert sol.cost == pytest.approx(float(s.x0 @ (s.initial_weight + P0) @ s.x0), rel=1e-9)
        np.testing.assert_allclose(sol.inputs[0], -K0 @ s.x0, rtol=1e-9)
        np.testing.assert_allclose(sol.gain, K0, rtol=1e-9)
    else:   # plumbing: the reported cost is the forward pass of the reported plan (closed_form's own referee, so
            # this cannot disagree unless the wrong plan or cost is returned); independent: the sparse QP
        assert np.isclose(recursion_cost(s, sol.inputs, "tcp"), sol.cost, rtol=1e-9)
        qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
        assert abs(qp.cost - sol.cost) <= 1e-7 * sol.cost


def test_expected_cost_of_the_optimal_plan_on_an_unstable_plant():
    """expected_cost(..., method='dense') returned 0.0 where the cost is about 21.6."""
    s = _unstable(3.0, 20)
    sol = pl.closed_form(s, "tcp")
    qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
    value = pl.expected_cost(s, sol.inputs, "tcp")
    assert abs(value - qp.cost) <= 1e-7 * qp.cost


def _pendulum_over(N: int) -> pl.System:
    data = pl.load_example("pendulum").to_dict()
    data["cost"]["horizon"] = N
    return system_from_dict(data)


def test_expected_cost_of_the_pendulums_plan_over_2000_steps_raises():
    """The closed form's plan steers the unstable pendulum (rho(A) = 1.061) to zero, so its states rolled out open
    loop carry its rounding amplified 1.061^t: a forward pass gives 1.48e80 where the optimum is 25445. The exact
    open-loop cost of that float plan (fractions, 7 minutes) is 1.4687e80; the forward pass is off by 1.1e78, which
    the bound says (1.1097728365937e78 against the true 1.1097728365867e78). expected_cost raises NumericalError
    saying why and what to use; the closed form's own cost is unaffected."""
    s = _pendulum_over(2000)
    sol = pl.closed_form(s, "tcp")
    assert sol.method == "recursion"
    for method in ("auto", "recursion"):
        with pytest.raises(pl.NumericalError, match=r"not resolved(.|\n)*open-loop growth of A(.|\n)*closed_form"):
            pl.expected_cost(s, sol.inputs, "tcp", method=method)
    with pytest.raises(pl.NumericalError, match="condition estimate"):
        pl.expected_cost(s, sol.inputs, "tcp", method="dense")
    with pytest.raises(pl.NumericalError, match="not resolved"):
        recursion_cost(s, sol.inputs, "tcp")
    value, bound = plan_cost(s, sol.inputs, "tcp")
    assert bound > 1e-3 * value                      # the true error: 0.75 % (the docstring's measurement)


def test_a_refused_plan_cost_was_in_fact_inaccurate():
    """The pendulum over 500 steps: its forward pass is off by 7.7e-7 (relative, against the exact rational cost of
    the float plan), and it is refused; the bound is within 1e-5 of the true error."""
    s = _pendulum_over(500)
    U = pl.closed_form(s, "tcp").inputs
    exact = exact_plan_cost(s, U, np.broadcast_to(s.input_weights, U.shape))
    value, bound = plan_cost(s, U, "tcp")
    error = abs(Fraction(value) - exact)
    assert error > Fraction(PLAN_COST_RTOL) * exact
    assert error <= Fraction(bound) <= error * Fraction(1 + 1e-5)
    with pytest.raises(pl.NumericalError, match="not resolved"):
        pl.expected_cost(s, U, "tcp")


def _held(N: int, psi: float) -> tuple[pl.System, np.ndarray]:
    """x_t = 0.1 held by u_t = -0.2 on a = 3 (0.2 is 2 x 0.1 in binary too, so 3 x 0.1 - 0.2 is 0.1 exactly): the
    exact states never move; the rolled-out ones drift from the first step's rounding, times 3^t."""
    s = pl.System(A=[[3.0]], B=[[1.0]], horizon=N, state_weight=[1.0], input_weight=[psi], mu=[1.0], x0=[0.1])
    return s, np.full((N, 1), -0.2)


@pytest.mark.parametrize(("psi", "resolved"), [(40.0, True), (4.0, False)])
def test_plan_cost_tolerance_is_pinned_on_both_sides(psi, resolved):
    """The held plan over 20 steps: rounding moves its rolled-out cost by 9.68e-9 (against fractions). With psi = 40
    the cost is 32.2: 3.0e-10 relative, inside PLAN_COST_RTOL = 1e-9 (returned) and outside a band 10x tighter; with
    psi = 4 it is 3.4: 2.8e-9, outside (refused) and inside a band 10x wider. Either verdict is the true error's
    (the bound is within 1e-5 of it)."""
    s, U = _held(20, psi)
    exact = exact_plan_cost(s, U, np.full(U.shape, psi))
    value, bound = plan_cost(s, U, "tcp")
    error = abs(Fraction(value) - exact)
    assert error <= Fraction(bound) <= error * Fraction(1.001)
    assert Fraction(PLAN_COST_RTOL / 10) * exact < error < Fraction(PLAN_COST_RTOL * 10) * exact
    if resolved:
        assert error <= Fraction(PLAN_COST_RTOL) * exact
        assert pl.expected_cost(s, U, "tcp") == value
        assert recursion_cost(s, U, "tcp") == value
    else:
        assert error > Fraction(PLAN_COST_RTOL) * exact
        for evaluate in (pl.expected_cost, recursion_cost):
            with pytest.raises(pl.NumericalError, match="not resolved"):
                evaluate(s, U, "tcp")


def test_markov_exact_cost_of_a_plan_is_refused_where_its_mean_states_are_not_resolved():
    """The Gilbert-Elliott pendulum over 2000 steps under the plug-in law's plan: the TCP-like cost (the mean states
    alone) is refused as the Bernoulli one is. The UDP-like cost is returned: the lost inputs' variance, amplified
    by A^t, makes it about 1e106, beside which the mean states' rounding (1e78) is nothing. With a chain that never
    loses (p = 0, mu = 1) the UDP-like cost is the mean states' alone, and it is refused."""
    from packetloss_cvx.lq.markov_cost import exact_cost

    data = pl.load_example("pendulum_bursty").to_dict()
    data["cost"]["horizon"] = 2000
    bursty = system_from_dict(data)
    data["channel"]["p"] = [0.0]
    perfect = system_from_dict(data)
    U = pl.closed_form(bursty.with_mu(bursty.mu_schedule), "tcp").inputs
    with pytest.raises(pl.NumericalError, match="not resolved"):
        exact_cost(bursty, U, "tcp")
    assert exact_cost(bursty, U, "udp") > 1e100
    U = pl.closed_form(perfect.with_mu(perfect.mu_schedule), "tcp").inputs
    with pytest.raises(pl.NumericalError, match="udp-like expected cost of this plan is not resolved"):
        exact_cost(perfect, U, "udp")


def test_expected_cost_beyond_the_double_range_raises():
    s = pl.load_example("two_actuator")
    with pytest.raises(pl.NumericalError, match="double-precision range"):
        pl.expected_cost(s, np.full((10, 2), 1e200), "tcp")


@pytest.mark.parametrize("w", [1e9, 1e10, 1e12, 1e14, 1e16, 1e100])
def test_badly_scaled_weights_are_refused_naming_the_weights(w):
    """1e12 gave rel dJ 1.1e-3 at exit 0; 1e16 gave dense 32 / recursion 1.75; 1e100 a negative cost.
    The true cost is about 3.0522 (it only grows with the weight and is 3.052228 at 1e10). At 1e9 the recursion's
    cost is 5.2e-8 off its plan's forward cost (5.4e-7 at 1e10), 50 times SELF_CHECK_RTOL: a self-check made 100 times
    looser returned it."""
    s = _weighted(w)
    for method in ("auto", "dense", "recursion"):
        with pytest.raises(pl.NumericalError, match="weights"):
            pl.closed_form(s, "tcp", method=method)


def test_moderate_weights_are_still_solved_and_agree_with_the_qp():
    s = _weighted(1e6)
    sol = pl.closed_form(s, "tcp")
    qp = pl.solve_qp(s, "tcp", with_gain=False, cross_check=False)
    assert abs(sol.cost - qp.cost) <= 1e-7 * sol.cost


def test_dense_memory_is_refused_up_front():
    s = _readme(1)
    data = s.to_dict()
    data["cost"]["horizon"] = 60000
    big = system_from_dict(data)
    with pytest.raises(pl.ResourceError, match="GiB"):
        pl.closed_form(big, "tcp", method="dense")


# ---------------------------------------------------------------- the QP twin and the command line

def _run(capsys, *argv):
    from packetloss_cvx.cli import main

    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(("rho", "N"), [(1.5, 60), (3.0, 20), (1.01, 2000), (10.0, 200)])
def test_udp_qp_on_unstable_plants_raises_numerical_error_never_infeasible(rho, N):
    """Statuses 'infeasible' / 'optimal_inaccurate' / a cvxpy ValueError on an unconstrained QP."""
    s = _unstable(rho, N)
    with pytest.raises(pl.NumericalError, match="unconstrained|double-precision"):
        pl.solve_qp(s, "udp", "sparse" if rho == 10.0 else "auto", with_gain=False, cross_check=False)


def test_qp_whose_objective_disagrees_with_its_own_plan_raises():
    """At state_weight 1e14 the QP reported 1.19 while the cost cannot be below 3.0522."""
    with pytest.raises(pl.NumericalError, match="forward cost of its\\s+own plan"):
        pl.solve_qp(_weighted(1e14), "tcp", with_gain=False, cross_check=False)


def test_cross_check_compares_the_printed_number_and_binds(capsys, monkeypatch):
    """solve --method dense compared the QP with the auto answer; now with the printed one, and a
    disagreement is exit 1 with one line naming both numbers."""
    import packetloss_cvx.cli.solve as cli

    real = cli.closed_form

    def off_by_1e3(system, protocol, method="auto"):
        sol = real(system, protocol, method)
        if method == "dense":
            import dataclasses

            return dataclasses.replace(sol, cost=sol.cost * (1 + 1e-3))
        return sol

    monkeypatch.setattr(cli, "closed_form", off_by_1e3)
    code, out, err = _run(capsys, "solve", "two_actuator", "--method", "dense", "--protocol", "tcp")
    assert code == 1
    assert "J_qp = 2.79847" in err
    assert "J* = 2.80126" in err
    assert "(dense)" in err
    assert err.count("\n") == 1
    assert not out
    code, out, _ = _run(capsys, "solve", "two_actuator", "--method", "recursion", "--protocol", "tcp")
    assert code == 0
    assert "(recursion)" in out


def test_api_cross_check_binds():
    import dataclasses

    s = pl.load_example("two_actuator")
    wrong = dataclasses.replace(pl.closed_form(s, "tcp"), cost=3.0)
    with pytest.raises(pl.CrossCheckError, match="J\\* = 3") as info:
        pl.solve_qp(s, "tcp", with_gain=False, reference=wrong)
    assert info.value.values["qp"] == pytest.approx(2.79847, rel=1e-5)


def test_cli_refuses_a_solve_whose_qp_cannot_fit_and_names_no_qp(capsys, tmp_path, monkeypatch):
    """N = 50000 with n = 2, m = 1: solve with the QP cross-check needs about 0.27 GiB (solve_bytes, by hand
    50000 x (260 + 60 + 40 + 3000 + 1400 + 1000) = 2.88e8 bytes), refused upfront against a 1e8-byte budget (exit 2,
    one line naming --no-qp); the closed form alone needs 1.8e7 and is answered."""
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e8")
    path = tmp_path / "long.toml"
    pl.save_system(_readme(1), path)
    path.write_text(path.read_text().replace("horizon = 1", "horizon = 50000"))
    code, out, err = _run(capsys, "solve", str(path), "--protocol", "tcp", "--json")
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert err.startswith("packetloss-cvx: error: cost.horizon: N = 50000 (n = 2, m = 1) with the QP cross-check")
    assert "--no-qp skips the cross-check" in err
    assert err.rstrip().endswith("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES=2.88e+08")
    code, out, err = _run(capsys, "solve", str(path), "--protocol", "tcp", "--json", "--no-qp")
    assert code == 0, err
    import json

    assert json.loads(out)["tcp"]["cost"] == pytest.approx(1.3044129215697624, rel=1e-9)   # the N = 200 value


def test_cli_refuses_a_solve_whose_qp_alone_cannot_fit(capsys, tmp_path, monkeypatch):
    """Twenty channels on a scalar plant over 5000 steps: solve's fitted peak with the cross-check fits a 1e8-byte
    budget (by hand 5000 x (260 + 15 + 800 + 3000 + 350 + 10000) = 7.2e7 bytes), the sparse QP's own estimate does
    not (by hand 5000 x (260 + 8000 + 13000) + 1e7 = 1.163e8, plus the closed forms' 5000 x 1075): refused upfront,
    exit 2 and one line naming --no-qp, where the QP was skipped after the closed forms (or, with ExpectedCostQP's
    own check, exit 1 in an audit)."""
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e8")
    s = pl.System(A=[[0.9]], B=np.ones((1, 20)), horizon=5000, state_weight=[1.0], input_weight=np.ones(20),
                  mu=np.full(20, 0.5), x0=[1.0])
    path = pl.save_system(s, tmp_path / "wide.toml")
    code, out, err = _run(capsys, "solve", str(path), "--protocol", "tcp", "--json")
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert err.startswith("packetloss-cvx: error: cost.horizon: N = 5000 (n = 1, m = 20) with the QP cross-check "
                          "(about 0.113 GiB)")
    assert "; --no-qp skips the cross-check, or to run it on purpose set " in err
    assert err.rstrip().endswith("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES=1.22e+08")


def test_cli_unstable_udp_reports_the_skipped_cross_check(capsys, tmp_path):
    path = pl.save_system(_unstable(1.5, 60), tmp_path / "unstable.toml")
    code, out, err = _run(capsys, "solve", str(path))
    assert code == 0, err
    assert "UDP-like" in out
    assert "QP cross-check skipped" in out
    assert "unconstrained" in out
    assert "TCP-like" in out
    assert "QP optimal" in out


def test_cli_badly_scaled_weights_exit_1_naming_the_weights(capsys, tmp_path):
    path = pl.save_system(_weighted(1e12), tmp_path / "w.toml")
    code, out, err = _run(capsys, "solve", str(path))
    assert code == 1
    assert not out
    assert "weights span 1.0e+12" in err
    assert err.count("\n") == 1
    path = pl.save_system(_weighted(1e100), tmp_path / "w100.toml")
    code, out, err = _run(capsys, "solve", str(path), "--no-qp")
    assert code == 1
    assert not out
    assert err.count("\n") == 1


def test_cli_huge_x0_prints_one_line(capsys):
    code, out, err = _run(capsys, "solve", "two_actuator", "--x0=1e200,1")
    assert code == 1
    assert not out
    assert err.count("\n") == 1
    assert "double-precision range" in err


# ---------------------------------------------------------------- found by a hostile review (2026-11-22)

def _pendulum_scaled(weight_scale: float, x0_scale: float, mu: float = 0.9) -> pl.System:
    p = pl.load_example("pendulum")
    return pl.System(A=p.A, B=p.B, horizon=80, state_weight=np.array([5.0, 1, 1, 1]) * weight_scale,
                     input_weight=[2.0 * weight_scale], mu=[mu], x0=[x0_scale, 0, 0, 0])


@pytest.mark.parametrize(("weight_scale", "x0_scale", "mu", "protocol"), [
    (1e-15, 1e-7, 0.9, "tcp"),     # the QP dropped every state weight below 1e-14: 15x too low
    (1.0, 1e-10, 0.3, "udp"),      # the cost check was absolute below J* = 1: 3.5% too low
    (1.0, 1e-6, 0.9, "udp"),       # 2.1e-5 relative, exit 0
    (1e-8, 1.0, 0.9, "tcp"),       # refused: the QP's inputs were inexact at that scale
])
def test_qp_is_right_at_every_scale(weight_scale, x0_scale, mu, protocol):
    """Reference by scaling: J* is homogeneous of degree 1 in the weights and 2 in x0 (no noise)."""
    unit = pl.closed_form(_pendulum_scaled(1.0, 1.0, mu), protocol).cost
    expected = unit * weight_scale * x0_scale**2
    s = _pendulum_scaled(weight_scale, x0_scale, mu)
    qp = pl.solve_qp(s, protocol, with_gain=False)        # the default cross-check binds
    assert abs(qp.cost - expected) <= 1e-7 * expected
    assert abs(pl.closed_form(s, protocol).cost - expected) <= 1e-9 * expected


def test_an_almost_dead_channel_does_not_fail_the_cross_check():
    """mu = 1e-300: that input is (almost) free, so any value is (almost) optimal; compared through Vbar U."""
    s = pl.load_example("two_actuator").with_mu([1e-300, 0.5])
    for protocol in ("tcp", "udp"):
        qp = pl.solve_qp(s, protocol, with_gain=False)
        dead = pl.closed_form(pl.load_example("two_actuator").with_mu([0.0, 0.5]), protocol).cost
        assert abs(qp.cost - dead) <= 1e-9 * dead


def test_cross_check_against_an_exact_zero(two_actuator):
    """No state weight: J* = 0 exactly; the QP's 1e-33 is rounding at the problem's scale."""
    s = pl.System(A=two_actuator.A, B=two_actuator.B, horizon=3, state_weight=[0.0, 0.0], input_weight=[1, 1],
                  mu=[0.5, 0.5], x0=[1.0, -1.0])
    qp = pl.solve_qp(s, "udp", with_gain=False)
    assert qp.cost < 1e-20
    assert pl.closed_form(s, "udp").cost == 0.0


def test_qp_memory_grows_with_n_and_is_refused_in_advance(monkeypatch):
    """The estimate counts the state terms (~250 N n^2 bytes measured): n = 3000 over 5 steps needs ~11 GiB,
    and a 300-state system is refused against a budget it would exceed."""
    from packetloss_cvx.qp.expected_cost import qp_memory_estimate

    def system(n: int) -> pl.System:
        return pl.System(A=np.eye(n) * 0.5, B=np.ones((n, 1)), horizon=5, state_weight=np.ones(n),
                         input_weight=[1.0], mu=[0.5], x0=np.ones(n))

    small = system(300)
    assert qp_memory_estimate(small, "sparse") > 8e7
    assert qp_memory_estimate(system(600), "sparse") - 1e7 > 3.9 * (qp_memory_estimate(small, "sparse") - 1e7)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "5e7")
    with pytest.raises(pl.ResourceError, match="GiB"):
        pl.ExpectedCostQP(small, "tcp", "sparse")
