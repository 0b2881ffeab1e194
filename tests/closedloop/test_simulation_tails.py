"""simulation.tails: the fourth-moment radius of a loop, and the error bars a sample gets only when it is below one."""

import itertools
import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.closedloop import tails
from packetloss_cvx.closedloop.tails import error_bar_reason, fourth_moment_radius
from packetloss_cvx.montecarlo.simulate import simulate


@pytest.mark.parametrize(("a", "k", "mu"), [(2.0, 2.0, 0.8), (1.5, 1.0, 0.6), (0.9, 0.3, 0.1), (3.0, 2.5, 0.95)])
def test_scalar_fourth_moment_radius_is_the_hand_value(a, k, mu):
    hand = mu * (a - k) ** 4 + (1 - mu) * a ** 4
    got = fourth_moment_radius(np.array([[a]]), np.array([[1.0]]), np.array([[k]]), np.array([mu]))
    assert got == pytest.approx(hand, rel=1e-12)


def _two_input_law(seed):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(2, 2)), rng.normal(size=(2, 2)), 0.5 * rng.normal(size=(2, 2)), rng.uniform(0.2, 0.9, 2)


@pytest.mark.parametrize("seed", range(4))
def test_fourth_moments_propagate_as_an_enumeration_of_delivery_paths(seed):
    """E[x_t^(4)] over every delivery path of 3 steps (64 paths) equals L_4 applied three times to x0^(4)."""
    A, B, K, mu = _two_input_law(seed)
    x0 = np.array([1.0, -0.5])
    expected = np.zeros((2, 2, 2, 2))
    for path in itertools.product(itertools.product((0.0, 1.0), repeat=2), repeat=3):
        x, p = x0, 1.0
        for v in path:
            p *= np.prod(np.where(np.array(v) == 1.0, mu, 1.0 - mu))
            x = (A - (B * np.array(v)) @ K) @ x
        expected += p * np.einsum("i,j,k,l->ijkl", x, x, x, x)
    F, prob = tails._mode_law(A, B, K[None], mu[None])
    X = np.einsum("i,j,k,l->ijkl", x0, x0, x0, x0)[None]
    for _ in range(3):
        X = tails._apply(X, F, prob, np.ones((1, 1)), "current")
    assert np.allclose(X[0], expected, rtol=1e-12, atol=1e-14 * np.abs(expected).max())


@pytest.mark.parametrize("delivery", ["current", "next"])
def test_coupled_fourth_moments_propagate_as_an_enumeration_of_mode_and_delivery_paths(delivery):
    """Behind a two-mode chain with mode gains: E[x_3^(4) ; mode_3] by enumerating modes and deliveries."""
    rng = np.random.default_rng(7)
    A, B = rng.normal(size=(2, 2)), rng.normal(size=(2, 1))
    K = 0.4 * rng.normal(size=(2, 1, 2))
    h, T = np.array([[0.9], [0.2]]), np.array([[0.8, 0.2], [0.4, 0.6]])
    x0, start = np.array([0.3, 1.0]), np.array([0.7, 0.3])
    expected = np.zeros((2, 2, 2, 2, 2))
    for modes in itertools.product((0, 1), repeat=4):          # modes at t = 0..3
        for v in itertools.product((0.0, 1.0), repeat=3):
            p, x = start[modes[0]], x0
            for t in range(3):
                p *= T[modes[t], modes[t + 1]]
                q = h[modes[t] if delivery == "current" else modes[t + 1], 0]
                p *= q if v[t] else 1.0 - q
                x = (A - B * v[t] @ K[modes[t]]) @ x
            expected[modes[3]] += p * np.einsum("i,j,k,l->ijkl", x, x, x, x)
    F, prob = tails._mode_law(A, B, K, h)
    X = start[:, None, None, None, None] * np.einsum("i,j,k,l->ijkl", x0, x0, x0, x0)[None]
    for _ in range(3):
        X = tails._apply(X, F, prob, T, delivery)
    assert np.allclose(X, expected, rtol=1e-12, atol=1e-14 * np.abs(expected).max())


