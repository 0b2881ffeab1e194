"""The stabilisable set behind Gilbert–Elliott channels (simulation.markov_region) against hand values (one state
and a Gilbert channel: r > 1 - 1/a^2 whatever p), the Bernoulli set at a memoryless chain's mean rate, the
coupled Riccati equation of markov.mjls (another algorithm, with weights), and sampled mode gains."""

import os
from pathlib import Path

import numpy as np
import pytest

from packetloss_cvx.closedloop.certificates import chain_outside_proved
from packetloss_cvx.closedloop.markov_region import (
    chain_at_rate,
    chain_certificate_margin,
    chain_critical_rate,
    chain_membership,
    chain_rate_map,
    critical_rate_unproved,
    homogeneous_coupled_riccati,
)
from packetloss_cvx.closedloop.mjls import coupled_riccati
from packetloss_cvx.closedloop.mjls import mean_square_radius as mjls_radius
from packetloss_cvx.closedloop.region import membership
from packetloss_cvx.errors import InputError, NumericalError
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import CERTIFICATE_RTOL, MEAN_SQUARE_MARGIN


def pl_load(name):
    from packetloss_cvx import load_system
    from packetloss_cvx.model.examples import __file__ as examples

    return load_system(Path(examples).parent / f"{name}.toml")


@pytest.mark.parametrize("a", [1.5, 2.0, 4.0])
@pytest.mark.parametrize("p", [0.05, 0.4, 0.9])
def test_one_state_gilbert_channel_needs_r_above_one_minus_one_over_a_squared(a, p):
    # by hand: deadbeat when good (h = 1), x+ = a x when bad: radius a^2 (1 - r), whatever p
    threshold = 1 - 1 / a**2
    A, B = np.array([[a]]), np.array([[1.0]])
    below = chain_membership(A, B, GilbertElliott(p=[p], r=[threshold - 0.01]))
    above = chain_membership(A, B, GilbertElliott(p=[p], r=[min(threshold + 0.01, 1.0)]))
    assert below.verdict == "unstable"
    assert chain_certificate_margin(A, B, GilbertElliott(p=[p], r=[threshold - 0.01]), below.certificate) >= -1e-12
    assert above.verdict == "stable"
    assert mjls_radius(A, B, GilbertElliott(p=[p], r=[min(threshold + 0.01, 1.0)]), above.gain, "next") < 1
    for delivery in ("current", "next"):                      # one channel: knowing the state changes nothing here
        assert chain_membership(A, B, GilbertElliott(p=[p], r=[threshold - 0.01]), delivery).verdict == "unstable"


@pytest.mark.parametrize("seed", range(8))
def test_memoryless_chain_is_the_bernoulli_set_at_its_mean_rate(seed):
    rng = np.random.default_rng(seed)
    n, m = 2, 2
    A = rng.normal(size=(n, n))
    A *= rng.uniform(1.0, 1.6) / max(abs(np.linalg.eigvals(A)))
    B = rng.normal(size=(n, m))
    s = System(A=A, B=B, horizon=1, state_weight=[1.0] * n, input_weight=[1.0] * m, mu=[1.0] * m, x0=[1.0] * n)
    agreed = 0
    for _ in range(10):
        mu = rng.uniform(0.05, 0.95, m)
        chain = chain_membership(A, B, GilbertElliott(p=1 - mu, r=mu))        # p + r = 1: memoryless
        bern = membership(s, mu, forms=("riccati", "lmi"), cross_check=False)
        if "undecided" not in (chain.verdict, bern.verdict):
            assert chain.verdict == bern.verdict, mu
            agreed += 1
    assert agreed >= 8


def test_knowing_the_current_state_can_only_help():
    # "current" tells the law which packets will arrive: its set contains the "next" one (a law that ignores the
    # extra knowledge is one of its laws); two channels of two_actuator's plant at a memoryless chain
    A, B = np.array([[1.03, 0.005], [0.35, 1.01]]), np.eye(2)
    for mu in ([0.06, 0.06], [0.1, 0.02], [0.03, 0.1]):
        mu = np.array(mu)
        ch = GilbertElliott(p=1 - mu, r=mu)
        if chain_membership(A, B, ch, "next").verdict == "stable":
            assert chain_membership(A, B, ch, "current").verdict == "stable"
        assert (chain_membership(A, B, ch, "current").verdict == "unstable") <= (
            chain_membership(A, B, ch, "next").verdict == "unstable")


