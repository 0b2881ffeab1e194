"""Certificates re-checked in exact arithmetic (linalg.Dyadic, linalg.exact_psd, simulation/certificates.py).

References: every principal minor in Fraction arithmetic (a matrix is PSD iff all are >= 0, PD iff the leading ones
are > 0), hand values of the scalar plant (every law's radius >= a^2 (1 - mu)), the Kronecker matrix of the second
moment enumerated over the delivery patterns, and the exact single-input least radius of a chain of integrators
(Elia 2005: mu is in S iff (1 - mu) prod |lambda_i|^2 < 1; scaled by rho, min_K rho(L_K) = |lambda|^2 (1 - mu)^(1/n)
for one Jordan block of size n).
"""

import itertools
from fractions import Fraction

import numpy as np
import pytest

from packetloss_cvx.closedloop import region
from packetloss_cvx.closedloop.certificates import (
    inside_proved,
    law_proved_stable,
    no_law_proved,
    outside_proved,
    snapped,
    stability_witness,
    tilted,
)
from packetloss_cvx.closedloop.moments import solve_fixed_point
from packetloss_cvx.closedloop.region import homogeneous_riccati
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.linalg import Dyadic, exact_psd
from packetloss_cvx.tolerances import CERTIFICATE_RTOL, MEAN_SQUARE_MARGIN

from ..references import enumerated_radius


def _det(rows):
    """A determinant by Gaussian elimination in Fractions."""
    M = [list(r) for r in rows]
    n, d = len(M), Fraction(1)
    for k in range(n):
        p = next((i for i in range(k, n) if M[i][k] != 0), None)
        if p is None:
            return Fraction(0)
        if p != k:
            M[k], M[p] = M[p], M[k]
            d = -d
        d *= M[k][k]
        for i in range(k + 1, n):
            f = M[i][k] / M[k][k]
            for j in range(k, n):
                M[i][j] -= f * M[k][j]
    return d


def _psd_by_minors(M, strict):
    F = [[Fraction(float(x)) for x in row] for row in M]
    n = len(F)
    if strict:
        return all(_det([r[:k] for r in F[:k]]) > 0 for k in range(1, n + 1))
    return all(_det([[F[i][j] for j in S] for i in S]) >= 0
               for k in range(1, n + 1) for S in itertools.combinations(range(n), k))


@pytest.mark.parametrize("seed", range(4))
def test_exact_psd_agrees_with_every_principal_minor(seed):
    """Integer Gram matrices L L' (PSD, of every rank), scaled by 2^-30 and 2^40 (exact), some with a diagonal entry
    moved by a relative 2^-20 either way: PSD and PD decided as the minors decide, both ways."""
    rng = np.random.default_rng(seed)
    seen = set()
    for _ in range(150):
        n = int(rng.integers(1, 6))
        L = rng.integers(-3, 4, size=(n, int(rng.integers(0, n + 1)))).astype(float)
        M = (L @ L.T) * rng.choice([1.0, 2.0 ** -30, 2.0 ** 40])
        if rng.random() < 0.5:
            i = int(rng.integers(n))
            M[i, i] += rng.choice([-1.0, 1.0]) * rng.choice([2.0 ** -20, 1.0]) * (abs(M[i, i]) or 1.0)
        for strict in (False, True):
            got = exact_psd(Dyadic.of(M), strict)
            assert got == _psd_by_minors(M, strict)
            seen.add((strict, got))
    assert len(seen) == 4     # PSD and not, PD and not: both answers were tested


def test_dyadic_arithmetic_is_exact():
    """0.1 is the double nearest 1/10; its exact square plus 2^-1074 (the least double) is what Fraction says."""
    x = Dyadic.of(np.array([[0.1, 5e-324]]))
    product = x @ x.T
    assert product.fraction(0, 0) == Fraction(0.1) ** 2 + Fraction(5e-324) ** 2
    with pytest.raises(NumericalError, match="not finite"):
        Dyadic.of(np.array([np.inf]))