def test_bernoulli_channels_are_the_one_mode_chain():
    """A memoryless two-mode chain (identical rows) that delivers with probability mu in both modes has the
    Bernoulli loop's fourth-moment radius."""
    A, B, K, mu = _two_input_law(1)
    chain = fourth_moment_radius(A, B, K, np.vstack([mu, mu]), np.full((2, 2), 0.5))
    assert chain == pytest.approx(fourth_moment_radius(A, B, K, mu), rel=1e-10)


@pytest.mark.parametrize("seed", range(3))
def test_the_operator_path_agrees_with_the_kronecker_matrix(seed, monkeypatch):
    """ARPACK on the operator (forced on a 3-state plant) against the eigenvalues of sum_v p_v (F_v kron 4)."""
    rng = np.random.default_rng(seed)
    A, B, K, mu = rng.normal(size=(3, 3)), rng.normal(size=(3, 2)), 0.3 * rng.normal(size=(2, 3)), np.array([0.7, 0.4])
    L4 = np.zeros((81, 81))
    for v in itertools.product((0.0, 1.0), repeat=2):
        p = np.prod(np.where(np.array(v) == 1.0, mu, 1.0 - mu))
        F = A - (B * np.array(v)) @ K
        L4 += p * np.kron(np.kron(F, F), np.kron(F, F))
    reference = np.abs(np.linalg.eigvals(L4)).max()
    monkeypatch.setattr(tails, "FOURTH_MOMENT_DENSE_MAX_DIM", 0)
    assert fourth_moment_radius(A, B, K, mu) == pytest.approx(reference, rel=1e-8)


def test_the_error_bar_band_is_the_stability_margin_on_both_sides():
    """rho_4 = (1 - mu) a^4 with k = a: 1 - 1e-8 (10x inside the margin 1e-9) has a bar, 1 - 1e-10 does not."""
    one = np.array([[1.0]])
    assert error_bar_reason(one, one, one, np.array([1e-8])) == ""
    assert error_bar_reason(one, one, one, np.array([1e-10])).startswith("no error bar: the fourth moments grow")


@pytest.fixture(scope="module")
def heavy():
    """a = 2 behind mu = 0.8: the DP law's second moments decay (0.8) but its fourth grow (3.2)."""
    return pl.System(A=[[2.0]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1e-6], mu=[0.8], x0=[1.0],
                     noise_cov=[[1.0]])


def test_a_heavy_tailed_loop_is_sampled_without_an_error_bar(heavy):
    run = simulate(heavy, samples=2000, steps=30, seed=0, closed_loop=True, laws=["dp"], progress=False).closed_loop[
        "dp"]
    assert run.stable
    assert run.spectral_radius < 1
    assert np.isnan(run.stderr)
    assert "fourth moments grow" in run.stderr_reason
    assert run.to_dict()["stderr"] is None
    assert "stderr_reason" in run.to_dict()


def test_behind_a_chain_the_mode_dependent_law_gets_its_bar_and_a_belief_law_says_why_not():
    sim = simulate(pl.load_example("pendulum_bursty"), samples=300, steps=10, seed=0, closed_loop=True,
                   progress=False)
    for law, run in sim.closed_loop.items():
        if np.isnan(run.spectral_radius):
            assert np.isnan(run.stderr), law
            assert run.stderr_reason.startswith("no error bar"), law
        elif run.stderr_reason == "":
            assert np.isfinite(run.stderr), law


def test_a_light_tailed_loop_keeps_its_error_bar(two_actuator):
    run = simulate(two_actuator, samples=2000, steps=30, seed=0, closed_loop=True, laws=["dp"],
                   progress=False).closed_loop["dp"]
    assert run.stderr_reason == ""
    assert np.isfinite(run.stderr)
    assert run.stderr > 0


def test_the_command_line_prints_no_plus_minus_for_a_heavy_tailed_loop(heavy, tmp_path, capsys):
    path = pl.save_system(heavy, tmp_path / "heavy.toml")
    assert main(["simulate", str(path), "--samples", "500", "--steps", "20", "--seed", "0", "--closed-loop"]) == 0
    text = capsys.readouterr().out
    dp_line = next(line for line in text.splitlines() if line.startswith("  DP optimum, closed loop"))
    assert "+-" not in dp_line
    assert "no error bar: the fourth moments grow" in text
    assert main(["simulate", str(path), "--samples", "500", "--steps", "20", "--seed", "0", "--closed-loop",
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["dp"]["closed_loop"]["stderr"] is None