@pytest.mark.parametrize("seed", range(6))
def test_current_convention_against_the_coupled_riccati_equation(seed):
    # markov.mjls.coupled_riccati's law knows the current state ("current"): where the set says stable, that
    # equation (value iteration with Omega > 0) has a stabilising solution; where no law works, it has none
    rng = np.random.default_rng(100 + seed)
    A = np.array([[1.0 + rng.uniform(0, 0.4), rng.uniform(-0.5, 0.5)], [0.0, rng.uniform(0.5, 1.3)]])
    B = rng.normal(size=(2, 2))
    for _ in range(4):
        ch = GilbertElliott(p=rng.uniform(0.05, 0.6, 2), r=rng.uniform(0.05, 0.9, 2))
        found = chain_membership(A, B, ch, delivery="current")
        s = System(A=A, B=B, horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0], x0=[1.0, 1.0], channel=ch)
        if found.verdict == "stable":
            assert coupled_riccati(s).spectral_radius < 1
        elif found.verdict == "unstable":
            try:
                radius = coupled_riccati(s).spectral_radius
            except NumericalError:
                continue
            assert radius >= 1 - 1e-9



@pytest.mark.parametrize(("seed", "draw"), [(0, 1), (3, 0), (5, 0), (5, 1), (5, 2)])
def test_current_convention_eigenpair_is_sandwiched_by_its_gains_and_its_certificate(seed, draw):
    # the chains of the test above where the Perron eigenvector concentrates on the all-lost mode (the policy
    # iteration's P settles off a fixed point): lambda = min_K rho(L_K) lies between the Collatz-Wielandt bound of
    # its own P (every law's radius >= 1 + margin) and the radius of its own gains (markov.mjls's operator); both
    # within 1e-9 relative of lambda pin it down (a stalled power iteration leaves it 1e-5 off). The modes P
    # weighs at rounding level (trace <= 1e-12, some of them slightly negative) are dropped from the certificate:
    # what is left is PSD, so still a Collatz-Wielandt test matrix
    rng = np.random.default_rng(100 + seed)
    A = np.array([[1.0 + rng.uniform(0, 0.4), rng.uniform(-0.5, 0.5)], [0.0, rng.uniform(0.5, 1.3)]])
    B = rng.normal(size=(2, 2))
    chains = [GilbertElliott(p=rng.uniform(0.05, 0.6, 2), r=rng.uniform(0.05, 0.9, 2)) for _ in range(4)]
    lam, P, K = homogeneous_coupled_riccati(A, B, chains[draw], "current")
    weighed = np.trace(P, axis1=-2, axis2=-1) > 1e-12
    Q = np.where(weighed[:, None, None], P, 0.0)
    below = 1.0 + chain_certificate_margin(A, B, chains[draw], Q / np.trace(Q, axis1=-2, axis2=-1).sum(), "current")
    above = mjls_radius(A, B, chains[draw], K, "current")
    assert below <= above * (1 + 1e-12)
    assert lam == pytest.approx(below, rel=1e-9)
    assert lam == pytest.approx(above, rel=1e-9)

def _chain_at_an_end(k, everywhere=True):
    """The k-th of a seeded sequence of plants (n = 2..4, one or two channels) behind a chain at the end of its mean
    rate (0 or 1, the other channel's 0, 1 or 1/2; burstiness 0 .. 0.9): a transient state (p = 0 or r = 0), whose
    modes R's eigenvector vanishes on, and closed loops whose complex pairs give double roots on all matrices. The
    chain starts from a belief on every state, so the transient states are reachable (from the stationary start,
    ``everywhere=False``, they are not, and leave the mode chain)."""
    rng = np.random.default_rng(9)
    for _ in range(k + 1):
        n, m = int(rng.integers(2, 5)), int(rng.integers(1, 3))
        A = rng.normal(size=(n, n))
        A *= rng.uniform(0.9, 1.4) / max(abs(np.linalg.eigvals(A)))
        B = rng.normal(size=(n, m))
        corr = rng.uniform(0.0, 0.9, m)
        base = GilbertElliott(p=(1 - corr) / 2, r=(1 - corr) / 2)
        rate = rng.choice([0.0, 1.0, 0.5], size=m) if m > 1 else rng.choice([0.0, 1.0], size=1)
    chain = chain_at_rate(base, rate)
    return A, B, chain.with_belief(np.full((m, 2), 0.5)) if everywhere else chain, ("next", "current")[k % 2]


@pytest.mark.parametrize("k", [1, 2, 6, 8, 11, 46, 55, 56, 105])
def test_eigenpair_is_sandwiched_behind_chains_at_the_ends_of_their_mean_rates(k):
    """lambda = min_K rho(L_K) lies between the Collatz-Wielandt bound of its own P (every law's radius >= it) and the
    radius of its own gains (markov.mjls's operator on all matrices); both within 1e-9 of lambda pin it down, and the
    verdict follows. Chosen among 120 such chains where a step of the engine had mattered: the eigenvalue problem
    restricted to symmetric tuples (a complex pair's double root had made the eigenvector's error bound useless:
    34 of the 120 unpinned, 16 undecided), the unregularised policy steps from the cleaned eigenvector (5 unpinned,
    one undecided), the regularised power iteration (one)."""
    A, B, ch, delivery = _chain_at_an_end(k)
    lam, P, K = homogeneous_coupled_riccati(A, B, ch, delivery)
    weighed = np.trace(P, axis1=-2, axis2=-1) > 1e-12
    Q = np.where(weighed[:, None, None], P, 0.0)
    below = 1.0 + chain_certificate_margin(A, B, ch, Q / np.trace(Q, axis1=-2, axis2=-1).sum(), delivery)
    above = mjls_radius(A, B, ch, K, delivery)
    assert lam == pytest.approx(below, rel=1e-9)
    assert lam == pytest.approx(above, rel=1e-9)
    assert chain_membership(A, B, ch, delivery).verdict == ("stable" if lam < 1 else "unstable")


