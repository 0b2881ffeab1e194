"""The structure-cached batched evaluator: a batch answers as the per-point closed form (both methods) and refuses
as it does (a plumbing check where the two share a kernel); against independent references: Theorem 1's dense
minimiser written out here, the QP twin on a sample, and hand values. A point's cost does not depend on the batch it
is in (bit for bit), and the other protocol's evaluator shares the structure and answers as one built fresh."""

import numpy as np
import pytest
from scipy.linalg import block_diag

import packetloss_cvx as pl
import packetloss_cvx.lq.evaluator as evaluator_module
from packetloss_cvx.linalg import block_diagonal
from packetloss_cvx.lq.evaluator import CostEvaluator
from packetloss_cvx.lq.prediction import prediction
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.model.random_systems import random_system

RTOL = 1e-12


def _rel(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_every_batch_point_equals_the_per_point_closed_form(seed, protocol):
    rng = np.random.default_rng(seed)
    s = random_system(rng)
    mus = rng.uniform(0.0, 1.0, (6, s.m))
    mus[0], mus[1] = 0.0, 1.0                                     # the edges: no delivery, perfect
    schedules = rng.uniform(0.0, 1.0, (3, s.horizon, s.m))
    for method in ("auto", "recursion"):
        ev = CostEvaluator(s, protocol, method)
        sol = ev.solve(mus)
        assert sol.costs.shape == (6,)
        assert sol.inputs.shape == (6, s.horizon, s.m)
        assert sol.gains.shape == (6, s.m, s.n)
        for i, mu in enumerate(mus):
            ref = pl.closed_form(s.with_mu(mu), protocol, method)
            assert _rel(sol.costs[i], ref.cost) <= RTOL
            assert np.allclose(sol.inputs[i], ref.inputs, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(ref.inputs).max()))
            assert np.allclose(sol.gains[i], ref.gain, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(ref.gain).max()))
            assert _rel(ev.cost(mu), ref.cost) <= RTOL
        for mu, value in zip(schedules, ev.costs(schedules), strict=True):
            assert _rel(value, pl.closed_form(s.with_mu(mu), protocol, method).cost) <= RTOL


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_dense_and_recursion_batches_agree_on_the_paper_system(two_actuator, protocol):
    grid = np.linspace(0.0, 1.0, 9)
    mus = np.array([(a, b) for a in grid for b in grid])
    dense = CostEvaluator(two_actuator, protocol, "dense").costs(mus)
    rec = CostEvaluator(two_actuator, protocol, "recursion").costs(mus)
    assert np.all(np.abs(dense - rec) <= 1e-12 * rec)
    assert CostEvaluator(two_actuator, protocol).method == "dense"     # N m = 20: auto allows dense


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_auto_takes_the_batched_recursion_for_many_points(protocol):
    s = random_system(np.random.default_rng(4), n=4, m=3, horizon=40, spectral_radius=0.95, noise=False)
    mus = np.random.default_rng(5).uniform(0.0, 1.0, (64, 3))
    auto = CostEvaluator(s, protocol)
    assert auto.method == "dense"                                       # allowed (N m = 120) ...
    assert auto.solve(mus[:2]).method == "dense"                        # ... and taken for few points,
    big = auto.solve(mus)                                               # the batched recursion for many
    assert big.method == "recursion"
    dense = CostEvaluator(s, protocol, "dense").costs(mus)
    assert np.all(np.abs(big.costs - dense) <= 1e-12 * dense)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_sample_against_the_qp_twin(two_actuator, protocol):
    rng = np.random.default_rng(7)
    mus = rng.uniform(0.05, 1.0, (3, 2))
    got = CostEvaluator(two_actuator, protocol).costs(mus)
    for mu, value in zip(mus, got, strict=True):
        qp = pl.solve_qp(two_actuator.with_mu(mu), protocol, with_gain=False, cross_check=False)
        assert abs(qp.cost - value) <= 1e-7 * value


