"""The stabilisable set behind Gilbert–Elliott channels: can some mode-dependent linear law
``u = -K_a x`` (a the channel state the law knows: the last one, or the current one) make the loop mean-square
stable, and where, over each channel's mean rate at fixed burstiness?

With ``E_a = sum_b T_ab P_b`` (T the mode chain, h_a the per-mode delivery probabilities) the adjoint of the
coupled second-moment map of gains K is the quadratic ``L_K^*(P)_a = A'E_aA - 2 A'F_a K_a + K_a' H_a K_a``:
with the deliveries following the next mode b ("next", the default: the law knows the last state, as a TCP-like
acknowledgement of a Gilbert channel reveals it) ``F_a = sum_b T_ab P_b B H_b`` and ``H_a = sum_b T_ab (H_b B'P_bB
H_b + diag(h_b (1 - h_b)) ∘ B'P_bB)``; following the current mode a ("current": the law knows the state that
decides this step's deliveries) the same with h_a in place of h_b (H_b = diag(h_b); markov.mjls's two
conventions). As for Bernoulli losses (simulation.region) two certificates, each checked in numpy by the operator
it speaks about:

- **inside**: mode gains K whose coupled map has radius ``< 1 - MEAN_SQUARE_MARGIN`` (mjls.mean_square_radius);
- **outside**: ``P_a >= 0``, ``sum_a tr P_a = 1``, with, for every mode a,

  .. math:: T_a(P) = \\begin{bmatrix} A'E_aA - P_a & -A'F_a \\\\ -F_a'A & H_a \\end{bmatrix} \\succeq 0,

  i.e. ``L_K^*(P) >= P`` for every K (``x'(L_K^*(P)_a - P_a)x = [x; K_a x]' T_a(P) [x; K_a x]``), so
  ``<P, L_K^j(Q)> >= <P, Q> > 0`` for Q > 0 and every j: no mode-dependent law is mean-square stabilising.

Both come from the homogeneous coupled Riccati map ``R(P)_a = min_K L_K^*(P)_a``, monotone, concave and
positively homogeneous on the PSD cone, whose eigenvalue ``R(P) = lambda P`` is lambda = min_K rho(L_K), the least
mean-square radius (simulation.chain_radius: the part no input reaches decided structurally, no gain that
diverges). A certificate that does not check is "undecided", never "unstable".

A memoryless chain (p + r = 1) is in state good with probability r at every step, independently of the past,
so under "next" it delivers Bernoulli(r h_good + p h_bad) unknown to the law and its set is S at that mean rate
(tested; under "current" the law knows which packets will arrive, and the set is larger); one state and a
Gilbert channel (h_good = 1, h_bad = 0): the deadbeat gain in the good state leaves ``x+ = a x`` in the bad one,
radius ``a^2 (1 - r)``, so the loop is stabilisable iff ``r > 1 - 1/a^2`` whatever p (tested).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..display import supported_digits
from ..errors import InputError, NumericalError
from ..linalg import typed_linalg
from ..model.chain import mode_chain
from ..model.channel import GilbertElliott, MarkovChannel, gilbert_rates
from ..results.region import CriticalPoint, Membership
from ..tolerances import CERTIFICATE_RTOL, CRITICAL_MU_TOL, MEAN_SQUARE_MARGIN
from .certificates import chain_proved_certificate
from .chain_radius import chain_certificate_margin, check_delivery, homogeneous_coupled_riccati
from .critical import critical_point
from .mjls import mean_square_radius as mjls_radius
from .riccati_map import cut_candidates, unreached_stein
from .stability import is_mean_square_stable

#: where a candidate proves ``1 - CERTIFICATE_RTOL`` (the verdict), `chain_outside` tries the float bound lowered by
#: these (relative), in turn, for the sharpest margin it proves: its own rounding on a well-conditioned plant (1.2^2 as
#: a double's exact square is 0.23 eps below the double 1.44), so a hand value keeps its digits; CERTIFICATE_RTOL;
#: then steps down to the regularised eigenvector's distance from R's and beyond (chain_radius:
#: COUPLED_POLICY_REGULARISATION = 1e-10 of lambda; a rank-one eigenvector, [[2, 0.7], [0, 0.9]] behind p = 0.3,
#: r = 0.6, proves 1.6 (1 - 1e-6), not 1.6 (1 - 1e-8))
_LOWERINGS = (16 * np.finfo(float).eps, CERTIFICATE_RTOL, 1e-10, 1e-8, 1e-6)

__all__ = ["chain_at_rate", "chain_certificate_margin", "chain_critical_rate", "chain_least_radius", "chain_membership",
           "chain_outside", "chain_rate_map",
           "critical_rate_unproved", "homogeneous_coupled_riccati"]

@typed_linalg("the chain's outside certificate")
def chain_outside(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, P: np.ndarray, delivery: str,
                  gains: np.ndarray | None = None) -> tuple[float, np.ndarray | None]:
    """``(margin, certificate)``: a certificate that proves every mode-dependent law's radius at least ``1 + margin
    >= 1 - CERTIFICATE_RTOL`` in exact arithmetic (certificates.chain_proved_certificate: the candidate itself,
    snapped or tilted), else ``(the largest float margin of the candidates, None)``. The candidates: P (normalised to
    ``sum_a tr P_a = 1``), then P with its eigenvalues below riccati_map.CUTS (1e-12, 1e-9, 1e-6) of the largest
    (over all modes) cut off (riccati_map.cut_candidates: an eigenvector leaves rounding weight on modes and blocks
    of smaller radius); each whose float margin (`chain_certificate_margin`) is ``>= -CERTIFICATE_RTOL`` is checked
    exactly at ``c = 1 - CERTIFICATE_RTOL`` (the verdict) and, where that holds, at ``c = (1 + margin)`` lowered by
    each of `_LOWERINGS` (relative) in turn for the sharpest margin it proves; last, the Stein certificate of a part
    no delivering input reaches (riccati_map.unreached_stein, one P for every mode), as for Bernoulli losses
    (region.membership). ``gains``: the mode gains that minimise at P, for the closed-loop tilt of the exact check.
    A float margin alone is never a verdict: on an ill-conditioned plant its rounding exceeds
    the band (a chain of four integrators behind a memoryless chain at rate 0.0124: float margin +6.6e-4 for a P
    that no exact check confirms, where a law of radius 0.9975 exists). Time O(4 chain margins) plus O(M^2 (n +
    m)^3) integer operations an exact try.
    """
    P = P / max(float(sum(np.trace(p) for p in P)), np.finfo(float).tiny)
    best = float("-inf")
    for Q in [P, *cut_candidates(0.5 * (P + P.transpose(0, 2, 1)))]:
        margin = chain_certificate_margin(A, B, channel, Q, delivery)
        best = max(best, margin)
        if not margin >= -CERTIFICATE_RTOL:
            continue
        floor = 1.0 - CERTIFICATE_RTOL
        proved = chain_proved_certificate(A, B, channel, Q, floor, delivery, gains)
        if proved is None:
            continue
        for c in [(1.0 + margin) * (1.0 - low) for low in _LOWERINGS]:    # the sharpest bound Q proves
            if c > floor:
                sharper = chain_proved_certificate(A, B, channel, Q, c, delivery, gains)
                if sharper is not None:
                    return c - 1.0, sharper
        return floor - 1.0, proved
    M = len(P)
    for c, Pu in unreached_stein(A, B, np.any(mode_chain(channel)[2] > 0, axis=0)):
        proved = chain_proved_certificate(A, B, channel, np.repeat(Pu[None] / M, M, axis=0), c, delivery)
        if proved is not None:
            return c - 1.0, proved
    return best, None


def chain_membership(A: npt.ArrayLike, B: npt.ArrayLike, channel: MarkovChannel, delivery: str = "next"
                     ) -> Membership:
    """Can some mode-dependent linear law make the loop behind ``channel`` mean-square stable? ``delivery`` as
    markov.mjls: "next" (default; the law knows the last state, as a TCP-like acknowledgement reveals it, the
    deliveries follow the state the chain moves to) or "current" (the law knows the state that decides this
    step's deliveries). A Membership: "stable" with the mode gains (M, m, n) and their coupled radius, "unstable"
    with P (M, n, n) and its margin, or "undecided" with the reason (the gains' radius and the certificate's bound
    bracket 1: near the boundary). ``mu`` holds the channel's mean rates. Time as
    `homogeneous_coupled_riccati` plus one coupled radius (O((M n^2)^3) dense).

    Raises
    ------
    InputError
        Not a Gilbert–Elliott channel, or not one channel per column of B.
    NumericalError
        A linear-algebra routine failed (never a verdict).

    Examples
    --------
    >>> a, b = np.array([[2.0]]), np.array([[1.0]])      # one state a = 2: iff r > 3/4, whatever p
    >>> [chain_membership(a, b, GilbertElliott(p=[0.4], r=[r])).verdict for r in (0.7, 0.8)]
    ['unstable', 'stable']
    """
    return _membership(np.asarray(A, dtype=float), np.asarray(B, dtype=float), channel, delivery)[0]


def chain_least_radius(A: npt.ArrayLike, B: npt.ArrayLike, channel: MarkovChannel, delivery: str = "next"
                       ) -> tuple[Membership, float, float]:
    """``(membership, lambda, error)``: `chain_membership`, the least radius lambda behind it
    (`homogeneous_coupled_riccati`, computed once for both) and lambda's own accuracy estimate: its distance to
    the coupled radius of its own gains computed by another eigenvalue routine (markov.mjls's operator on all
    matrices; lambda claims to be that radius). 0.0 where lambda is exactly 0 (every chain path driven to zero,
    detected structurally); nan where the gains' radius cannot be computed. On 312 of 313 seeded chains the two agree
    within 1e-9 of lambda; a defective root (a Jordan block of the coupled map, known only to about eps^(1/k)) leaves
    them 6e-6 apart on the other: a caller prints only the digits ``error`` supports. Time as
    `chain_membership` plus one coupled radius.

    Examples
    --------
    >>> found, lam, error = chain_least_radius(np.array([[2.0]]), np.array([[1.0]]), GilbertElliott(p=[0.4], r=[0.8]))
    >>> found.verdict, round(lam, 12), error < 1e-12            # a^2 (1 - r) = 0.8: deadbeat when good
    ('stable', 0.8, True)
    """
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    found, lam, K, radius = _membership(A, B, channel, delivery)
    if lam == 0.0:
        return found, lam, 0.0
    if np.isnan(radius) and np.all(np.isfinite(K)):
        try:
            radius = mjls_radius(A, B, channel, K, delivery)
        except NumericalError:
            radius = float("nan")
    return found, lam, abs(lam - radius)


@typed_linalg("the chain membership")
def _membership(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, delivery: str
                ) -> tuple[Membership, float, np.ndarray, float]:
    """`chain_membership`, the least radius lambda behind it, its gains K and their coupled radius where it was
    computed (nan otherwise): "stable" where the eigenpair's gains have a coupled radius below ``1 -
    MEAN_SQUARE_MARGIN`` (markov.mjls, on the plant as given), "unstable" where its P (or a cut of it,
    `chain_outside`) proves every law's radius ``>= 1 - CERTIFICATE_RTOL`` in exact arithmetic; else "undecided" with
    both
    numbers. Time as `chain_membership`."""
    check_delivery(delivery)
    if not isinstance(channel, MarkovChannel) or not channel.two_state:
        found = (f"channels of {', '.join(map(str, channel.sizes))} states" if isinstance(channel, MarkovChannel)
                 else f"{type(channel).__name__}")
        raise InputError("channel", f"the stabilisable set behind a chain is computed for two-state "
                                    f"(Gilbert-Elliott) channels, found {found}: solve and simulate give this "
                                    f"chain's costs and loops; region takes --mu for Bernoulli links")
    if channel.m != B.shape[1]:
        raise InputError("channel", f"expected {B.shape[1]} channels (the columns of B), found {channel.m}")
    lam, P, K = homogeneous_coupled_riccati(A, B, channel, delivery)
    rates = channel.mean_rate
    form = f"coupled-riccati ({delivery})"
    radius = float("nan")
    if not np.isfinite(lam):
        reason = f"the coupled Riccati eigenvalue is not finite ({lam})"
    elif lam < 1.0:
        try:
            radius = mjls_radius(A, B, channel, K, delivery)
        except NumericalError as err:
            radius, why = float("nan"), f" ({err})"
        else:
            why = ""
        if is_mean_square_stable(radius):
            return Membership(rates, "stable", K, radius, None, float("nan"), ((form, "stable"),)), lam, K, radius
        shown = supported_digits(lam, abs(lam - radius), 12) if np.isfinite(radius) else 6
        reason = (f"lambda = {lam:.{shown}g} < 1, but its gains' coupled radius {radius:.{shown}g}{why} is not below "
                  f"1 - {MEAN_SQUARE_MARGIN:g}")
    else:
        margin, certificate = chain_outside(A, B, channel, P, delivery, K)
        if certificate is not None:
            return (Membership(rates, "unstable", None, float("nan"), certificate, margin, ((form, "unstable"),)),
                    lam, K, radius)
        if margin >= -CERTIFICATE_RTOL:
            reason = (f"lambda = {lam:.6g} >= 1 (its accuracy not estimated); its certificate's float bound says every "
                      f"law's radius is >= {1.0 + margin:.12g}, but no candidate survives the exact check (the "
                      "rounding of the float bound exceeds its margin)")
        else:
            reason = (f"lambda = {lam:.6g} >= 1 (its accuracy not estimated), but its certificate proves only that "
                      f"every law's radius is >= {1.0 + margin:.12g}, short of 1 - {CERTIFICATE_RTOL:g}")
    return (Membership(rates, "undecided", None, float("nan"), None, float("nan"), ((form, "undecided"),), reason),
            lam, K, radius)


def chain_at_rate(channel: MarkovChannel, rate: npt.ArrayLike) -> MarkovChannel:
    """The Gilbert–Elliott channel with each channel's mean delivery rate ``rate_i`` and the same burstiness
    (correlation ``lambda_i = 1 - p_i - r_i``) and state delivery probabilities. The stationary P(good) is
    ``g_i = (rate_i - h_bad_i) / (h_good_i - h_bad_i)``, so ``r_i = g_i (1 - lambda_i)``, ``p_i = (1 - g_i)
    (1 - lambda_i)``. O(m).

    Raises
    ------
    InputError
        A rate outside [h_bad_i, h_good_i], or a chain that never moves (lambda_i = 1).

    Examples
    --------
    >>> ch = chain_at_rate(GilbertElliott(p=[0.1], r=[0.3]), [0.5])      # lambda = 0.6 kept
    >>> [round(float(v), 12) for v in (ch.p[0], ch.r[0], ch.mean_rate[0], ch.correlation[0])]
    [0.2, 0.2, 0.5, 0.6]
    """
    rate = np.atleast_1d(np.asarray(rate, dtype=float))
    if rate.shape != (channel.m,):
        raise InputError("rate", f"expected {channel.m} mean rates, found shape {rate.shape}")
    lam = channel.correlation
    if np.any(lam >= 1.0):
        raise InputError("channel", "a chain that never moves (p + r = 0) has no mean rate to vary")
    span = channel.h_good - channel.h_bad
    if np.any(span <= 0) or np.any(rate < channel.h_bad - 1e-15) or np.any(rate > channel.h_good + 1e-15):
        raise InputError("rate", f"expected each mean rate within [h_bad, h_good], found {rate.tolist()}")
    g = np.clip((rate - channel.h_bad) / span, 0.0, 1.0)
    p, r = gilbert_rates(g, lam)
    return GilbertElliott(p=p, r=r, h_good=channel.h_good, h_bad=channel.h_bad)


def chain_rate_map(A: npt.ArrayLike, B: npt.ArrayLike, channel: MarkovChannel, axis: npt.ArrayLike,
                   channels: tuple[int, int] = (0, 1), delivery: str = "next", with_error: bool = False
                   ) -> tuple[np.ndarray, ...]:
    """The region over the mean rates of channels I, J (the others at their own rates) at fixed burstiness:
    ``(stable, lam)`` on the grid ``axis`` × ``axis`` (rows rate_J, columns rate_I): 1.0 certified stable, 0.0
    certified not stabilisable, nan undecided; ``lam`` the homogeneous coupled Riccati eigenvalue (min over mode
    laws of the coupled radius). One channel (m = 1): one row over ``axis``. ``with_error``: a third array, each
    lambda's own accuracy estimate (`chain_least_radius`'s ``error``), for a caller that prints only the digits
    it supports. Time K^2 memberships (plus K^2 coupled radii ``with_error``).

    Examples
    --------
    >>> stable, lam = chain_rate_map([[2.0]], [[1.0]], GilbertElliott(p=[0.5], r=[0.5]), [0.5, 0.9])
    >>> stable.tolist()                                     # memoryless: Bernoulli, S = {mu > 3/4}
    [[0.0, 1.0]]
    """
    axis = np.asarray(axis, dtype=float)
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    base = channel.mean_rate.copy()
    rows = axis if channel.m > 1 else axis[:1]
    stable = np.full((len(rows), len(axis)), np.nan)
    lam = np.full_like(stable, np.nan)
    error = np.full_like(stable, np.nan)
    for r, y in enumerate(rows):
        for c, x in enumerate(axis):
            rate = base.copy()
            rate[channels[0]] = x
            if channel.m > 1:
                rate[channels[1]] = y
            ch = chain_at_rate(channel, rate)
            if with_error:
                found, lam[r, c], error[r, c] = chain_least_radius(A, B, ch, delivery)
            else:
                found, lam[r, c], _, _ = _membership(A, B, ch, delivery)
            if found.verdict != "undecided":
                stable[r, c] = 1.0 if found.verdict == "stable" else 0.0
    return (stable, lam, error) if with_error else (stable, lam)


def critical_rate_unproved(channel: MarkovChannel) -> str | None:
    """Why no critical mean rate is offered behind ``channel`` (None where the region is proved monotone in the
    mean rates at fixed burstiness: every channel with ``h_bad = 0`` and burstiness ``0 <= lambda_i < 1``, a
    chain that moves, and ``h_good_i > 0``; docs/mathematics.md, "The critical mean rate behind a chain"). O(m).

    >>> critical_rate_unproved(GilbertElliott(p=[0.1], r=[0.3])) is None
    True
    >>> critical_rate_unproved(GilbertElliott(p=[0.6], r=[0.7]))[:40]
    'monotonicity in the mean rate is proved '
    >>> critical_rate_unproved(GilbertElliott(p=[0.0], r=[0.0], state=["good"]))[:31]   # a chain that never moves
    'channel(s) [1] never move (1 - '
    >>> critical_rate_unproved(GilbertElliott(p=[0.1], r=[0.3], h_good=[0.0]))[:28]          # never delivers
    'channel(s) [1] never deliver'
    """
    still = [i + 1 for i in range(channel.m) if channel.correlation[i] >= 1.0]
    if still:                   # p + r = 0 (a given state), or below the resolution of 1 - p - r: no ray to run
        return (f"channel(s) {still} never move (1 - p - r = 1 in floating point): at fixed burstiness the mean rate "
                "cannot be varied, so there is no critical mean rate (the membership above still answers)")
    dead = [i + 1 for i in range(channel.m) if channel.h_good[i] == 0.0 and channel.h_bad[i] == 0.0]
    if dead:                    # its mean rate is 0 whatever the chain: nothing to vary
        return (f"channel(s) {dead} never deliver (h_good = h_bad = 0): their mean rate cannot be varied, so there "
                "is no critical mean rate (the membership above still answers)")
    bad = [i + 1 for i in range(channel.m) if channel.h_bad[i] != 0.0 or channel.correlation[i] < 0.0]
    if not bad:
        return None
    return ("monotonicity in the mean rate is proved for channels with h_bad = 0 and burstiness >= 0 only (a "
            f"thinning of the chain); channel(s) {bad} are outside it, so no bisection is offered (the rate map "
            "--grid K still answers point by point)")


def chain_critical_rate(system, direction: npt.ArrayLike | None = None, tol: float = CRITICAL_MU_TOL,
                        delivery: str = "next") -> CriticalPoint:
    """The least ``t`` with mean rates ``t * direction`` (burstiness and h kept, `chain_at_rate`) at which some
    mode-dependent law stabilises the loop behind the system's chain:
    [`critical_point`][packetloss_cvx.closedloop.critical.critical_point]'s bisection on decided points, the upper end
    with stabilising mode gains, the lower end with an infeasibility certificate, so the exact critical rate lies in
    ``[lower, t]``. Offered only where the region is proved monotone along the ray (`critical_rate_unproved`).
    ``direction`` nonnegative, not all zero (default all ones); t runs to ``min_i h_good_i / direction_i``. Time
    O(log2(1 / tol)) chain memberships.

    Raises
    ------
    InputError
        No Gilbert-Elliott channel, a bad direction, or a chain outside the proof (the reason).
    NumericalError
        The ray's end or mu = 0 undecided, or no point of a bracket wider than ``tol`` decidable.

    Examples
    --------
    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.4], r=[0.4]))     # one state, a Gilbert channel: iff r > 1 - 1/a^2
    >>> point = chain_critical_rate(s)               # burstiness 0.2 kept: r = 0.8 rate, so rate > (5/9) / 0.8
    >>> bool(point.lower <= 25 / 36 <= point.t <= point.lower + 1e-6), point.inside.verdict, point.outside.verdict
    (True, 'stable', 'unstable')
    """
    channel = system.channel
    if not isinstance(channel, MarkovChannel) or not channel.two_state:
        raise InputError("channel", "expected a system with a Gilbert-Elliott channel (two-state chains)")
    check_delivery(delivery)
    reason = critical_rate_unproved(channel)
    if reason is not None:
        raise InputError("channel", reason)
    d = np.ones(channel.m) if direction is None else np.asarray(direction, dtype=float).reshape(-1)
    if d.shape != (channel.m,) or not np.all(np.isfinite(d)) or np.any(d < 0) or not np.any(d > 0):
        raise InputError("direction", f"expected {channel.m} nonnegative numbers, not all zero")
    A, B = np.asarray(system.A, dtype=float), np.asarray(system.B, dtype=float)
    end = float(np.min(channel.h_good[d > 0] / d[d > 0]))

    def decide(rate: np.ndarray) -> Membership:
        return chain_membership(A, B, chain_at_rate(channel, np.minimum(rate, channel.h_good)), delivery)

    return critical_point(system, "dp", d, tol, decide=decide, end=end)