def test_no_sampled_mode_gains_beat_an_outside_certificate():
    A, B = np.array([[1.2, 0.3], [0.0, 1.1]]), np.array([[1.0, 0.0], [0.0, 1.0]])
    ch = GilbertElliott(p=[0.6, 0.6], r=[0.15, 0.15])
    found = chain_membership(A, B, ch)
    assert found.verdict == "unstable"
    rng = np.random.default_rng(0)
    for _ in range(200):
        K = rng.normal(scale=1.5, size=(4, 2, 2))
        assert mjls_radius(A, B, ch, K, "next") >= 1 - 1e-9


def test_chain_at_rate_keeps_burstiness_and_refuses_bad_rates():
    base = GilbertElliott(p=[0.1, 0.3], r=[0.2, 0.3], h_good=[1.0, 0.9], h_bad=[0.0, 0.1])
    ch = chain_at_rate(base, [0.4, 0.5])
    assert np.allclose(ch.correlation, base.correlation)
    assert np.allclose(ch.mean_rate, [0.4, 0.5])
    with pytest.raises(InputError, match="rate"):
        chain_at_rate(base, [0.4, 0.95])                  # above h_good of channel 2
    with pytest.raises(InputError, match="rate"):
        chain_at_rate(base, [0.4])


def test_rate_map_of_a_memoryless_chain_is_the_bernoulli_map(two_actuator):
    axis = np.linspace(0.0, 1.0, 6)
    stable, lam = chain_rate_map(two_actuator.A, two_actuator.B, GilbertElliott(p=[0.5, 0.5], r=[0.5, 0.5]), axis)
    for r, y in enumerate(axis):
        for c, x in enumerate(axis):
            ref = membership(two_actuator, [x, y], forms=("riccati",)).verdict
            assert stable[r, c] == (1.0 if ref == "stable" else 0.0)
    assert np.all(np.diff(stable, axis=1) >= 0)
    assert np.all(np.diff(stable, axis=0) >= 0)
    assert np.all((lam < 1) == (stable == 1.0))


@pytest.mark.parametrize(("a", "corr", "d"), [((1.5, 1.2), (0.2, 0.6), (1.0, 1.0)),
                                              ((2.0, 1.1), (0.0, 0.9), (1.0, 0.3)),
                                              ((1.3, 3.0), (0.5, 0.1), (0.0, 1.0))])
def test_critical_mean_rate_of_a_decoupled_plant_is_its_worst_channel(a, corr, d):
    """diag(a), B = I behind two Gilbert channels (h_good = 1, h_bad = 0) with burstiness lambda_i kept: block i is
    stabilisable iff r_i = rate_i (1 - lambda_i) > 1 - 1/a_i^2 (hand: deadbeat when good, x+ = a x when bad), so
    along rates t d the critical t is max_i (1 - 1/a_i^2) / ((1 - lambda_i) d_i) (inf past the ray's end
    min_i 1 / d_i); both ends carry their certificates, checked here by the coupled radius of sampled gains."""
    a, corr, d = np.array(a), np.array(corr), np.array(d)
    ch = chain_at_rate(GilbertElliott(p=(1 - corr) / 2, r=(1 - corr) / 2), [0.5, 0.5])
    s = System(A=np.diag(a), B=np.eye(2), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
               x0=[1.0, 1.0], channel=ch)
    point = chain_critical_rate(s, d)
    with np.errstate(divide="ignore"):
        exact = float(np.max(np.where(d > 0, (1 - 1 / a**2) / ((1 - corr) * d), np.where(a > 1, np.inf, 0.0))))
    end = float(np.min(1 / d[d > 0]))
    if exact >= end:
        assert point.t == np.inf
        assert point.outside.verdict == "unstable"
        return
    assert point.lower <= exact <= point.t <= point.lower + 1e-6
    assert point.inside.verdict == "stable"
    assert point.outside.verdict == "unstable"
    inside = chain_at_rate(ch, point.t * d)
    assert mjls_radius(s.A, s.B, inside, point.inside.gain, "next") < 1.0
    outside = chain_at_rate(ch, point.lower * d)
    rng = np.random.default_rng(0)
    for K in rng.normal(scale=2.0, size=(50, 4, 2, 2)):
        assert mjls_radius(s.A, s.B, outside, K, "next") >= 1 - 1e-9