def test_hand_values_of_a_scalar_plant():
    """x1 = x0 + v u, J(u) = E-form of eq:opt-lqg-simplest with N = 1 and Omega_g = Omega_d = 1:
    TCP-like 1 + 2 mu u + (mu^2 + mu) u^2, minimum 1 - mu / (1 + mu); UDP-like adds
    mu (1 - mu) u^2, so the quadratic coefficient is 2 mu and the minimum 1 - mu / 2."""
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    mu = np.array([[0.0], [0.25], [0.5], [1.0]])
    assert np.allclose(CostEvaluator(s, "tcp").costs(mu), 1.0 - mu[:, 0] / (1.0 + mu[:, 0]), rtol=1e-15)
    assert np.allclose(CostEvaluator(s, "udp").costs(mu), 1.0 - mu[:, 0] / 2.0, rtol=1e-15)
    # quadratic in x0: J*(c x0) = c^2 J* without noise or Q
    assert np.allclose(CostEvaluator(s, "udp").costs(mu, x0=[3.0]), 9.0 * (1.0 - mu[:, 0] / 2.0))


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_batch_of_initial_states(protocol):
    rng = np.random.default_rng(3)
    s = random_system(rng, n=3, m=2, horizon=6, noise=True)
    mus = rng.uniform(0.0, 1.0, (4, 2))
    xs = rng.normal(size=(4, 3))
    got = CostEvaluator(s, protocol).solve(mus, x0=xs)
    for i in range(4):
        ref = pl.closed_form(s.with_mu(mus[i]).with_x0(xs[i]), protocol)
        assert _rel(got.costs[i], ref.cost) <= RTOL
        assert np.allclose(got.inputs[i], ref.inputs, rtol=1e-9, atol=1e-12)


def test_chunks_do_not_change_the_answers(two_actuator, monkeypatch):
    """The dense path's chunks agree within ROUNDING_ORDER_RTOL: its stacked products are BLAS calls whose kernel
    (and so the order of each sum) depends on the stack's size (OpenBLAS's Sandybridge kernel: 6.2e-16 relative
    between 11 points at once and 3 a chunk; the others equal to the bit). The recursion's are equal to the bit on
    every kernel: the brute-force allocation pools points into batches and relies on a point's cost not depending
    on its batch (allocation/brute_force.py)."""
    from packetloss_cvx.tolerances import ROUNDING_ORDER_RTOL

    mus = np.random.default_rng(5).uniform(0.0, 1.0, (11, 2))
    whole = CostEvaluator(two_actuator, "udp").costs(mus)
    rec = CostEvaluator(two_actuator, "udp", "recursion").costs(mus)
    monkeypatch.setattr(evaluator_module, "CHUNK_BYTES", 8 * 20 * 20 * 3)          # 3 points a chunk
    chunked = CostEvaluator(two_actuator, "udp").costs(mus)
    assert np.abs(whole - chunked).max() <= ROUNDING_ORDER_RTOL * np.abs(whole).max()
    monkeypatch.setattr(evaluator_module, "CHUNK_BYTES", 1600)                       # recursion: 2 a chunk
    assert np.array_equal(rec, CostEvaluator(two_actuator, "udp", "recursion").costs(mus))
    assert CostEvaluator(two_actuator, "udp").costs(np.zeros((0, 2))).shape == (0,)


def _weighted(w: float) -> pl.System:
    data = pl.load_example("two_actuator").to_dict()
    data["cost"]["state_weight"] = [w, 1.0]
    return system_from_dict(data)


@pytest.mark.parametrize("w", [1e12, 1e16, 1e100])
def test_weight_spreads_the_recursion_refuses_are_refused_alike(w):
    s = _weighted(w)
    with pytest.raises(pl.NumericalError, match="weights"):
        pl.closed_form(s, "tcp", "recursion")
    for method in ("auto", "recursion"):
        with pytest.raises(pl.NumericalError, match="weights"):
            CostEvaluator(s, "tcp", method).costs([[0.9, 0.5], [0.3, 0.2]])


def test_beyond_the_double_range_raises():
    s = random_system(np.random.default_rng(1), n=2, m=1, horizon=400, spectral_radius=10.0)
    with pytest.raises(pl.NumericalError):
        pl.closed_form(s, "udp")
    with pytest.raises(pl.NumericalError, match="double-precision|overflowed"):
        CostEvaluator(s, "udp").costs([[0.5]])


@pytest.mark.parametrize(("mus", "error", "match"), [
    ([[0.5, 1.2]], pl.ProbabilityError, "mu: expected probabilities"),
    ([[0.5, -0.1]], pl.ProbabilityError, "mu: expected probabilities"),
    ([[0.5, 0.5, 0.5]], pl.DimensionError, r"mu: expected shape \(points, 2\)"),
    ([0.5, 0.5], pl.DimensionError, "mu: expected shape"),
    ([[0.5, np.nan]], pl.InputError, "mu"),
])
def test_bad_channels_are_refused_naming_mu(two_actuator, mus, error, match):
    with pytest.raises(error, match=match):
        CostEvaluator(two_actuator, "udp").costs(mus)


