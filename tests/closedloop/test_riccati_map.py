"""The homogeneous Riccati map over M-mode channels (simulation/riccati_map.py).

References: hand values (scalar plants: one mode ``R(p) = a^2 (1 - mu) p``; a Gilbert channel, deadbeat when good:
``R(P)_a = a^2 T_a,bad P_bad``), the Theorem-1 step's closed form ``A'PA - G' H^-1 G`` (a Hessian inverse instead
of a least-squares residual), and the one-mode chain against a two-mode chain whose modes deliver alike (the
stacked path against the one-mode path: the same map).
"""

import numpy as np
import pytest

from packetloss_cvx.closedloop.riccati_map import (
    bernoulli_rates,
    certificate_bound,
    chain_rates,
    cut_candidates,
    reach_split,
    riccati_squares,
)


@pytest.mark.parametrize(("a", "mu"), [(2.0, 0.5), (1.5, 0.9), (3.0, 0.0), (0.7, 1.0)])
def test_one_mode_scalar_map_is_a_squared_times_the_loss(a, mu):
    """Scalar, one input: min_k E[(a - v k)^2] = a^2 (1 - mu) at k = a (hand), so R(p) = a^2 (1 - mu) p."""
    A, B = np.array([[a]]), np.array([[1.0]])
    _, squares, weight = riccati_squares(np.array([[[[2.0]]]]), A, B, *bernoulli_rates(np.array([[mu]])))
    assert squares[0] / weight[0] == pytest.approx(a * a * (1 - mu), rel=1e-14, abs=1e-15)
    assert certificate_bound(np.eye(1)[None], A, B, *bernoulli_rates(np.array([mu]))) == pytest.approx(
        a * a * (1 - mu), rel=1e-14, abs=1e-15)


@pytest.mark.parametrize("delivery", ["next", "current"])
def test_gilbert_channel_scalar_map_by_hand(delivery):
    """Scalar a, one Gilbert channel (good delivers surely, bad never), modes (good, bad), T = [[1 - p, p], [r, 1 - r]].
    "next": from mode a the step delivers iff the next mode is good, so k = a zeroes that branch and R(P)_a = a^2
    T_a,bad P_bad. "current": from good every step delivers (R = 0 at k = a), from bad none (R = a^2 (T_bg P_g + T_bb
    P_b))."""
    a, p, r = 1.7, 0.3, 0.6
    T, h = np.array([[1 - p, p], [r, 1 - r]]), np.array([[1.0], [0.0]])
    P = np.array([[[0.4]], [[0.6]]])
    F = riccati_squares(P, np.array([[a]]), np.array([[1.0]]), *chain_rates(T, h, delivery), scaled=True)[0]
    R = np.einsum("aki,akj->aij", F, F)[:, 0, 0]
    if delivery == "next":
        expected = [a * a * p * 0.6, a * a * (1 - r) * 0.6]
    else:
        expected = [0.0, a * a * (r * 0.4 + (1 - r) * 0.6)]
    assert R == pytest.approx(expected, rel=1e-14, abs=1e-15)
    # P on the bad mode only: its bound is R(P)_bad / P_bad = a^2 (1 - r) under either convention
    bound = certificate_bound(np.array([[[0.0]], [[1.0]]]), np.array([[a]]), np.array([[1.0]]),
                              *chain_rates(T, h, delivery), scaled=True)
    assert bound == pytest.approx(a * a * (1 - r), rel=1e-14)