def test_no_critical_mean_rate_where_monotonicity_is_not_proved():
    """h_bad > 0 or negative burstiness: outside the thinning proof (docs/mathematics.md), so no bisection; the guard
    planted off, the bisection answers here (the test fails)."""
    for ch in (GilbertElliott(p=[0.1], r=[0.3], h_good=[0.9], h_bad=[0.2]), GilbertElliott(p=[0.6], r=[0.7])):
        s = System(A=[[1.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0], channel=ch)
        assert critical_rate_unproved(ch) is not None
        with pytest.raises(InputError, match="h_bad = 0 and burstiness >= 0"):
            chain_critical_rate(s)


@pytest.mark.parametrize(("P", "delivery", "expected"), [((0.5, 0.5), "next", 0.2), ((0.9, 0.1), "next", 0.4 / 3 - 1),
                                                        ((0.0, 1.0), "next", 2.2), ((0.0, 1.0), "current", 2.2),
                                                        ((0.5, 0.5), "current", -1.0)])
def test_chain_certificate_margin_is_the_radius_bound_by_hand(P, delivery, expected):
    """One state a = 2 behind a Gilbert channel (p = 0.3, r = 0.2; modes good, bad), P = (p_g, p_b). "next": the law
    in mode a is deadbeat when the next state is good, so R(P)_good = p a^2 p_b and R(P)_bad = (1 - r) a^2 p_b;
    "current": R(P)_good = 0 (delivered now), R(P)_bad = a^2 (r p_g + (1 - r) p_b). The margin is
    min_a R(P)_a / P_a - 1 over the modes P weighs (hand). The check before (T_a's least eigenvalue over its scale)
    gives other numbers (planted: fails)."""
    ch = GilbertElliott(p=[0.3], r=[0.2])
    P = np.array(P)[:, None, None]
    margin = chain_certificate_margin(np.array([[2.0]]), np.array([[1.0]]), ch, P, delivery)
    assert margin == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(("a", "p", "r"), [
    ([1.0081973392691654, 1.6570049780089249, 1.2145586912876247], [0.528405766277057, 0.1964285046745779],
     [0.5977019058914226, 0.5906309904931722]),
    ([1.2124664594314019, 1.8375938704985586, 1.6428041510616023], [0.27899003775333686, 0.2775204509256364],
     [0.7651880185776133, 0.2345712165067831]),
])
def test_current_convention_eigenvalue_of_a_plant_with_a_mode_no_channel_actuates(a, p, r):
    # decoupled, B the first two columns of I, by hand: state 3 evolves as x3' = a3 x3 under every law, radius
    # a3^2; state i = 1, 2 at best deadbeat while its channel is good (delivered), a_i x_i while bad, so its least
    # radius is a_i^2 P(bad -> bad) = a_i^2 (1 - r_i); lambda = min over laws = the largest of the three (a3^2
    # here), >= 1: unstable. (The policy steps' gains wander to 1e18-1e32 on state 3; they once gave 0.82 for 1.475)
    A, B = np.diag(a), np.eye(3)[:, :2]
    chain = GilbertElliott(p=p, r=r)
    lam, _, _ = homogeneous_coupled_riccati(A, B, chain, "current")
    assert lam == pytest.approx(max(a[2] ** 2, *(a[i] ** 2 * (1 - r[i]) for i in range(2))), rel=1e-9)
    assert chain_membership(A, B, chain, "current").verdict == "unstable"


@pytest.mark.parametrize(("a", "p", "r"), [
    ([1.3941867660288976, 1.992023228581445], [0.5580599465563497, 0.13360434638739538],
     [0.492470444487148, 0.5721613295775925]),
    ([1.1713572524069735, 1.4945801644671766], [0.24676147676492927, 0.5075901237429848],
     [0.40193063229018183, 0.466062275332867]),
])
def test_current_convention_decoupled_plant_outside_is_proved_unstable(a, p, r):
    # decoupled, B = I, by hand: state i at best deadbeat while its channel is good, a_i x_i while bad, least
    # radius a_i^2 (1 - r_i) > 1 here for state 2 (1.698 and 1.193): unstable. The settled policy steps' P gives no
    # outside certificate that checks; the power iteration's P proves it (8 of 400 such draws; 1bc1ef6 decided them)
    A, B = np.diag(a), np.eye(2)
    chain = GilbertElliott(p=p, r=r)
    assert max(a[i] ** 2 * (1 - r[i]) for i in range(2)) > 1.19
    found = chain_membership(A, B, chain, "current")
    assert found.verdict == "unstable"
    assert found.certificate is not None


def _proved_or_undecided(found, A, B, ch, delivery, hand):
    """The verdict on a plant whose part no input reaches is hidden by a rotation: the split's couplings are
    rounding, not zero, in the plant as stored, so lambda (hand) is the least radius of the plant with them set to
    zero, and "unstable" is reported only with a certificate that proves every law's radius >= 1 + margin in exact
    arithmetic on the plant as stored (margin >= -CERTIFICATE_RTOL, and no more than the hand value); otherwise
    "undecided" with the reason. Never "stable"."""
    assert found.verdict in ("unstable", "undecided")
    if found.verdict == "undecided":
        assert "exact check" in found.reason
        return
    assert -CERTIFICATE_RTOL <= found.certificate_margin <= (hand - 1) + 1e-12 * hand
    assert chain_outside_proved(A, B, ch, found.certificate, 1.0 + found.certificate_margin, delivery)


def _coupled_plant(a_c, a_u, coupling):
    """x_u drives x_c (coupling), one input reaches x_c only: T'AT = [[a_c, coupling], [0, a_u]], T'B = [[1], [0]]."""
    return np.array([[a_c, coupling], [0.0, a_u]]), np.array([[1.0], [0.0]])


def _rotation(seed, n):
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(n, n)))
    return q * np.sign(np.diag(r))