@pytest.mark.parametrize(("mu", "error", "match"), [
    ([0.5, 1.2], pl.ProbabilityError, "mu: expected probabilities"),
    ([-1e-300, 0.5], pl.ProbabilityError, "mu: expected probabilities"),
    ([np.nan, 0.5], pl.InputError, "mu"),
    ([0.5, np.nan], pl.InputError, "mu"),
    ([[0.5, np.nan]] * 10, pl.InputError, "mu"),
])
@pytest.mark.parametrize("checked", [True, False])
def test_one_point_refuses_bad_channels_as_the_batch_does(two_actuator, mu, error, match, checked):
    """The one-point path's own range test (a channel vector's entries compared one by one) lets no NaN or
    out-of-range entry through: each is refused by the batch's validation, checked or not."""
    with pytest.raises(error, match=match):
        CostEvaluator(two_actuator, "udp").cost(np.array(mu), checked=checked)


def test_bad_arguments(two_actuator):
    with pytest.raises(pl.InputError, match="protocol"):
        CostEvaluator(two_actuator, "ftp")
    with pytest.raises(pl.InputError, match="method"):
        CostEvaluator(two_actuator, "tcp", "fast")
    with pytest.raises(pl.DimensionError, match="x0"):
        CostEvaluator(two_actuator, "tcp").costs([[0.5, 0.5]], x0=[[1.0, 2.0]] * 2)


def test_batch_solution_is_frozen(two_actuator):
    sol = CostEvaluator(two_actuator, "tcp").solve([[0.5, 0.5]])
    with pytest.raises(ValueError, match="read-only"):
        sol.costs[0] = 0.0
    assert set(sol.to_dict()) == {"protocol", "costs", "inputs", "gains", "method"}


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("checked", [True, False])
def test_cost_along_a_coordinate_line_equals_the_closed_form(seed, protocol, checked):
    """The Schur complement along an edge (the other channels factored once) against closed_form; unchecked
    (``checked=False``, the allocation's probes: no residual, no self-check, no fall-back) as well as checked, and
    the one-point cost likewise (a factor dropped on the unchecked path gave 105.31 for 25.82, every test passing)."""
    rng = np.random.default_rng(seed)
    s = random_system(rng, m=int(rng.integers(1, 4)), non_stationary=False)
    ev = CostEvaluator(s, protocol)
    mu = rng.uniform(0.0, 1.0, s.m)
    for i in range(s.m):
        line = ev.line(mu, i, checked)
        for value in (0.0, 0.37, 1.0):
            point = mu.copy()
            point[i] = value
            reference = pl.closed_form(s.with_mu(point), protocol).cost
            assert _rel(line(value), reference) <= RTOL
            assert _rel(ev.cost(point, checked=checked), reference) <= RTOL


def test_line_refuses_a_bad_channel_index(two_actuator):
    with pytest.raises(pl.InputError, match="i: expected a channel index"):
        CostEvaluator(two_actuator, "udp").line([0.5, 0.5], 2)


@pytest.mark.parametrize(("mu", "error"), [
    ([0.5, 1.2], pl.ProbabilityError), ([-1e-300, 0.5], pl.ProbabilityError), ([np.nan, 0.5], pl.InputError),
    ([0.5, np.nan], pl.InputError), ([0.5, 0.5, 0.5], pl.DimensionError),
])
def test_line_refuses_a_bad_channel_vector(two_actuator, mu, error):
    """A channel vector taken as it is (a search's line) only when it is one: the rest is refused naming mu."""
    with pytest.raises(error, match="mu"):
        CostEvaluator(two_actuator, "udp").line(np.array(mu), 0)


@pytest.mark.parametrize("mask", [[False, True], [True, True]])
@pytest.mark.parametrize("checked", [True, False])
def test_masked_channels_are_refused_on_the_one_point_paths(two_actuator, mask, checked):
    """A masked array is an ndarray whose masked entries have no value: cost and line refuse it naming mu, as the
    batch's validation does (the one-point paths take only a plain float ndarray as it is)."""
    mu = np.ma.array([0.5, 0.7], mask=mask)
    evaluator = CostEvaluator(two_actuator, "udp")
    with pytest.raises(pl.InputError, match="mu: expected plain numbers, found a masked array"):
        evaluator.cost(mu, checked=checked)
    with pytest.raises(pl.InputError, match="mu: expected plain numbers, found a masked array"):
        evaluator.line(mu, 0, checked=checked)