def test_outside_certificate_is_decided_at_the_exact_bound():
    """Scalar a = 2, b = 1: every law's radius is >= a^2 (1 - mu), equal at k = a (hand). At mu = 3/4 (exact in
    binary) the bound 1 holds and 1 + 2^-40 does not; P = -1 (negative definite) proves nothing."""
    A, B, mu = np.array([[2.0]]), np.array([[1.0]]), np.array([0.75])
    assert outside_proved(A, B, mu, np.eye(1), 1.0)
    assert not outside_proved(A, B, mu, np.eye(1), 1.0 + 2.0 ** -40)
    assert not outside_proved(A, B, mu, -np.eye(1), 0.5)
    assert no_law_proved(A, B, mu, np.eye(1))
    assert not no_law_proved(A, B, np.array([0.75 + 2.0 ** -40]), np.eye(1))


def test_inside_witness_is_decided_at_the_exact_radius():
    """k = a = 2 at mu = 7/8: L_K(x) = (a - mu k)^2 x + mu (1 - mu) k^2 x = x / 2 exactly (hand)."""
    A, B, K, mu = np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.875])
    assert inside_proved(A, B, K, mu, np.eye(1), 0.5 + 2.0 ** -50)
    assert not inside_proved(A, B, K, mu, np.eye(1), 0.5)
    assert not inside_proved(A, B, K, mu, -np.eye(1), 1.0)           # X must be definite
    assert law_proved_stable(A, B, K, mu)
    assert stability_witness(A, B, K, mu, 0.5) is None                # its radius is not below 0.5


def test_a_chain_of_integrators_false_certificate_is_refused_and_its_gain_proved():
    """A = I4 + N (ones on the superdiagonal), b = e4, mu = 0.0124 (a chain of integrators near S's edge): the exact
    least radius is (1 - mu)^(1/4) = 0.99689 < 1 (Elia), and the gain K = [4.888e-9, 6.896e-6, 4.1397e-3, 1.00413] has
    radius 0.99750 (enumerated). The unscaled power iteration (its P graded from 4e-14 to 1) gives lambda 1.00137 and a
    P that a float check accepts with margin 6.6e-4 under the Haswell kernel (the P and its float margin move with the
    kernel); in exact arithmetic neither that P nor any of its cuts proves anything, and the gain is proved
    stable."""
    A, B, mu = np.eye(4) + np.eye(4, k=1), np.eye(4)[:, 3:], np.array([0.0124])
    K = np.array([[4.888e-9, 6.896e-6, 4.1397e-3, 1.00413]])
    assert enumerated_radius(A, B, K, mu) == pytest.approx(0.99750, abs=1e-5)
    assert law_proved_stable(A, B, K, mu)
    lam, P, _ = _unscaled(A, B, mu)
    assert lam > 1.0                                                  # the candidate is wrong
    w, U = np.linalg.eigh(P / np.trace(P))
    cuts = [(U[:, w > c * w[-1]] * w[w > c * w[-1]]) @ U[:, w > c * w[-1]].T for c in (0.0, 1e-12, 1e-9, 1e-6)]
    for Q in cuts:
        assert not outside_proved(A, B, mu, Q / np.trace(Q), 1.0 - CERTIFICATE_RTOL)


def _unscaled(A, B, mu):
    """The homogeneous Riccati eigenpair without the graded refinement (region._GRADED = 0)."""
    saved = region._GRADED
    region._GRADED = 0.0
    try:
        return homogeneous_riccati(A, B, mu)
    finally:
        region._GRADED = saved