@pytest.mark.parametrize("delivery", ["next", "current"])
@pytest.mark.parametrize(("a_c", "a_u", "r", "verdict"), [
    (2.0, 1.5, 0.6, "unstable"),       # x_u dominates: rho(A_uu)^2 = 2.25 > a_c^2 (1 - r) = 1.6
    (2.0, 0.9, 0.6, "unstable"),       # the reached part dominates: 1.6 > 0.81, the part no input reaches is stable
    (2.0, 0.9, 0.9, "stable"),         # both below 1: 0.4 and 0.81
    (1.5, 1.02, 0.7, "unstable"),      # barely: 1.0404 > 0.675
])
@pytest.mark.parametrize("rotated", [False, True])
def test_least_radius_with_a_part_no_input_reaches_is_the_larger_of_the_two_radii(a_c, a_u, r, verdict, delivery,
                                                                                rotated):
    """By hand: x_u+ = a_u x_u under every law (no input reaches it), so its second moment grows by a_u^2 whatever
    the gains; x_c behind one Gilbert channel is at best deadbeat when delivered and a_c x_c + x_u when lost, so with
    x_u = 0 its least radius is a_c^2 (1 - r) (module docstring), and x_u only feeds it a decaying input. The least
    radius is the larger of a_u^2 and a_c^2 (1 - r), under both conventions, in the split's coordinates and in any
    others (``rotated``: Q A Q', Q B for a random orthogonal Q, so no entry of B is zero and the part no input
    reaches is found only by the staircase). The verdict's certificate is proved in exact arithmetic, at most 1e-6
    below the hand value, and checked by 200 sampled mode gains, none of which beats it; the returned gains attain
    lambda. Rotated, the couplings the split drops are rounding in the plant as stored: "unstable" only where an
    exact certificate survives, else "undecided" (`_proved_or_undecided`)."""
    A, B = _coupled_plant(a_c, a_u, 0.7)
    if rotated:
        Q = _rotation(3, 2)
        A, B = Q @ A @ Q.T, Q @ B
    ch = GilbertElliott(p=[0.3], r=[r])
    hand = max(a_u**2, a_c**2 * (1 - r))
    lam, P, K = homogeneous_coupled_riccati(A, B, ch, delivery)
    assert lam == pytest.approx(hand, rel=1e-12)
    assert mjls_radius(A, B, ch, K, delivery) == pytest.approx(hand, rel=1e-9)
    found = chain_membership(A, B, ch, delivery)
    rng = np.random.default_rng(7)
    if rotated and verdict == "unstable":
        _proved_or_undecided(found, A, B, ch, delivery, hand)
    else:
        assert found.verdict == verdict
    if verdict == "stable":
        assert mjls_radius(A, B, ch, found.gain, delivery) < 1
        return
    if not rotated:    # proved exactly, and sharp: chain_outside's largest lowering (1e-6) of a float bound within
        # the regularisation (1e-10) of the hand value
        assert chain_outside_proved(A, B, ch, found.certificate, 1.0 + found.certificate_margin, delivery)
        assert hand * (1 - 1e-6 - 1e-10) <= 1.0 + found.certificate_margin <= hand
    for gains in rng.normal(scale=3.0, size=(200, 2, 1, 2)):
        assert mjls_radius(A, B, ch, gains, delivery) >= 1


