"""Cost difference, Lemma 2, Lemma 3, Theorem 4 and the properties that hold (Theorems 2, 3)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import packetloss_cvx as pl
from packetloss_cvx.lq import analysis as an
from packetloss_cvx.lq import difference
from packetloss_cvx.lq.prediction import prediction
from packetloss_cvx.model.random_systems import random_system

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)  # the same inputs on every run
seeds = st.integers(0, 2**32 - 1)


@given(seed=seeds)
@SETTINGS
def test_cost_difference_equals_difference_of_optima(seed):
    s = random_system(np.random.default_rng(seed))
    direct = pl.closed_form(s, "udp").cost - pl.closed_form(s, "tcp").cost
    assert np.isclose(difference.cost_difference(s), direct, rtol=1e-8, atol=1e-10 * pl.closed_form(s, "tcp").cost)


@given(seed=seeds)
@SETTINGS
def test_theorem_2_weak_inequality_holds(seed):
    """J*_udp >= J*_tcp for every system (J_udp(U) - J_tcp(U) is a PSD form)."""
    s = random_system(np.random.default_rng(seed))
    assert difference.cost_difference(s) >= 0.0


@given(seed=seeds, step=st.floats(0.05, 0.95))
@SETTINGS
def test_theorem_3_monotone_in_mu(seed, step):
    rng = np.random.default_rng(seed)
    s = random_system(rng, edge_mu=False)
    mu1 = s.mu_schedule
    mu2 = mu1 + (1 - mu1) * step
    for protocol in ("tcp", "udp"):
        assert pl.closed_form(s.with_mu(mu2), protocol).cost <= pl.closed_form(s.with_mu(mu1), protocol).cost


@given(seed=seeds, nu=st.floats(0.05, 0.95))
@SETTINGS
def test_lemma_2_matches_finite_differences(seed, nu):
    s = difference.scalar_channel(random_system(np.random.default_rng(seed)), 0.5)
    pred = prediction(s)
    exact = difference.cost_difference_derivative(s, nu, pred)
    fd = difference.cost_difference_fd(s, nu, pred=pred)
    scale = max(abs(fd), 1e-7 * max(1.0, difference.cost_difference(s, nu, pred)))
    assert abs(exact - fd) <= 1e-5 * scale


@given(seed=seeds)
@SETTINGS
def test_lemma_3_proof_matrix_gives_the_exact_roots(seed):
    s = difference.scalar_channel(random_system(np.random.default_rng(seed)), 0.5)
    pred = prediction(s)
    roots = difference.det_roots(s, pred)
    cands = difference.lemma3_candidates(s, "proof", pred)
    finite = roots[np.isfinite(roots) & (np.abs(roots) < 1e6)]
    for r in finite:
        assert np.min(np.abs(cands - r)) <= 1e-6 * (1 + abs(r))
    # and at a real root in (0, 1) the matrix f(nu) is singular
    real = finite[(np.abs(finite.imag) < 1e-10) & (finite.real > 0.01) & (finite.real < 0.99)].real
    for r in real[:3]:
        GF, GG = difference.G_maps(pred, r)
        scale = np.linalg.norm(GG, 2) * pred.Omega_d.max() * np.linalg.norm(GF, 2)
        sv = np.linalg.svd(difference.lemma2_matrix(pred, r), compute_uv=False)
        assert sv[-1] <= 1e-6 * scale


def test_lemma_3_as_printed_misses_the_roots():
    """Pinned: n = m = 1, N = 2 (the audit's shrunk case): the lemma's matrix gives other points."""
    s = pl.System(A=[[0.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.7], x0=[-2.0])
    roots = difference.det_roots(s)
    printed = difference.lemma3_candidates(s, "lemma")
    proof = difference.lemma3_candidates(s, "proof")
    finite = roots[np.isfinite(roots)]
    assert max(np.min(np.abs(proof - r)) for r in finite) < 1e-9
    assert max(np.min(np.abs(printed - r)) for r in finite) > 1e-2


def test_theorem_4_is_exact_for_one_decision_variable():
    """N = m = 1: J_Delta = nu (1 - nu) / (2 (nu + 1)) for A = B = x0 = 1, peak at sqrt(2) - 1 by hand;
    with a 1×1 f, det f = 0 is the stationarity condition, so the candidate is right."""
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    assert np.isclose(difference.maximise_cost_difference(s).point[0], np.sqrt(2) - 1, atol=1e-8)
    assert np.isclose(difference.theorem4_maximiser(s, "proof").point[0], np.sqrt(2) - 1, atol=1e-12)


def test_theorem_4_misses_the_maximiser_at_n1_N2():
    """Pinned, the audit's shrunk case: A = 0.5, B = 1, N = 2, x0 = -2."""
    s = pl.System(A=[[0.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.7], x0=[-2.0])
    best = difference.maximise_cost_difference(s)
    claimed = difference.theorem4_maximiser(s, "proof")
    assert best.value > 0
    assert claimed is None or claimed.value < 0.99 * best.value


def test_maximiser_depends_on_x0_but_candidates_do_not(pendulum):
    a = difference.scalar_channel(pendulum.with_x0([1, 0, 0, 0]), 0.5)
    b = difference.scalar_channel(pendulum.with_x0([1, 1, 1, 1]), 0.5)
    assert abs(difference.maximise_cost_difference(a).point[0] - difference.maximise_cost_difference(b).point[0]) > 0.1
    assert np.allclose(np.sort_complex(difference.lemma3_candidates(a, "proof")),
                       np.sort_complex(difference.lemma3_candidates(b, "proof")))


def test_maximiser_is_a_stationary_point(two_actuator):
    s = difference.scalar_channel(two_actuator, 0.5)
    best = difference.maximise_cost_difference(s)
    nu = float(best.point[0])
    assert 0 < nu < 1
    scale = abs(difference.cost_difference_derivative(s, 0.5))
    assert abs(difference.cost_difference_derivative(s, nu)) < 1e-5 * scale
    for other in np.linspace(0.001, 0.999, 50):
        assert difference.cost_difference(s, other) <= best.value * (1 + 1e-12)


def test_two_channel_maximiser(two_actuator):
    best = difference.maximise_cost_difference_2d(two_actuator, grid=21)
    assert np.all((best.point >= 0) & (best.point <= 1))
    assert best.value >= difference.cost_difference(two_actuator, [0.9, 0.5])
    with pytest.raises(pl.InputError, match="m = 2"):
        difference.maximise_cost_difference_2d(pl.load_example("pendulum"))


def test_monotonicity_scan(two_actuator):
    for protocol in ("tcp", "udp"):
        assert an.monotonicity_violations(two_actuator, protocol) == []


def test_eigenvalue_table_by_hand():
    """n = m = N = 1, A = -0.5, B = 1, Omega = Psi = 1, mu = 0.4. By hand: Omega_g = 1, Omega_gp = -0.5,
    G_tcp = 0.4 + 1 = 1.4, G_udp = G_tcp + 1 (1 - 0.4) = 2, K = G^-1 Omega_gp (the first move is -K x)."""
    s = pl.System(A=[[-0.5]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.4], x0=[1.0])
    table = an.eigenvalue_table(s)
    hand = {"tcp": {"A-BK": -0.5 + 0.5 / 1.4, "A-BMK": -0.5 + 0.4 * 0.5 / 1.4},   # -1/7, -5/14
            "udp": {"A-BK": -0.5 + 0.5 / 2.0, "A-BMK": -0.5 + 0.4 * 0.5 / 2.0}}   # -1/4, -2/5
    for protocol, loops in hand.items():
        for loop, eig in loops.items():
            assert np.allclose(table[protocol][loop], [eig], rtol=1e-12, atol=0)


def _simulated_loop(qp, system, delivered, x0, steps):
    """x_{t+1} = A x_t + B D u_t, u_t the first move of the plan Clarabel finds from x_t (the sparse QP:
    no Phi, Gamma or closed form involved); D = I for A - BK, D = M for the mean loop A - BMK."""
    xs = [np.asarray(x0, dtype=float)]
    for _ in range(steps):
        u = qp.solve(x0=xs[-1], with_gain=False, cross_check=False).inputs[0]
        xs.append(system.A @ xs[-1] + system.B @ delivered @ u)
    return xs


def _misfit(runs, eigenvalues):
    """Largest relative residual of x_{t+2} - (l1 + l2) x_{t+1} + l1 l2 x_t = 0 along the runs."""
    c = np.poly(np.asarray(eigenvalues))   # [1, -(l1 + l2), l1 l2]
    assert np.allclose(c.imag, 0.0, atol=1e-12)
    c = c.real
    return max(np.linalg.norm(xs[t + 2] + c[1] * xs[t + 1] + c[2] * xs[t]) / np.linalg.norm(xs[t])
               for xs in runs for t in range(len(xs) - 2))


def test_eigenvalue_table_against_a_simulated_closed_loop(two_actuator):
    """Each loop run step by step with a fresh QP solve per step: the trajectories from e1 and e2 must
    obey x_{t+2} = (l1 + l2) x_{t+1} - l1 l2 x_t, the recurrence of the table's eigenvalue pair, which
    two independent starts pin down; the other loop's pair must not fit (the check can tell them apart)."""
    s = two_actuator.with_mu([0.9, 0.5])
    table = an.eigenvalue_table(two_actuator, [0.9, 0.5])
    delivered = {"A-BK": np.eye(2), "A-BMK": np.diag([0.9, 0.5])}
    for protocol in ("tcp", "udp"):
        qp = pl.ExpectedCostQP(s, protocol, "sparse")
        for loop, other in (("A-BK", "A-BMK"), ("A-BMK", "A-BK")):
            runs = [_simulated_loop(qp, s, delivered[loop], x0, 3) for x0 in ([1.0, 0.0], [0.0, 1.0])]
            assert _misfit(runs, table[protocol][loop]) < 1e-8
            assert _misfit(runs, table[protocol][other]) > 1e-2


def test_gain_conventions_first_block_is_the_solvers_law(two_actuator):
    """The paper's law (first block of G^-1 Omega_gp, dense) against the first move the sparse QP finds
    from each unit state (U* is linear in x), and the shifted law against the last move."""
    for protocol in ("tcp", "udp"):
        gains = an.gain_conventions(two_actuator, protocol)
        qp = pl.ExpectedCostQP(two_actuator, protocol, "sparse")
        plans = [qp.solve(x0=x, with_gain=False, cross_check=False).inputs for x in np.eye(2)]
        assert np.allclose(gains["first block of G^-1 Omega_gp"], -np.column_stack([U[0] for U in plans]),
                           rtol=0, atol=1e-8)
        assert np.allclose(gains["last block of G^-1 Omega_gp"], -np.column_stack([U[-1] for U in plans]),
                           rtol=0, atol=1e-8)
        assert set(gains) == {"first block of G^-1 Omega_gp", "first block of G Omega_gp (literal)",
                              "nominal (Omega_g + Psi)^-1 Omega_gp", "last block of G^-1 Omega_gp"}


def test_closed_loop_eigenvalues_names_its_loops(two_actuator):
    K = np.zeros((2, 2))
    eigs = an.closed_loop_eigenvalues(two_actuator, K, ("A-BMK",))
    assert list(eigs) == ["A-BMK"]
    # K = 0 leaves A: (tr -+ sqrt(tr^2 - 4 det)) / 2 with tr = 2.04, det = 1.03 * 1.01 - 0.005 * 0.35 = 1.03855
    assert np.allclose(np.sort(eigs["A-BMK"].real), [(2.04 - np.sqrt(0.0074)) / 2, (2.04 + np.sqrt(0.0074)) / 2],
                       rtol=1e-12)
    with pytest.raises(pl.InputError, match="loops"):
        an.closed_loop_eigenvalues(two_actuator, K, ("A+BK",))