@pytest.mark.parametrize("seed", range(5))
def test_one_mode_map_is_the_theorem_one_step_without_weights(seed):
    """For P > 0 and a Hessian H = M B'PB M + diag(mu (1 - mu)) o B'PB > 0, R(P) = A'PA - G'H^-1 G with G = M B'PA
    (the closed form of min_K L_K^*(P)), which riccati_squares gives as a least-squares residual instead."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 5)), int(rng.integers(1, 4))
    A, B, mu = rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.uniform(0.05, 0.95, size=m)
    X = rng.normal(size=(n, n))
    P = X @ X.T + 0.1 * np.eye(n)
    M = np.diag(mu)
    BPB = B.T @ P @ B
    H = M @ BPB @ M + np.diag(mu * (1 - mu) * np.diag(BPB))
    G = M @ B.T @ P @ A
    expected = A.T @ P @ A - G.T @ np.linalg.solve(H, G)
    F = riccati_squares(P[None, None], A, B, *bernoulli_rates(mu[None]))[0][0, 0]
    scale = np.linalg.norm(A.T @ P @ A, 2)
    assert np.allclose(F.T @ F, expected, rtol=0, atol=1e-11 * scale)


@pytest.mark.parametrize("seed", range(5))
def test_two_modes_that_deliver_alike_are_the_one_mode_chain(seed):
    """A chain whose modes have the same delivery rates mu and P_a = P in both: R(P)_a is Bernoulli(mu)'s R(P)
    whatever T (each row sums to 1). The stacked two-mode path against the one-mode path, and both bounds."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
    A, B, mu = rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.uniform(0.05, 0.95, size=m)
    X = rng.normal(size=(n, n))
    P = X @ X.T
    q = rng.uniform(0.1, 0.9, size=2)
    T, h = np.array([[q[0], 1 - q[0]], [q[1], 1 - q[1]]]), np.vstack([mu, mu])
    one = riccati_squares(P[None, None], A, B, *bernoulli_rates(mu[None]))[0][0, 0]
    two = riccati_squares(np.stack([P, P]), A, B, *chain_rates(T, h, "next"))[0]
    for F in two:
        assert np.allclose(F.T @ F, one.T @ one, rtol=1e-12, atol=1e-12 * np.linalg.norm(one, 2) ** 2)
    assert certificate_bound(np.stack([P, P]), A, B, *chain_rates(T, h, "current")) == pytest.approx(
        certificate_bound(P[None], A, B, *bernoulli_rates(mu)), rel=1e-10)


def test_cut_candidates_drop_the_directions_below_each_cut():
    """P = diag(1, 1e-10, 1e-13) on one mode and diag(0.5, 0) on another: the cut at 1e-12 drops the 1e-13 direction,
    at 1e-9 and 1e-6 the 1e-10 one too; each candidate has trace 1 over the modes (hand)."""
    P = np.array([np.diag([1.0, 1e-10, 1e-13]), np.diag([0.5, 0.0, 0.0])])
    found = list(cut_candidates(P))
    total = 1.5 + 1e-10
    assert len(found) == 3
    assert np.allclose(found[0], np.array([np.diag([1.0, 1e-10, 0.0]), np.diag([0.5, 0.0, 0.0])]) / total,
                       rtol=0, atol=1e-16)
    for Q in found[1:]:
        assert np.allclose(Q, np.array([np.diag([1.0, 0.0, 0.0]), np.diag([0.5, 0.0, 0.0])]) / 1.5, rtol=0,
                           atol=1e-16)
    assert not list(cut_candidates(np.eye(2)[None]))          # no cut changes a well-spread P


def test_reach_split_zeroes_the_rows_of_the_part_no_input_reaches():
    """A = diag(0.5, 1.2), b = e1: the second state is not reached (nc = 1, A_uu = 1.2); a channel that never
    delivers reaches nothing (nc = 0) (hand)."""
    A, B = np.diag([0.5, 1.2]), np.array([[1.0, 0.0], [0.0, 1.0]])
    split, Bt = reach_split(A, B, np.array([True, False]))
    assert split.nc == 1
    assert split.A_uu.tolist() == [[1.2]]
    assert np.all(Bt[1:] == 0.0)
    assert abs(abs(Bt[0, 0]) - 1.0) <= 1e-15
    assert reach_split(A, B, np.array([False, False]))[0].nc == 0