@pytest.mark.parametrize("seed", range(4))
def test_least_radius_of_a_decoupled_plant_hidden_by_a_rotation_is_its_largest_block(seed):
    """diag(a) with B the first two columns of I behind two Gilbert channels ("current"), seen through a random
    orthogonal Q: by hand, lambda = max(a_3^2, a_i^2 (1 - r_i)) (tests above), whatever Q. The mode no channel
    actuates is found by the staircase only to rounding (B's third row in the split's coordinates is about 1e-16),
    and a gain of 1e16 on it would fool a solver that takes rounding for an input. The verdict: proved exactly on the
    plant as stored, or undecided (`_proved_or_undecided`)."""
    rng = np.random.default_rng(200 + seed)
    a = rng.uniform(1.0, 1.9, 3)
    chain = GilbertElliott(p=rng.uniform(0.1, 0.6, 2), r=rng.uniform(0.2, 0.8, 2))
    Q = _rotation(seed, 3)
    A, B = Q @ np.diag(a) @ Q.T, Q @ np.eye(3)[:, :2]
    hand = max(a[2] ** 2, *(a[i] ** 2 * (1 - chain.r[i]) for i in range(2)))
    lam, P, K = homogeneous_coupled_riccati(A, B, chain, "current")
    assert lam == pytest.approx(hand, rel=1e-9)
    assert np.abs(K).max() < 10 * a.max()
    found = chain_membership(A, B, chain, "current")
    assert hand >= 1
    _proved_or_undecided(found, A, B, chain, "current", hand)


@pytest.mark.parametrize("seed", range(24))
def test_a_dominant_part_no_input_reaches_gives_its_radius_exactly_in_any_coordinates(seed):
    """Random plants with a planted part no input reaches (n = 3..5, one or two channels, up to n - m such modes)
    coupled into the reached part, its largest |a_u| above every |a_c|, seen through a random orthogonal Q (no
    entry of B is zero): by hand, lambda = max a_u^2 (it bounds the reached part's least radius, at most
    rho(A_cc)^2 = max a_c^2), and every law's radius is at least that (the certificate, exact). Without the
    controllability split the engine wandered on about one plant in ten (lambda 1.4505 for 1.4671, 1.6489 for
    1.6910; two undecided), its gains on the rotated unreached modes fed by rounding couplings. The verdict: proved
    exactly on the plant as stored, or undecided (`_proved_or_undecided`)."""
    rng = np.random.default_rng(2000 + seed)
    n, m = int(rng.integers(3, 6)), int(rng.integers(1, 3))
    nu = int(rng.integers(1, n - m + 1))
    a_c = rng.uniform(0.5, 1.5, n - nu)
    a_u = rng.uniform(1.0, 1.3, nu) * max(a_c.max(), 0.9)
    Ad = np.diag(np.concatenate([a_c, a_u]))
    Ad[: n - nu, n - nu:] = rng.normal(size=(n - nu, nu))
    Bd = np.zeros((n, m))
    Bd[: n - nu] = rng.normal(size=(n - nu, m))
    q, r = np.linalg.qr(rng.normal(size=(n, n)))
    Q = q * np.sign(np.diag(r))
    A, B = Q @ Ad @ Q.T, Q @ Bd
    ch = GilbertElliott(p=rng.uniform(0.1, 0.6, m), r=rng.uniform(0.2, 0.8, m))
    delivery = ("next", "current")[seed % 2]
    hand = float(np.max(a_u)) ** 2
    lam, P, K = homogeneous_coupled_riccati(A, B, ch, delivery)
    assert lam == pytest.approx(hand, rel=1e-9)
    found = chain_membership(A, B, ch, delivery)
    _proved_or_undecided(found, A, B, ch, delivery, hand)