def test_a_rank_one_certificate_is_proved_tilted_not_as_rounded():
    """A = [[2, 1], [0, 0.5]] has x'A = 2 x' for x = (3, 2): with b'x != 0, every law leaves E[(x'x_t)^2] to grow by
    a^2 (1 - mu) = 2 at mu = 1/2 (the scalar case), so P = vv' (v = x / |x|) proves every radius >= 2 in exact
    arithmetic only with its exact kernel. Rounded, vv' fails at 1.9; the Stein-tilted P - t S (t down to 1e-14 of
    ||P||) pass."""
    A, B, mu = np.array([[2.0, 1.0], [0.0, 0.5]]), np.array([[0.6], [-0.2]]), np.array([0.5])
    v = np.array([3.0, 2.0]) / np.sqrt(13.0)
    assert not outside_proved(A, B, mu, np.outer(v, v), 1.9)
    proved = [outside_proved(A, B, mu, Q, 1.9) for Q in tilted(A, np.outer(v, v), 1.9)]
    assert len(proved) == 6
    assert all(proved)
    # and no more than the truth: the gain K = a x' / (b'x) (it cancels x'Ax's mean) has radius 2 (enumerated)
    x = np.array([3.0, 2.0])
    assert enumerated_radius(A, B, 2.0 * x[None] / float(B[:, 0] @ x), mu) == pytest.approx(2.0, abs=1e-12)
    assert not any(outside_proved(A, B, mu, Q, 2.0 + 1e-9) for Q in tilted(A, np.outer(v, v), 2.0 + 1e-9))


def test_snapping_restores_the_exact_zeros_of_a_decoupled_certificate():
    """diag(0.5, 2), B = (1, 0)': x2+ = 2 x2 whatever the law, so P = e2 e2' proves every radius >= 4 (hand). With
    1e-17 off the block (an orthogonal transform's rounding) T_c(P) is indefinite by 1e-34; snapped, it holds."""
    A, B, mu = np.diag([0.5, 2.0]), np.array([[1.0], [0.0]]), np.array([0.5])
    P = np.array([[1e-34, 1e-17], [1e-17, 1.0]])
    assert not outside_proved(A, B, mu, P, 3.9)
    assert any(outside_proved(A, B, mu, Q, 3.9) for Q in snapped(P))


def test_a_singular_fixed_point_solve_is_a_numerical_error():
    """X = X + C has no solution (the map has the eigenvalue 1): a NumericalError, not numpy's LinAlgError escaping
    membership, critical_point and region_map near a boundary."""
    with pytest.raises(NumericalError, match="singular"):
        solve_fixed_point(lambda X: X, lambda: np.eye(1), np.eye(1), "a demo")


def test_the_stable_margin_is_the_registered_one():
    """law_proved_stable proves rho < 1 - MEAN_SQUARE_MARGIN: scalar k = a, radius a^2 (1 - mu) (hand), just inside
    and just outside that margin."""
    A, B, K = np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]])
    inside = 1.0 - (1.0 - 2.0 * MEAN_SQUARE_MARGIN) / 4.0            # radius 1 - 2 margin
    outside = 1.0 - (1.0 - 0.5 * MEAN_SQUARE_MARGIN) / 4.0           # radius 1 - margin / 2
    assert law_proved_stable(A, B, K, np.array([inside]))
    assert not law_proved_stable(A, B, K, np.array([outside]))


# ---- the chains' certificates on the same exact path (Bernoulli is the one-mode chain) ----

def test_a_memoryless_chain_with_equal_deliveries_gives_the_bernoulli_verdict_exactly():
    """p + r = 1 and h_good = h_bad = mu: every mode's T_c(P) is Bernoulli's (the exact rows of T sum to 1), so the
    chain's exact verdict is outside_proved's at every c, proved or not."""
    from packetloss_cvx.closedloop.certificates import chain_outside_proved
    from packetloss_cvx.model.channel import GilbertElliott

    rng = np.random.default_rng(71)
    seen = set()
    for n, m in [(1, 1), (2, 1), (3, 2)]:
        for _ in range(4):
            A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
            F = rng.normal(size=(n, n))
            P, mu, p = F @ F.T, rng.uniform(0.2, 1.0, m), rng.uniform(0.1, 0.9, m)
            ch = GilbertElliott(p=p, r=1 - p, h_good=mu, h_bad=mu)
            for c in (1e-3, 0.1, 0.5, 1.0):
                verdict = outside_proved(A, B, mu, P, c)
                assert chain_outside_proved(A, B, ch, np.repeat(P[None], 2**m, axis=0), c) == verdict
                seen.add(verdict)
    assert seen == {True, False}