def _dense_written_here(s, protocol, mu):
    """Theorem 1's dense minimiser from the prediction matrices, written out here (not costs.hessian_factor):
    U* = -G^{-1} Omega_gp x, J* = C + (Omega_gp x)' Vbar U*."""
    pred = prediction(s)
    v = np.tile(mu, s.horizon) if np.ndim(mu) == 1 else np.ravel(mu)
    G = pred.Omega_g @ np.diag(v) + np.diag(pred.Psi)
    if protocol == "udp":
        G = G + np.diag(np.diag(pred.Omega_g) * (1 - v))
    g = pred.Omega_gp @ s.x0
    u = -np.linalg.solve(G, g)
    C = s.x0 @ (s.initial_weight + pred.Omega_p) @ s.x0 + pred.noise_term
    return C + g @ (v * u), u.reshape(s.horizon, s.m)


@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_batched_recursion_against_the_dense_formula_written_here(seed, protocol):
    """The batched kernel (method 'recursion') against an independent algebra, not another copy of itself."""
    rng = np.random.default_rng(100 + seed)
    s = random_system(rng, spectral_radius=float(rng.uniform(0.5, 1.1)))
    mus = rng.uniform(0.0, 1.0, (5, s.m))
    mus[0, 0], mus[1] = 0.0, 1.0
    sol = CostEvaluator(s, protocol, "recursion").solve(mus)
    for k, mu in enumerate(mus):
        cost, U = _dense_written_here(s, protocol, mu)
        assert _rel(sol.costs[k], cost) <= 1e-9
        on = np.broadcast_to(mu > 0, U.shape)
        assert np.abs(sol.inputs[k] - U)[on].max(initial=0.0) <= 1e-9 * max(1.0, np.abs(U).max())


# ---------------------------------------------------------------- the checks' bands, pinned on both sides

def _referee_off(monkeypatch, relative: float = 0.0, absolute: float = 0.0) -> None:
    """The evaluator's self-check referee (recursion.forward_cost, the forward cost of each point's plan) moved by a
    chosen amount: the disagreement the check sees is ``relative`` of the forward cost plus ``absolute``."""
    real = evaluator_module.forward_cost
    monkeypatch.setattr(evaluator_module, "forward_cost", lambda *a, **k: real(*a, **k) * (1 + relative) + absolute)


@pytest.mark.parametrize(("method", "match"), [("dense", "failed the dense solve's residual or the self-check"),
                                               ("recursion", "forward cost of its own plan")])
@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_batch_self_check_refuses_3_and_keeps_0_3_times_self_check_rtol(two_actuator, monkeypatch, method, match,
                                                                          factor, kept):
    """Every point of a batch whose cost is off its plan's forward cost by 3 SELF_CHECK_RTOL raises (a dense point
    asked for by method 'dense' is not recomputed), by 0.3 SELF_CHECK_RTOL is returned as it is."""
    from packetloss_cvx.tolerances import SELF_CHECK_RTOL

    mus = np.array([[0.9, 0.5], [0.3, 0.8]])
    evaluator = CostEvaluator(two_actuator, "udp", method)
    exact = evaluator.costs(mus)
    _referee_off(monkeypatch, relative=factor * SELF_CHECK_RTOL)
    if kept:
        assert np.array_equal(evaluator.costs(mus), exact)
    else:
        with pytest.raises(pl.NumericalError, match=match):
            evaluator.costs(mus)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_batch_recursion_self_check_absolute_term_is_self_check_atol_times_p0_and_x(monkeypatch, factor, kept):
    """The batched recursion's absolute term SELF_CHECK_ATOL ||P_0|| ||x||^2 on its own (as closed_form's, see
    tests/lq/test_costs.py): ||P_0|| = 1e6 (0.81 + ... + 0.81^10) by hand, from the weight on a mode no input reaches,
    while x0 lies outside that mode and the cost is below 2."""
    from packetloss_cvx.tolerances import SELF_CHECK_ATOL

    s = pl.System(A=[[0.9, 0.0], [0.0, 0.5]], B=[[0.0], [1.0]], horizon=10, state_weight=[1e6, 1.0],
                  input_weight=[1.0], mu=[0.5], x0=[0.0, 1.0])
    norm_P0 = 1e6 * sum(0.81 ** t for t in range(1, 11))
    evaluator = CostEvaluator(s, "tcp", "recursion")
    exact = evaluator.costs([[0.5], [0.2]])
    assert np.all(exact < 2.0)
    _referee_off(monkeypatch, absolute=factor * SELF_CHECK_ATOL * norm_P0 * 1.0)
    if kept:
        assert np.array_equal(evaluator.costs([[0.5], [0.2]]), exact)
    else:
        with pytest.raises(pl.NumericalError, match="forward cost of its own plan"):
            evaluator.costs([[0.5], [0.2]])