def test_a_channel_that_never_delivers_actuates_nothing():
    """h_good = h_bad = 0 on channel 2: its column of B never acts, so x2+ = 1.2 x2 under every law (hand: lambda =
    max(1.2^2, 1.5^2 (1 - r_1)) = 1.44), decided structurally; the gains on x2 stay 0 (they were 3e15 when the
    Hessians of rounding were inverted) and the certificate is exact."""
    A, B = np.diag([1.5, 1.2]), np.eye(2)
    ch = GilbertElliott(p=[0.4, 0.2], r=[0.4, 0.3], h_good=[1.0, 0.0])
    for delivery in ("next", "current"):
        lam, P, K = homogeneous_coupled_riccati(A, B, ch, delivery)
        assert lam == pytest.approx(1.44, rel=1e-12)
        assert np.abs(K).max() <= 1.5 * (1 + 1e-9)
        found = chain_membership(A, B, ch, delivery)
        assert found.verdict == "unstable"
        assert found.certificate_margin == pytest.approx(0.44, rel=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_least_radius_is_zero_where_every_chain_path_can_be_driven_to_zero(seed):
    """A chain that is good at every step after the first (p = 0, r = 1) delivers every packet from then on, so a
    controllable plant can be driven to zero in n steps (pole placement at 0; the first, lost step changes
    nothing): the least radius is exactly 0 (R^j(I) = 0, detected), not the 1e-9 .. 1e-3 that the radius of gains
    near deadbeat has in floating point (a nilpotent loop's eigenvalues move by eps^(1/n)); the gains returned
    stabilise."""
    rng = np.random.default_rng(300 + seed)
    n, m = 2 + seed % 3, 1 + seed % 2
    A = rng.normal(size=(n, n)) * 1.5
    B = rng.normal(size=(n, m))
    ch = GilbertElliott(p=[0.0] * m, r=[1.0] * m)
    for delivery in ("next", "current"):
        lam, P, K = homogeneous_coupled_riccati(A, B, ch, delivery)
        assert lam == 0.0
        assert mjls_radius(A, B, ch, K, delivery) < 1 - MEAN_SQUARE_MARGIN
        assert chain_membership(A, B, ch, delivery).verdict == "stable"


def test_pendulum_bursty_at_the_ends_of_its_mean_rate():
    """pendulum_bursty's chain at burstiness 0.8: at mean rate 1 the good state is absorbing (p = 0) and the bad one
    transient, lost with probability 1 - r = 0.8 each step it lasts: the least radius is 0.8 rho(A)^2 (by hand: the
    single input is controllable, so the good state's loop can be made as fast as wanted; the bad state's is A);
    at mean rate 0 the bad state is absorbing and nothing is ever delivered: rho(A)^2. Under some kernels the
    first was "undecided" (lambda 0.9014, far from 1: gains of the transient state taken from a P that vanishes
    there). The chain starts in the transient state (bad at rate 1, good at rate 0): from the stationary law it would
    never be met (test_pendulum_bursty_from_its_stationary_law_at_rate_1)."""
    s = pl_load("pendulum_bursty")
    rho2 = float(np.max(np.abs(np.linalg.eigvals(s.A)))) ** 2
    for rate, hand, verdict in ((1.0, 0.8 * rho2, "stable"), (0.0, rho2, "unstable")):
        ch = chain_at_rate(s.channel, [rate]).with_belief([[1.0 - rate, rate]])
        lam, P, K = homogeneous_coupled_riccati(s.A, s.B, ch)
        assert lam == pytest.approx(hand, rel=1e-9)
        found = chain_membership(s.A, s.B, ch)
        assert found.verdict == verdict
        if verdict == "stable":
            assert mjls_radius(s.A, s.B, ch, found.gain, "next") < 1
        else:      # the certificate proves every law's radius >= 1 + margin >= 1 - CERTIFICATE_RTOL, exactly
            assert found.certificate_margin >= -CERTIFICATE_RTOL
            assert chain_outside_proved(s.A, s.B, ch, found.certificate, 1.0 + found.certificate_margin)


def test_pendulum_bursty_from_its_stationary_law_at_rate_1():
    """At mean rate 1 from the stationary law (good for ever) every packet arrives: the single input is controllable,
    so a deadbeat law exists and the least radius is 0 (the transient bad state, whose 0.8 rho(A)^2 decided the
    previous test, is never met)."""
    s = pl_load("pendulum_bursty")
    ch = chain_at_rate(s.channel, [1.0])
    lam, _, K = homogeneous_coupled_riccati(s.A, s.B, ch)
    assert lam == 0.0
    found = chain_membership(s.A, s.B, ch)
    assert found.verdict == "stable"
    assert mjls_radius(s.A, s.B, ch, found.gain, "next") < 1 - MEAN_SQUARE_MARGIN


def test_a_failed_linear_algebra_routine_is_a_numerical_error(monkeypatch):
    """numpy.linalg.LinAlgError (an SVD or eigenvalue routine that did not converge) from inside the engine reaches
    the caller as NumericalError naming the computation, never as a verdict or an untyped error."""
    def fail(*args, **kwargs):
        raise np.linalg.LinAlgError("SVD did not converge")

    A, B = np.array([[2.0]]), np.array([[1.0]])
    ch = GilbertElliott(p=[0.3], r=[0.6])
    monkeypatch.setattr(np.linalg, "svd", fail)
    with pytest.raises(NumericalError, match="linear-algebra routine failed"):
        chain_membership(A, B, ch)
    with pytest.raises(NumericalError, match="linear-algebra routine failed"):
        homogeneous_coupled_riccati(A, B, ch)
    monkeypatch.setattr(np.linalg, "eigvals", fail)
    with pytest.raises(NumericalError, match="eigenvalue routine failed"):
        mjls_radius(A, B, ch, np.ones((2, 1, 1)), "next")


def test_a_float_bound_that_rounding_fools_is_no_verdict(monkeypatch):
    """A chain of four integrators behind a memoryless chain whose states deliver alike (h = 0.0124 in both): every
    mode's T_c(P) is Bernoulli(0.0124)'s, and the mode-independent law K below has coupled radius 0.9975
    (markov.mjls's dense operator, and the delivery patterns enumerated: tests/references.py), so no verdict
    "unstable" is true. The unbalanced Bernoulli eigenvector (region._GRADED = 0) put on both modes, cut at
    1e-12, has a float Collatz–Wielandt bound of 1.00066 (> 1: rounding of a graded P, eigenvalues 1 .. 4e-14);
    the exact check refuses it, so chain_outside gives no certificate and the membership built on it is
    "undecided" with the reason. Planted (the float bound taken as the verdict, as before): "unstable" (fails)."""
    from packetloss_cvx.closedloop import markov_region, region
    from packetloss_cvx.closedloop.markov_region import chain_outside
    from packetloss_cvx.closedloop.riccati_map import cut_candidates

    from ..references import enumerated_radius

    A, B, mu = np.eye(4) + np.eye(4, k=1), np.eye(4)[:, 3:], np.array([0.0124])
    ch = GilbertElliott(p=[0.5], r=[0.5], h_good=mu, h_bad=mu)
    K = np.array([[4.888e-9, 6.896e-6, 4.1397e-3, 1.00413]])
    assert enumerated_radius(A, B, K, mu) == pytest.approx(0.99750, abs=1e-5)
    for delivery in ("next", "current"):
        assert mjls_radius(A, B, ch, np.repeat(K[None], 2, axis=0), delivery) == pytest.approx(0.99750, abs=1e-5)
    monkeypatch.setattr(region, "_GRADED", 0.0)
    lam, P, _ = region.homogeneous_riccati(A, B, mu)
    monkeypatch.undo()
    P2 = np.repeat(P[None] / (2 * np.trace(P)), 2, axis=0)
    assert lam > 1.0
    fooled = max(chain_certificate_margin(A, B, ch, Q, "next") for Q in [P2, *cut_candidates(P2)])
    # the float bound of P or a cut of it (chain_outside's candidates) is fooled by the rounding of some kernels
    # (1.00066 under Haswell; -1, not fooled, under Prescott); what must hold everywhere is the exact check's refusal
    assert fooled > 1e-4 or os.environ.get("OPENBLAS_CORETYPE", "").lower() not in ("", "haswell")
    margin, certificate = chain_outside(A, B, ch, P2, "next")
    assert certificate is None
    monkeypatch.setattr(markov_region, "homogeneous_coupled_riccati", lambda *args: (lam, P2, np.zeros((2, 1, 4))))
    found = chain_membership(A, B, ch)
    assert found.verdict == "undecided"
    # the reason names what failed: the exact check where the float bound was fooled, else the float bound itself
    assert ("exact check" if fooled > 1e-4 else "certificate proves only") in found.reason


@pytest.mark.parametrize(("a0", "mu"), [(1.0, 0.0124), (1.001, 0.002), (1.001, 0.0079), (1.001, 0.0186),
                                        (1.3, 0.5)])
def test_one_mode_and_memoryless_chains_give_the_bernoulli_least_radius_of_a_jordan_chain(a0, mu):
    """Bernoulli losses are the one-mode chain, and a memoryless chain whose states deliver alike (p + r = 1,
    h_good = h_bad = mu) is Bernoulli(mu) under either convention: behind each, one Jordan block of size 4 driven at
    its last state has the least radius of Elia's single-input theorem, a0^2 (1 - mu)^(1/4) (hand,
    tests/closedloop/test_region.py), which the Bernoulli engine (region.homogeneous_riccati) meets. The chain
    engine agrees with both within MEAN_SQUARE_MARGIN, as the Bernoulli engine with the hand value. Its eigenvector
    is graded (diagonal 4e-14 .. 1): without the balancing the two engines share (riccati_map.grading_scale,
    planted to None in chain_radius) it was 5.6e-3 above (1.0023 for 0.99689; fails)."""
    from packetloss_cvx.closedloop.region import homogeneous_riccati
    from packetloss_cvx.model.channel import MarkovChannel

    from ..plants import chain

    s = chain(a0)
    A, B = np.asarray(s.A, float), np.asarray(s.B, float)
    hand = a0 ** 2 * (1 - mu) ** 0.25
    bernoulli = homogeneous_riccati(A, B, np.array([mu]))[0]
    assert bernoulli == pytest.approx(hand, rel=MEAN_SQUARE_MARGIN)
    memoryless = GilbertElliott(p=[0.5], r=[0.5], h_good=[mu], h_bad=[mu])
    for ch, delivery in ((MarkovChannel(transition=[[[1.0]]], delivery=[[mu]]), "next"), (memoryless, "next"),
                         (memoryless, "current")):
        lam = homogeneous_coupled_riccati(A, B, ch, delivery)[0]
        assert lam == pytest.approx(hand, rel=MEAN_SQUARE_MARGIN)
        assert lam == pytest.approx(bernoulli, rel=MEAN_SQUARE_MARGIN)
