"""The exact inside certificate behind a chain (closedloop.certificates.chain_inside_proved, chain_law_proved_stable):
it proves the mode gains' coupled radius below 1 exactly where the radius is below 1, and never where it is not,
whatever radius a caller claims.

Independent reference, written here: the coupled second-moment radius of the mode gains by power iteration of
``Q_b <- sum_a T_ab sum_v P(v | b) (A - B V K_a) Q_a (A - B V K_a)'`` with every delivery vector enumerated.
"""

import itertools

import numpy as np
import pytest

from packetloss_cvx.closedloop.certificates import chain_inside_proved, chain_law_proved_stable
from packetloss_cvx.model.chain import mode_chain
from packetloss_cvx.model.channel import GilbertElliott


def enumerated_radius(A, B, channel, K, iterations=400):
    """The coupled second-moment radius of mode gains K ("next": the gain of the last mode, the deliveries of the
    next) by power iteration over the enumerated delivery vectors."""
    _, T, h = mode_chain(channel)
    M, n, m = T.shape[0], A.shape[0], B.shape[1]
    patterns = [np.array(v, dtype=float) for v in itertools.product((0.0, 1.0), repeat=m)]
    Q = np.array([np.eye(n) for _ in range(M)])
    ratio = np.nan
    for _ in range(iterations):
        nxt = np.zeros_like(Q)
        for a, b in itertools.product(range(M), range(M)):
            for v in patterns:
                w = T[a, b] * float(np.prod(np.where(v == 1.0, h[b], 1.0 - h[b])))
                F = A - (B * v) @ K[a]
                nxt[b] += w * F @ Q[a] @ F.T
        total = sum(np.trace(X) for X in nxt)
        ratio, Q = total / sum(np.trace(X) for X in Q), nxt / total
    return ratio


@pytest.mark.parametrize("seed", range(8))
def test_chain_law_proved_stable_agrees_with_the_enumerated_radius(seed):
    rng = np.random.default_rng(seed)
    m = 1 + seed % 2
    ch = GilbertElliott(p=rng.uniform(0.05, 0.5, m), r=rng.uniform(0.2, 0.8, m), h_good=rng.uniform(0.7, 1.0, m),
                        h_bad=rng.uniform(0.0, 0.4, m))
    M = 2 ** m
    A = rng.normal(size=(2, 2))
    B = rng.normal(size=(2, m))
    K = np.array([np.linalg.lstsq(B, A, rcond=None)[0] * rng.uniform(0.3, 1.0) for _ in range(M)])
    radius = enumerated_radius(A, B, ch, K)
    assert abs(radius - 1) >= 1e-3        # the seeds' premise (off the boundary), asserted rather than skipped
    assert chain_law_proved_stable(A, B, ch, K, radius) is bool(radius < 1)
    if radius > 1:      # a claimed radius below the true one never proves what is false: the witness is checked
        assert not chain_law_proved_stable(A, B, ch, K, 0.5)


def test_chain_inside_proved_rejects_a_witness_just_short_of_the_bound():
    """Scalar deadbeat law behind a Gilbert channel: L_K(X) = (0, a^2 (p X_g + (1 - r) X_b)) exactly, so X = (1, 1)
    proves c iff c > a^2 (p + 1 - r) (and X_g c > 0)."""
    ch = GilbertElliott(p=[0.25], r=[0.5])                   # a^2 (p + 1 - r) = 4 * 0.75 = 3
    A, B, K, X = np.array([[2.0]]), np.array([[1.0]]), np.full((2, 1, 1), 2.0), np.ones((2, 1, 1))
    assert chain_inside_proved(A, B, ch, K, X, 3.0 + 2.0 ** -40)
    assert not chain_inside_proved(A, B, ch, K, X, 3.0)
    assert not chain_inside_proved(A, B, ch, K, -X, 4.0)       # X must be positive definite


def test_chain_inside_proved_counts_the_delivery_variance():
    """Fractional deliveries (0.75, 0.25), x' = (2 - 2 v) x in both modes, X = (1, 1): by hand
    ``L_K(X)_b = ((a - h_b k)^2 + h_b (1 - h_b) k^2) sum_a T_ab`` = 1.0 * 1.25 (good) and 3.0 * 0.75 = 2.25 (bad),
    all dyadic: X proves c iff c > 2.25. Without the variance term the bad block would be 1.6875, and c = 2 pass."""
    ch = GilbertElliott(p=[0.25], r=[0.5], h_good=[0.75], h_bad=[0.25])
    A, B, K, X = np.array([[2.0]]), np.array([[1.0]]), np.full((2, 1, 1), 2.0), np.ones((2, 1, 1))
    assert chain_inside_proved(A, B, ch, K, X, 2.25 + 2.0 ** -40)
    assert not chain_inside_proved(A, B, ch, K, X, 2.25)
    assert not chain_inside_proved(A, B, ch, K, X, 2.0)