@pytest.mark.parametrize("delivery", ["current", "next"])
@pytest.mark.parametrize("seed", [72, 73, 74])
def test_chain_certificates_are_proved_exactly_below_the_least_radius_and_never_above(seed, delivery):
    """homogeneous_coupled_riccati's certificate P proves its float bound (chain_certificate_margin + 1) less 1e-7
    in exact arithmetic, and nothing 1e-6 above the coupled radius r of its own gains K (the dense operator's
    eigenvalues): r is attained by a law, so a check that proved more would be wrong."""
    from packetloss_cvx.closedloop.certificates import chain_outside_proved
    from packetloss_cvx.closedloop.chain_radius import chain_certificate_margin, homogeneous_coupled_riccati
    from packetloss_cvx.closedloop.mjls import mean_square_radius as chain_radius
    from packetloss_cvx.model.channel import GilbertElliott

    rng = np.random.default_rng(seed)
    n, m = 2, 2
    A, B = rng.normal(size=(n, n)) * 1.5, rng.normal(size=(n, m))
    ch = GilbertElliott(p=rng.uniform(0.1, 0.4, m), r=rng.uniform(0.2, 0.6, m), h_good=rng.uniform(0.6, 1.0, m),
                        h_bad=rng.uniform(0.0, 0.4, m))
    lam, P, K = homogeneous_coupled_riccati(A, B, ch, delivery)
    attained = chain_radius(A, B, ch, K, delivery, method="dense")
    bound = 1.0 + chain_certificate_margin(A, B, ch, P, delivery)
    assert bound == pytest.approx(lam, rel=1e-6)
    assert bound <= attained * (1 + 1e-9)
    assert chain_outside_proved(A, B, ch, P, bound * (1 - 1e-7), delivery)
    assert not chain_outside_proved(A, B, ch, P, attained * (1 + 1e-6), delivery)


def test_a_mode_with_sure_deliveries_is_proved_by_the_closed_loop_tilt():
    """A 3-state plant behind a Gilbert channel, "current" (the good state delivers surely): the least radius is
    1.416, and R's eigenvector is rank one on the good mode, the minimising input acting on its kernel. That block
    rebuilt as l l' + 1e-13 k k' (k its kernel direction: weight there that R(P) does not return, as rounding
    leaves) is refused by every open-loop candidate (P, snapped, the coupled Stein tilts) at c = 1 - 1e-12, under
    Haswell, Prescott, Nehalem and SkylakeX; the tilt by ``cS - L_K^*(S) = I`` at the eigenpair's own gains K
    proves it (definite on ``[x; K x]``, x in the kernel). Planted (the gains not passed): fails."""
    from packetloss_cvx.closedloop.certificates import chain_outside_proved, chain_proved_certificate
    from packetloss_cvx.closedloop.chain_radius import homogeneous_coupled_riccati
    from packetloss_cvx.closedloop.mjls import mean_square_radius as chain_radius
    from packetloss_cvx.model.channel import GilbertElliott

    rng = np.random.default_rng(2)
    n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
    A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
    ch = GilbertElliott(p=rng.uniform(0.05, 0.6, m), r=rng.uniform(0.05, 0.9, m))
    assert (n, m, ch.h_good.tolist(), ch.h_bad.tolist()) == (3, 1, [1.0], [0.0])
    lam, P, K = homogeneous_coupled_riccati(A, B, ch, "current")
    assert chain_radius(A, B, ch, K, "current", method="dense") == pytest.approx(lam, rel=1e-9)
    assert lam > 1.4
    w, U = np.linalg.eigh(P[0])
    assert w[1] <= 1e-15 * w[2]                                  # rank one on the good mode
    Q = P.copy()
    Q[0] = w[2] * np.outer(U[:, 2], U[:, 2]) + 1e-13 * np.outer(U[:, 0], U[:, 0])
    assert chain_proved_certificate(A, B, ch, Q, 1 - CERTIFICATE_RTOL, "current") is None
    proved = chain_proved_certificate(A, B, ch, Q, 1 - CERTIFICATE_RTOL, "current", K)
    assert proved is not None
    assert chain_outside_proved(A, B, ch, proved, 1 - CERTIFICATE_RTOL, "current")