def _with_residual(G: np.ndarray, rhs: np.ndarray, X: np.ndarray, fraction: float, keep: np.ndarray) -> np.ndarray:
    """X moved so that G X - rhs is ``fraction`` DENSE_RESIDUAL_RTOL (||G||_F ||X|| + ||rhs||) exactly (to rounding),
    along a direction that leaves keep' X unchanged (the cost C - g'Vbar X then moves only at second order: the
    residual check alone can object). G (k, k), rhs and X (k, r), keep (k,)."""
    from packetloss_cvx.tolerances import DENSE_RESIDUAL_RTOL

    y = np.linalg.solve(G.T, keep)                      # keep' G^{-1} r = y' r: r orthogonal to y moves nothing
    r = np.zeros(G.shape[0])
    r[0], r[1] = y[1], -y[0]
    r /= np.linalg.norm(r)
    size = fraction * DENSE_RESIDUAL_RTOL * (np.linalg.norm(G) * np.linalg.norm(X) + np.linalg.norm(rhs))
    step = np.linalg.solve(G, size * r)
    out = X.copy()
    out[:, 0] += step
    return out


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_batch_dense_solve_refuses_3_and_keeps_0_3_times_dense_residual_rtol(two_actuator, monkeypatch, factor, kept):
    """The dense path's LU solve returned with a relative residual ||G F - rhs|| / (||G|| ||F|| + ||rhs||) of 3
    DENSE_RESIDUAL_RTOL: the point is refused (method 'dense' raises); of 0.3: kept, with the exact solve's cost."""
    mus = np.array([[0.9, 0.5]])
    evaluator = CostEvaluator(two_actuator, "udp", "dense")
    exact = evaluator.costs(mus)
    v = np.tile(mus[0], two_actuator.horizon)
    keep = v * (prediction(two_actuator).Omega_gp @ two_actuator.x0)          # Vbar g: the cost's direction
    real = np.linalg.solve

    def solve(G, rhs):
        X = real(G, rhs)
        if G.ndim != 3:
            return X
        return np.stack([_with_residual(G[p], rhs[p], X[p], factor, keep) for p in range(G.shape[0])])

    monkeypatch.setattr(np.linalg, "solve", solve)
    if kept:
        assert evaluator.costs(mus) == pytest.approx(exact, rel=1e-13)
    else:
        with pytest.raises(pl.NumericalError, match="failed the dense solve's residual"):
            evaluator.costs(mus)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_points_cost_does_not_depend_on_its_batch(seed, protocol):
    rng = np.random.default_rng(seed)
    s = random_system(rng)
    ev = CostEvaluator(s, protocol, "recursion")
    for P in (2, 15, 63):
        mus = rng.uniform(0.0, 1.0, (P, s.m))
        mus[0] = 1.0
        batch = ev.costs(mus)
        alone = np.array([ev.costs(mu[None])[0] for mu in mus])
        assert np.array_equal(batch, alone)
        assert np.array_equal(ev.costs(mus[::-1]), batch[::-1])


@pytest.mark.parametrize("seed", range(8))
def test_the_other_protocols_evaluator_shares_the_structure_and_answers_alike(seed):
    rng = np.random.default_rng(seed)
    s = random_system(rng)
    assert np.array_equal(block_diagonal(s.state_weights), block_diag(*s.state_weights))
    mus = rng.uniform(0.0, 1.0, (5, s.m))
    for p, q in (("tcp", "udp"), ("udp", "tcp")):
        shared = CostEvaluator(s, p).with_protocol(q)
        fresh = CostEvaluator(s, q)
        assert shared.protocol == q
        assert shared.method == fresh.method
        assert np.array_equal(shared.costs(mus), fresh.costs(mus))
        assert shared.cost(mus[0]) == fresh.cost(mus[0])
        plan, ref = shared.optimum(), pl.closed_form(s, q)                  # the system's own channel
        assert plan is shared.optimum()
        assert abs(plan.cost - ref.cost) <= 1e-12 * ref.cost
        scale = max(1.0, np.abs(ref.inputs).max())
        assert np.allclose(plan.inputs, ref.inputs, rtol=1e-9, atol=1e-12 * scale)
        assert np.allclose(plan.gain, ref.gain, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(ref.gain).max()))


def test_a_chains_udp_plan_is_refused_as_closed_form_refuses_it():
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.1], r=[0.3]))
    with pytest.raises(pl.InputError, match="correlated"):
        CostEvaluator(s, "udp").optimum()
    assert abs(CostEvaluator(s, "tcp").optimum().cost - pl.closed_form(s, "tcp").cost) <= 1e-12
