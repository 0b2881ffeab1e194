"""The stabilisable set S: is some linear law ``u = -K x`` mean-square stabilising over channel ``mu``?

Full state, independent Bernoulli(mu_i) losses (docs/mathematics.md §2, "The stabilisable set"). For a law K
the second moment obeys ``S+ = L_K(S) + Sigma_W`` (simulation.stability); ``mu`` is in S iff
``min_K rho(L_K) < 1``. Two certificates, each checked in numpy by the operator it speaks about:

- **inside**: a gain K whose operator has radius ``< 1 - MEAN_SQUARE_MARGIN`` (stability.mean_square_radius);
- **outside**: a matrix ``P >= 0``, ``tr P = 1``, with

  .. math:: T_\\mu(P) = \\begin{bmatrix} A'PA - P & -A'PBM \\\\ -MB'PA & MB'PBM + \\mathrm{diag}(\\mu(1-\\mu))
     \\circ B'PB \\end{bmatrix} \\succeq 0.

  Since ``x'(L_K^*(P) - P)x = [x; Kx]' T_mu(P) [x; Kx]``, this says ``L_K^*(P) >= P`` for every K, so
  ``<P, L_K^j(X)> >= <P, X> > 0`` for X > 0 and every j: no K makes the loop mean-square stable.

Three forms find them: "dp" (the stabilising solution of the modified Riccati equation,
simulation.riccati; success is a gain, failure is no verdict), "riccati" (the homogeneous modified
Riccati map ``R(P) = min_K L_K^*(P)`` with Omega = Psi = 0, power-iterated to its eigenpair
``R(P) = lambda P``: lambda = min_K rho(L_K); its gain is the inside certificate when lambda < 1, its P the
outside one when lambda > 1) and "lmi" (simulation.region_lmi: the Schur-complement LMI and its alternative,
cvxpy + Clarabel). A form that cannot check its certificate says "undecided", never "unstable".

The map's algebra (R as a sum of squares, the Collatz–Wielandt bound of a certificate, its cuts, the part no input
reaches, the balancing of a graded eigenvector) is simulation.riccati_map's, over M-mode channels: Bernoulli losses
are its one-mode chain, and simulation.chain_radius iterates the same map behind Gilbert–Elliott chains. The
iteration here is its own (batched over channels, a Kronecker policy iteration): the chain's, run on one-mode chains,
agrees on the least radius within 9.1e-10 (graded Jordan chains; 3.7e-15 on two_actuator) and takes several times
the time (docs/performance.md, "The stabilisable-set iteration at one mode": where that time goes).

The "dp" form can only prove "stable" (its gain's radius below ``1 - MEAN_SQUARE_MARGIN``). When the "riccati"
form ran before it and proved "unstable", or undecided but its P bounds every law's radius at
``1 - MEAN_SQUARE_MARGIN / 2`` or more (the outside check with that band, `_DP_HOPELESS`), no gain can pass
(both checks are exact), so the "dp" form says "undecided" without running: outside S the DP's value iteration
crawls to its step cap near the boundary (scalar a = 2 at mu = 0.75: 20,000 steps) for that same verdict.

Every certificate is re-checked in exact rational arithmetic (simulation.certificates): a verdict is a proof about
the plant as stored, or the form says "undecided". Where the inputs that deliver leave a part of the state
unreached (linalg.controllable_split), that part's radius ``rho(A_uu)^2`` bounds every law's radius exactly and its
Stein certificate decides (`_unreached`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..errors import CrossCheckError, InputError, NumericalError, SolverError
from ..linalg import ControllableSplit, controllable_split
from ..lq.recursion import riccati_step
from ..model.system import System
from ..results.region import Membership
from ..tolerances import (
    CERTIFICATE_RTOL,
    HOMOGENEOUS_RICCATI_MAX_ITER,
    KRONECKER_MAX_N,
    LEAST_RADIUS_ATOL,
    MEAN_SQUARE_MARGIN,
    RICCATI_RTOL,
)
from .certificates import candidates, law_proved_stable, outside_proved
from .moments import stationary_channel
from .riccati import dp_riccati
from .riccati_map import (
    GRADED,
    POLICY_STEPS,
    SHIFT,
    bernoulli_rates,
    certificate_bound,
    converges_within,
    cut_candidates,
    grading_scale,
    perron_adjoint,
    psd_part_factor,
    psd_size,
    reach_split,
    riccati_factors,
    unreached_stein,
)
from .stability import check_law, is_mean_square_stable, law_radius, mean_square_radius, second_moment_matrix

__all__ = ["FORMS", "LazyLmi", "certificate_margin", "converges_within", "homogeneous_riccati", "membership",
           "proved_margin"]

#: power-iteration steps before the policy iteration takes over (n <= KRONECKER_MAX_N; the policy iteration's step
#: cap: riccati_map.POLICY_STEPS; the power iteration's shift: riccati_map.SHIFT)
_POWER_STEPS = 30
#: power steps after which a point whose steps shrink too slowly to converge within _POWER_STEPS is handed to the
#: policy iteration at once, asked at this step only (two_actuator: steps shrink by about 0.8 each, 120 to go; the
#: 26 power steps left were waste)
_POWER_WATCH = 4
#: where the eigenpair's own gain is not proved stabilising, the gain is taken once more from P + _LIFT I (tr P = 1):
#: the Perron eigenvector of a decoupled plant vanishes on the blocks whose radius is not the largest, and the
#: least-squares minimiser gives them gain 0; the lifted P weighs every direction (without it,
#: diag(1.2, 2, 0.5), B = I is "undecided" by this form at every mu inside S)
_LIFT = 1e-6

#: the forms :func:`membership` can run, cheapest first
FORMS = ("riccati", "dp", "lmi")


class LazyLmi:
    """The LMI form of one plant (region_lmi.LmiForm), built and cvxpy imported only when first asked
    to solve: callers that bisect keep one across points, and a path the Riccati forms decide never
    loads cvxpy. Time O(1) to make.

    >>> t, K, status = LazyLmi([[2.0]], [[1.0]]).stabilise(np.array([0.9]))   # S = {mu > 0.75}
    >>> status, t > 0
    ('optimal', True)
    """

    def __init__(self, A: npt.ArrayLike, B: npt.ArrayLike) -> None:
        self.A, self.B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
        self._form = None

    def _get(self):
        if self._form is None:
            from .region_lmi import LmiForm
            self._form = LmiForm(self.A, self.B)
        return self._form

    def stabilise(self, mu: np.ndarray) -> tuple[float, np.ndarray | None, str]:
        """As `region_lmi.LmiForm.stabilise`."""
        return self._get().stabilise(mu)

    def certify(self, mu: np.ndarray) -> tuple[float, np.ndarray | None, str]:
        """As `region_lmi.LmiForm.certify`."""
        return self._get().certify(mu)


def certificate_margin(A: np.ndarray, B: np.ndarray, mu: np.ndarray, P: np.ndarray) -> float:
    """``c - 1``, c the bound every law's mean-square radius meets by the infeasibility certificate P: the largest
    c with ``R(P) >= c P`` (riccati_map.certificate_bound at the one-mode chain; equivalently ``T_mu(P)`` with
    ``A'PA - cP`` in its corner is PSD), so ``rho(L_K) >= c`` for every K.

    ``P >= 0`` with a margin ``>= -CERTIFICATE_RTOL`` proves (to rounding) that no law stabilises: a band on the
    radius, not on T's scale (the least eigenvalue of ``T_mu(P)`` over its scale, the check before, shrinks like
    ``1 / ||K||^2`` with the gain, so a P from 1e-6 inside S had passed it where the gains were about 600). Time
    O((n + m)^3). Returns ``-inf`` when P is not PSD to ``CERTIFICATE_RTOL`` times its norm, is zero or not finite;
    the bound speaks of P's PSD part.

    Examples
    --------
    >>> A, B = np.array([[2.0]]), np.array([[1.0]])   # R(p) = a^2 (1 - mu) p: no law stabilises iff mu <= 3/4
    >>> [round(certificate_margin(A, B, np.array([mu]), np.eye(1)), 12) for mu in (0.6, 0.9)]
    [0.6, -0.6]
    """
    P = 0.5 * (P + P.T)[None]
    if not psd_size(P) > 0:
        return float("-inf")
    return certificate_bound(P, A, B, *bernoulli_rates(mu)) - 1.0


def _homogeneous_step(P: np.ndarray, A: np.ndarray, B: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(K, R(P))``: the minimiser of ``L_K^*(P)`` (least squares, the minimum-norm solution: its Hessian may be
    singular) and the min, for a stack P (..., n, n) with mu (..., m): Theorem 1's step
    ([`riccati_step`][packetloss_cvx.lq.recursion.riccati_step]) with no weights, the loss variance weighted by P, the
    Hessian solved by least squares. A Hessian that is not finite gives K = nan."""
    lead = P.shape[:-2]
    P2, mu2 = P.reshape(-1, *P.shape[-2:]), np.broadcast_to(mu, (*lead, B.shape[1])).reshape(-1, B.shape[1])
    K, R = riccati_step(P2, A, B, mu2, np.zeros_like(mu2), variance=True, least_squares=True)
    return K.reshape(*lead, *K.shape[1:]), R.reshape(P.shape)


def homogeneous_riccati(A: np.ndarray, B: np.ndarray, mu: np.ndarray, start: np.ndarray | None = None
                        ) -> tuple[float, np.ndarray, np.ndarray]:
    """``(lambda, P, K)``: the eigenpair ``R(P) = lambda P`` of the homogeneous modified Riccati map
    ``R(P) = min_K L_K^*(P)`` (``tr P = 1``) and the gain that attains the minimum; for a stack of channels
    ``mu`` (G, m), the G eigenpairs ``(lambda (G,), P (G, n, n), K (G, m, n))`` in one batch.

    ``R`` is monotone, concave and positively homogeneous on the PSD cone; the shifted power iteration
    ``P <- (R(P) / lambda + 0.1 P) / 1.1`` (the shift removes a peripheral spectrum, e.g. rotations) converges to
    its Perron eigenpair, and lambda = min_K rho(L_K). A point stops when ``||P_next - P|| <= RICCATI_RTOL``; for
    n <= KRONECKER_MAX_N a policy iteration on the Perron eigenvector finishes the points left after 30 steps,
    and after step 4 those whose last two steps shrink too slowly to reach RICCATI_RTOL within the 30 (on
    two_actuator nearly every point: its steps shrink by about 0.8); else the iteration stops after
    ``HOMOGENEOUS_RICCATI_MAX_ITER`` steps. Each point of a batch takes exactly the steps it would
    alone (the batch only shares NumPy's calls), so a batch agrees with its points one by one to rounding
    (tests/closedloop/test_region.py). The result is a candidate, checked by the caller. Time O(iterations (n^3 + m^3))
    per
    point, plus O(n^6) a policy step.

    ``start`` (n, n), optional: a PSD matrix near the eigenvector (a nearby channel's P), where every point's
    iteration starts instead of ``I / n``, mixed as ``(1 - _START_MIX) start / tr(start) + _START_MIX I / n``: an
    interior point of the PSD cone (the mix keeps the directions a nearby channel's P may lack, e.g. a decoupled
    plant's other blocks), in fewer steps where the start is near the eigenvector. Not always the same
    candidate: on a decoupled plant the steps can end on another block's eigenvector than the cold start's
    (either may miss the dominant block; tests/closedloop/test_region.py), which the caller's checks then refuse. A
    start
    that is not finite, or whose trace is not positive, is ignored.

    Examples
    --------
    >>> lam, P, K = homogeneous_riccati(np.array([[2.0]]), np.array([[1.0]]), np.array([0.5]))
    >>> round(lam, 12), round(float(K[0, 0]), 12)   # scalar: min_k (a - mu k)^2 + mu(1-mu)k^2 = a^2 (1 - mu) at k = a
    (2.0, 2.0)
    >>> lam, P, K = homogeneous_riccati(np.array([[2.0]]), np.array([[1.0]]), np.array([[0.5], [0.75]]))
    >>> np.round(lam, 12).tolist()                  # a^2 (1 - mu) at each point of the batch
    [2.0, 1.0]
    """
    mu = np.asarray(mu, dtype=float)
    single = mu.ndim == 1
    mus = mu.reshape(-1, B.shape[1])
    n, m = B.shape
    lam, P, K = np.empty(mus.shape[0]), np.empty((mus.shape[0], n, n)), np.empty((mus.shape[0], m, n))
    reaches = mus > 0.0                               # a channel that never delivers reaches nothing
    try:
        for pattern in np.unique(reaches, axis=0):
            idx = np.flatnonzero(np.all(reaches == pattern, axis=1))
            split, Bt = reach_split(A, B, pattern)
            if split.nc == n:
                lam[idx], P[idx], K[idx] = _graded(A, B, mus[idx], start)
            else:
                lam[idx], P[idx], K[idx] = _split_eigenpairs(split, Bt, A, B, mus[idx], start)
    except np.linalg.LinAlgError as err:
        raise NumericalError(f"homogeneous Riccati eigenpair: a linear-algebra routine failed ({err}); no "
                             "candidate certificate") from None
    return (float(lam[0]), P[0], K[0]) if single else (lam, P, K)


def _split_eigenpairs(split: ControllableSplit, Bt: np.ndarray, A: np.ndarray, B: np.ndarray, mus: np.ndarray,
                      start: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`homogeneous_riccati` where the inputs that deliver leave a part unreached (``split``, the Kalman
    decomposition ``T'AT = [[A_cc, A_cu], [0, A_uu]]``, ``Bt = T'B = [[B_c], [0]]``: riccati_map.reach_split): the
    second-moment operator is block triangular, so ``rho(L_K) = max(rho of the reached part's operator,
    rho(A_uu)^2)`` and the least radius is ``max(lambda_c, rho(A_uu)^2)``, lambda_c the reached part's own
    (computed on (A_cc, B_c)); the gain is the reached part's, 0 on the rest. P: where the unreached part decides,
    the Perron eigenvector of ``X -> A_uu' X A_uu``; else the eigenvector of the whole map, iterated from the reached
    part's (checked by the caller like any candidate). Time that of the reached part's iteration (and the whole
    one's)."""
    n, m = B.shape
    G, nc, T = mus.shape[0], split.nc, split.T
    Tc, Tu = T[:, :nc], T[:, nc:]
    unreached = split.uncontrollable_radius ** 2
    lam_c, K = np.zeros(G), np.zeros((G, m, n))
    P_c = np.zeros((G, nc, nc))
    if nc:
        start_c = None if start is None else Tc.T @ np.asarray(start, dtype=float) @ Tc
        lam_c, P_c, K_c = _graded(split.A_cc, Bt[:nc], mus, start_c)
        K = K_c @ Tc.T
    lam = np.maximum(lam_c, unreached)
    P = np.empty((G, n, n))
    top = unreached >= lam_c
    if np.any(top):
        P[top] = Tu @ perron_adjoint(split.A_uu) @ Tu.T
    for g in np.flatnonzero(~top):
        P[g] = _graded(A, B, mus[g:g + 1], Tc @ P_c[g] @ Tc.T)[1][0]
    return lam, P, K


#: riccati_map.GRADED, here where the tests switch the refinement off (0.0) to see the unbalanced iteration
_GRADED = GRADED
#: the refinement's passes at most (the second changes nothing where the first balanced P)
_BALANCE_PASSES = 2
#: a refinement is kept where its gain's radius is nearer its lambda than the last one's, or within this much of
#: lambda (relative): the radius of a near-defective Perron root (a Jordan chain's loop) is itself known only to about
#: sqrt(eps), so two gaps below it are not told apart (OpenBLAS's Nehalem kernel, 1.001 I4 + N at mu = 0.002: the
#: balanced pass's lambda 1.3e-14 off Elia's value with a gap of 1.06e-8, the unbalanced 4.2e-9 off with 1.7e-9)
_GAP_NOISE = 1e-7


def _graded(A: np.ndarray, B: np.ndarray, mus: np.ndarray, start: np.ndarray | None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The iteration (`_iterate`), and for each point whose P is graded (its diagonal spans more than
    `_GRADED`) the iteration again on the plant scaled by ``D = diag(2^round(-log2(P_ii) / 2))``
    (riccati_map.grading_scale, as the chains' eigenpair is balanced)
    (``A -> D^-1 A D``, ``B -> D^-1 B``: exact in floating point, the same operators up to similarity), started from
    ``D P D``, mapped back (``P = D^-1 P~ D^-1``, ``K = K~ D^-1``, exact too). On a chain of integrators (P's
    diagonal 4e-14 ... 1) the unscaled iteration is not a fixed point (lambda 1.0101 for 1.0015); scaled, it
    matches the exact single-input value to 1e-14 (tests/closedloop/test_region.py). Time: the iteration's, twice or
    three
    times for a graded point."""
    lam, P, K = _iterate(A, B, mus, start)
    for g in range(mus.shape[0]):
        best, gap = (lam[g], P[g], K[g]), None
        for _ in range(_BALANCE_PASSES):
            D = grading_scale(best[1], _GRADED)
            if D is None:
                break
            l_, P_, K_ = _iterate(A * D[None, :] / D[:, None], B / D[:, None], mus[g:g + 1],
                                  D[:, None] * best[1] * D[None, :])
            found = (l_[0], P_[0] / D[:, None] / D[None, :], K_[0] / D[None, :])
            # kept only where its gain's radius is nearer its lambda than the last one's (an eigenpair of the
            # minimising law): on a decoupled plant the scaled steps can end on a block that is not the largest
            # (lambda 0.16 where 1.0001), whose gain leaves the largest block unstable
            gap = _gap(A, B, mus[g], *best) if gap is None else gap
            found_gap = _gap(A, B, mus[g], *found)
            if not found_gap < max(gap, _GAP_NOISE * abs(float(found[0]))):
                break
            best, gap = found, found_gap
        lam[g], P[g], K[g] = best
    return lam, P, K


def _gap(A: np.ndarray, B: np.ndarray, mu: np.ndarray, lam: float, P: np.ndarray, K: np.ndarray) -> float:
    """``|rho(L_K) - lambda|`` of a candidate eigenpair (inf where the radius fails). O(n^6)."""
    try:
        return abs(law_radius(A, B, K, mu) - lam) if np.all(np.isfinite(K)) else float("inf")
    except NumericalError:
        return float("inf")


def _iterate(A: np.ndarray, B: np.ndarray, mus: np.ndarray, start: np.ndarray | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The shifted power iteration and its policy iteration (`homogeneous_riccati`) on one plant, for the
    stack of channels ``mus`` (G, m); a point where the always-delivered channels alone reach the whole state
    (controllable_split of their columns) has lambda 0.0 exactly: their deadbeat law makes every L_K nilpotent.
    Time O(iterations (n^3 + m^3)) a point, plus O(n^6) a policy step."""
    n = A.shape[0]
    P = np.repeat(_first_iterate(n, start)[None], mus.shape[0], axis=0)
    active = np.ones(mus.shape[0], dtype=bool)
    zeroed = np.full(mus.shape[0], np.nan)            # tr R(P) / tr P where the zero test stopped a point
    policy = n <= KRONECKER_MAX_N
    slow = np.zeros(mus.shape[0], dtype=bool)          # handed to the policy iteration before the last power step
    steps = _POWER_STEPS if policy else HOMOGENEOUS_RICCATI_MAX_ITER
    floor = LEAST_RADIUS_ATOL * float(np.linalg.norm(A, 2)) ** 2
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        _power(P, A, B, mus, active, zeroed, floor, slow if policy else None, 0, steps)
        if policy and np.any(active | slow):
            left = np.flatnonzero(active | slow)
            found, moved = _policy_iteration(P[left], A, B, mus[left])
            # a point handed over early keeps the policy iteration's P only where it is a fixed point of R (as
            # markov_region's): near a deadbeat law (lambda -> 0) the policy steps stop at rounding, lambda 1.3e-7
            # and ||R(P) / lambda - P|| 6e-6 where the power iteration reaches 0
            moved &= ~slow[left] | _fixed(found, A, B, mus[left])
            P[left[moved]] = found[moved]
            # handed over early and not moved by the policy iteration (its first Perron eigenvector degenerate) or
            # not to a fixed point: the power steps left, then the policy iteration, as without the hand-off
            back = left[~moved & slow[left]]
            if back.size:
                active[:] = False
                active[back] = True
                _power(P, A, B, mus, active, zeroed, floor, None, _POWER_WATCH, steps)
                if np.any(active):
                    P[active] = _policy_iteration(P[active], A, B, mus[active])[0]
        K, _ = _homogeneous_step(P, A, B, mus)
    lam = _eigenvalue(P, A, B, mus)
    stopped = ~np.isnan(zeroed)   # stopped by the zero test: tr R(P) / tr P there, in [0, floor] by that test
    lam[stopped] = np.clip(zeroed[stopped], 0.0, floor)
    always = mus == 1.0
    for pattern in np.unique(always[np.any(always, axis=1)], axis=0):
        if controllable_split(A, B[:, pattern]).nc == n:
            lam[np.all(always == pattern, axis=1)] = 0.0
    return lam, P, K


#: the weight of I / n in a started power iteration's first iterate (:func:`homogeneous_riccati`)
_START_MIX = 1e-3


def _first_iterate(n: int, start: np.ndarray | None) -> np.ndarray:
    """The power iteration's first P: ``I / n``, or with a usable ``start`` its mix with it. O(n^2)."""
    plain = np.eye(n) / n
    if start is None:
        return plain
    start = np.asarray(start, dtype=float)
    trace = float(np.trace(start)) if start.shape == (n, n) and np.all(np.isfinite(start)) else float("nan")
    if not trace > 0:
        return plain
    return (1.0 - _START_MIX) * (0.5 * (start + start.T)) / trace + _START_MIX * plain


def _power(P: np.ndarray, A: np.ndarray, B: np.ndarray, mus: np.ndarray, active: np.ndarray, zeroed: np.ndarray,
           floor: float, slow: np.ndarray | None, first: int, steps: int) -> None:
    """The shifted power iteration's steps ``first .. steps - 1`` on the points ``active`` (G,), in place on P and
    ``active`` (a point leaves when it stops: ``||P_next - P|| <= RICCATI_RTOL``, or its zero test ``tr R(P) <=
    floor tr P`` (``floor = LEAST_RADIUS_ATOL ||A||_2^2``), which records a finite ``tr R(P) / tr P`` in
    ``zeroed``). With ``slow`` (G,), after step _POWER_WATCH a point whose last two steps shrink too slowly to reach
    RICCATI_RTOL by the last step leaves too, marked in ``slow``. Time O((steps - first) (n^3 + m^3)) a point."""
    last = np.full(P.shape[0], np.inf)               # each point's previous step ||P_next - P||
    for step in range(first, steps):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        Pa = P[idx]
        _, R = _homogeneous_step(Pa, A, B, mus[idx])
        lam = np.trace(R, axis1=-2, axis2=-1)
        # R(P) = 0 to rounding: lambda = 0 (a deadbeat law, e.g. mu_i = 1 and B invertible), or an overflow the
        # caller's check refuses; iterating on R / lambda would amplify rounding: such a point stops here
        zero = ~(np.isfinite(lam) & (lam > floor * np.trace(Pa, axis1=-2, axis2=-1)))
        P_next = (R / lam[:, None, None] + SHIFT * Pa) / (1.0 + SHIFT)
        moved = np.linalg.norm(P_next - Pa, axis=(-2, -1))
        done = moved <= RICCATI_RTOL
        P[idx[~zero]] = P_next[~zero]
        active[idx[zero | done]] = False
        small = zero & np.isfinite(lam)               # not an overflow: R(P) vanishes to the floor
        zeroed[idx[small]] = lam[small] / np.trace(Pa[small], axis1=-2, axis2=-1)
        if slow is not None and step + 1 == _POWER_WATCH:
            # a point whose steps shrink too slowly to reach RICCATI_RTOL by the last power step (ratio r of its
            # last two steps: log(RTOL / step) / log r steps to go) goes to the policy iteration now; asked once
            # only: later, a deadbeat point's steps stall at rounding as lambda -> 0 (two_actuator with mu_2 = 1),
            # and the power iteration's own zero test, not the policy iteration, ends it
            hand = ~zero & ~done & ~converges_within(moved, last[idx], steps - step - 1)
            slow[idx[hand]] = True
            active[idx[hand]] = False
        last[idx] = moved


def _fixed(P: np.ndarray, A: np.ndarray, B: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Is each P (G, n, n) an eigenvector of R, ``||R(P) / lambda - P / tr P|| <= RICCATI_RTOL`` (the power
    iteration's own stop)? (G,) bool. O(G (n^3 + m^3))."""
    _, R = _homogeneous_step(P, A, B, mu)
    lam = np.trace(R, axis1=-2, axis2=-1)
    scale = np.trace(P, axis1=-2, axis2=-1)
    residual = np.linalg.norm(R / lam[:, None, None] - P / scale[:, None, None], axis=(-2, -1))
    return np.isfinite(lam) & (lam > 0) & (residual <= RICCATI_RTOL)


def _eigenvalue(P: np.ndarray, A: np.ndarray, B: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """lambda = tr R(P+) / tr P+ at the found eigenvector (P+ its PSD part): a sum of squares over a sum of
    nonnegative eigenvalues, so it cannot be negative (A'PA - A'PBM K had given -1.2e-9 and -9e-7 where a
    deadbeat law makes it 0); nan where P is not finite. O(n^3 + (n + m)^3) a point."""
    lam = np.full(P.shape[0], np.nan)
    finite = np.all(np.isfinite(P), axis=(-2, -1))
    if np.any(finite):
        L, w = psd_part_factor(P[finite])
        F = riccati_factors(L[:, None], A, B, *bernoulli_rates(mu[finite]))[:, 0]
        total = np.sum(w, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            lam[finite] = np.where(total > 0, np.sum(F * F, axis=(-2, -1)) / total, np.nan)
    return lam


def _policy_iteration(P: np.ndarray, A: np.ndarray, B: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """From power-iteration P (G, n, n) at mu (G, m): K = argmin L_K^*(P), then P = the Perron eigenvector of L_K^*
    (the transposed Kronecker matrix, exact for n <= KRONECKER_MAX_N), until lambda settles, each point on its
    own; returns the P found and which points it moved (G,) (False: P given back). Each step can only lower rho
    (L_{K+}^*(P) <= L_K^*(P) = lambda P, a Collatz-Wielandt bound), so it converges where the power iteration
    crawls (second eigenvalue near the first). Time O(n^6) a step a point."""
    n = A.shape[0]
    P, best = P.copy(), P.copy()
    last = np.full(P.shape[0], np.inf)
    alive = np.ones(P.shape[0], dtype=bool)
    moved_any = np.zeros(P.shape[0], dtype=bool)
    for _ in range(POLICY_STEPS):
        K, _ = _homogeneous_step(P[alive], A, B, mu[alive])
        idx = np.flatnonzero(alive)
        finite = np.all(np.isfinite(K), axis=(-2, -1))
        alive[idx[~finite]] = False          # keep the last good P
        idx, K = idx[finite], K[finite]
        M = np.swapaxes(second_moment_matrix(A, B, K, mu[idx]), -1, -2)
        finite = np.all(np.isfinite(M), axis=(-2, -1))   # an overflowing operator: keep the last good P
        alive[idx[~finite]] = False
        idx, M = idx[finite], M[finite]
        if not idx.size:
            break
        vals, vecs = np.linalg.eig(M)
        top = np.argmax(vals.real, axis=-1)
        rows = np.arange(idx.size)
        lam = vals[rows, top].real
        V = vecs[rows, :, top].real.reshape(-1, n, n)
        V = 0.5 * (V + np.swapaxes(V, -1, -2))
        trace = np.trace(V, axis1=-2, axis2=-1)
        usable = np.isfinite(lam) & (trace != 0.0)
        alive[idx[~usable]] = False
        idx, lam, V, trace = idx[usable], lam[usable], V[usable], trace[usable]
        if not idx.size:
            break
        Pn = V / trace[:, None, None]
        # a degenerate Perron root (lambda = 0, its eigenvector not PSD): keep the last good P
        degenerate = (lam <= 0.0) | (np.linalg.eigvalsh(Pn)[:, 0] < -CERTIFICATE_RTOL)
        settled = ~degenerate & (lam >= last[idx] * (1.0 - RICCATI_RTOL))
        kept = ~degenerate & (~settled | (lam <= last[idx]))
        best[idx[kept]] = Pn[kept]
        moved_any[idx[kept]] = True
        moving = ~degenerate & ~settled
        last[idx[moving]] = lam[moving]
        P[idx[moving]] = Pn[moving]
        alive[idx[~moving]] = False
        if not np.any(alive):
            break
    return best, moved_any


def _inside(A: np.ndarray, B: np.ndarray, mu: np.ndarray, K: np.ndarray | None) -> tuple[str, float]:
    """"stable" with the law's radius where K's radius is below ``1 - MEAN_SQUARE_MARGIN`` and an exact witness
    proves it (certificates.law_proved_stable), else "undecided" (with the computed radius where there is one)."""
    if K is None or not np.all(np.isfinite(K)):
        return "undecided", float("nan")
    try:
        radius = mean_square_radius(A, B, K, mu)
    except NumericalError:
        return "undecided", float("nan")
    proved = is_mean_square_stable(radius) and law_proved_stable(A, B, K, mu, radius)
    return ("stable" if proved else "undecided"), radius


#: the certificate margin from which the "dp" form is not run (module docstring): every law's radius is then at
#: least 1 - MEAN_SQUARE_MARGIN / 2, proved exactly, so no gain can be proved below the 1 - MEAN_SQUARE_MARGIN that
#: "stable" needs (nor after a proved "unstable" of the "riccati" form, whose margin is above this one)
_DP_HOPELESS = -0.5 * MEAN_SQUARE_MARGIN


def _outside(A: np.ndarray, B: np.ndarray, mu: np.ndarray, P: np.ndarray | None, floor: float = -CERTIFICATE_RTOL,
             eigenvalue: float = float("nan")) -> tuple[str, float, np.ndarray | None]:
    """"unstable" with the margin and the certificate that proves every law's radius at least ``1 + margin >= 1 +
    floor`` in exact arithmetic (`proved_margin`), else "undecided" with the float estimate of P's margin
    (`certificate_margin`). Tried in turn: P and P cut at riccati_map.CUTS (each also snapped), then each of
    them tilted (certificates.candidates). ``eigenvalue``: the homogeneous Riccati eigenvalue whose eigenvector P
    is, when the caller has it: the tilts' estimate where P's own float bound says nothing (a numerically
    rank-one P whose image R(P) the rounding turns off its direction has bound 0, while its tilts prove c up to
    nearly lambda: the python-control spring of tests/closedloop/test_region_certificates.py)."""
    if P is None or not np.all(np.isfinite(P)):
        return "undecided", float("nan"), None
    P = 0.5 * (P + P.T) / max(float(np.trace(P)), np.finfo(float).tiny)
    margin = certificate_margin(A, B, mu, P)
    # the power iteration leaves weight ~1e-13 on a block whose own radius is below the top one (decoupled (3, 1.2,
    # 0.5) at the boundary: the bound of P is that block's 0.175, of P cut at 1e-12 exactly 1)
    candidates = [(P, margin)] + [(Q[0], certificate_margin(A, B, mu, Q[0])) for Q in cut_candidates(P[None])]
    for tilt in (False, True):       # the candidates as they are first (a PSD certificate where one checks)
        for Q, estimate in candidates:
            if tilt and np.isfinite(eigenvalue) and eigenvalue - 1.0 > max(estimate, floor):
                estimate = eigenvalue - 1.0      # the tilts aim below lambda, not below P's own bound: only a
                #                                  choice of the c tried, each decided by the exact check
            proved = proved_margin(A, B, mu, Q, estimate, floor, tilt)
            if proved is not None:
                return "unstable", *proved
    return "undecided", margin, None


def proved_margin(A: np.ndarray, B: np.ndarray, mu: np.ndarray, P: np.ndarray, estimate: float, floor: float,
                  tilt: bool = False) -> tuple[float, np.ndarray] | None:
    """``(c - 1, certificate)`` for the largest c tried that a candidate of P proves exactly (every law's radius
    >= c, certificates.outside_proved; the candidates of certificates.candidates: P and P snapped, or with ``tilt``
    those tilted): P's float ``estimate`` of the margin lowered by CERTIFICATE_RTOL relative, then (with ``tilt``)
    half of it, then ``1 + floor``; None where none holds, or where the estimate is below the floor by more than its
    own rounding. A tilt needs room below the bound it aims at (its ``t S`` spends part of the margin), and the
    Stein equation of ``c = 1`` has no solution where A has eigenvalues on the unit circle (an undamped
    oscillator), hence the half. Time O((n + m)^3) integer operations a try, at most 36 tries.

    >>> A, B = np.array([[2.0]]), np.array([[1.0]])      # every law's radius >= a^2 (1 - mu) = 1.6 at mu = 0.6
    >>> margin, P = proved_margin(A, B, np.array([0.6]), np.eye(1), 0.6, -1e-12)
    >>> 0.6 * (1 - 1e-11) < margin <= 0.6, P.tolist()
    (True, [[1.0]])
    """
    if not estimate >= floor - CERTIFICATE_RTOL:
        return None
    tries = [(1.0 + estimate) * (1.0 - CERTIFICATE_RTOL)] if estimate > floor else []
    if tilt and estimate > max(floor, 0.0):
        tries.append(1.0 + 0.5 * estimate)
    for c in tries + [1.0 + floor]:
        if c < 1.0 + floor:
            continue
        for Q in candidates(A, P, c, tilt):
            if outside_proved(A, B, mu, Q, c):
                return c - 1.0, Q
    return None


def _unreached(A: np.ndarray, B: np.ndarray, mu: np.ndarray) -> tuple[float, np.ndarray] | None:
    """``(margin, P)`` where the part no delivering input reaches (riccati_map.unreached_stein, the channels with mu
    > 0) has ``rho(A_uu)^2 >= 1 - CERTIFICATE_RTOL`` and its Stein certificate checks exactly (a candidate of it,
    certificates.candidates); None otherwise (no such part, or a split resting on a rank decision: its coupling
    rounded away, the check fails and the other certificates decide). Time O(n^4 + n_u^6).

    >>> margin, P = _unreached(np.array([[0.5, 1.0], [0.0, 1.2]]), np.array([[1.0], [0.0]]), np.array([0.5]))
    >>> round(margin, 6), P.round(12).tolist()      # every law leaves x2+ = 1.2 x2: radius >= 1.44
    (0.44, [[0.0, 0.0], [0.0, 1.0]])
    """
    for c, P in unreached_stein(A, B, mu > 0.0):
        for Q in candidates(A, P, c, tilt=False):
            if outside_proved(A, B, mu, Q, c):
                return c - 1.0, Q
    return None


def membership(system: System, mu: npt.ArrayLike | None = None, forms: tuple[str, ...] = FORMS,
               cross_check: bool = True, lmi: LazyLmi | None = None,
               riccati: tuple[float, np.ndarray, np.ndarray] | None = None) -> Membership:
    """Is ``mu`` in the stabilisable set S? Each form in ``forms`` proposes a certificate, checked in numpy.

    Time: "riccati" O(iterations (n^3 + m^3)); "dp" as [`dp_riccati`][packetloss_cvx.closedloop.riccati.dp_riccati];
    "lmi" two Clarabel SDPs.

    Parameters
    ----------
    system : System
        Plant A, B (the weights do not matter for S, except through the "dp" form's own convergence).
    mu : array_like, optional
        The channel (default: the system's stationary channel).
    forms : tuple of str
        Of `FORMS`, run in this order.
    cross_check : bool
        Run every form and require the decided ones to agree (default); False stops at the first decided.
    lmi : LazyLmi, optional
        This plant's LMI form, kept across calls (one is made otherwise).
    riccati : (lambda, P, K), optional
        `homogeneous_riccati` at this mu when the caller has it (a region map keeps lambda as the DP
        radius): the "riccati" form uses it instead of iterating again. Its certificate is checked at mu as
        always, so a pair from elsewhere can only leave the form undecided, never make a verdict.

    Returns
    -------
    Membership
        verdict "stable" with its gain, "unstable" with its certificate P (symmetric, not negative semidefinite,
        tr P = 1 where P >= 0), each proved in exact arithmetic (simulation.certificates), or "undecided" (no form
        could check a certificate: near the boundary, on an ill-conditioned plant, or a solver failure).

    Raises
    ------
    CrossCheckError
        Two forms decided differently.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> [membership(s, [mu], forms=("riccati", "dp")).verdict for mu in (0.7, 0.8)]   # S = {mu > 0.75}
    ['unstable', 'stable']
    """
    A, B, _, mu_ = check_law(system.A, system.B, np.zeros((system.m, system.n)),
                             stationary_channel(system) if mu is None else mu)
    unknown = [f for f in forms if f not in FORMS]
    if unknown or not forms:
        raise InputError("forms", f"expected some of {', '.join(FORMS)}, found {list(forms)}")
    verdicts: dict[str, str] = {}
    values: dict[str, float] = {}
    best: dict[str, object] = {}
    pair = riccati
    for form in forms:
        if form == "riccati" and pair is None:
            try:
                pair = homogeneous_riccati(A, B, mu_)
            except NumericalError:     # no candidate: the form is undecided
                pair = (float("nan"), np.full((system.n, system.n), np.nan), np.full((system.m, system.n), np.nan))
        if form == "dp" and (verdicts.get("riccati") == "unstable" or (verdicts.get("riccati") == "undecided" and
                                                                      _outside(A, B, mu_, pair[1], _DP_HOPELESS,
                                                                               pair[0])[0]
                                                                      == "unstable")):
            verdicts[form], values[form] = "undecided", float("nan")    # no gain can pass (_DP_HOPELESS)
            continue
        verdict, value, gain, P = _run(form, system, A, B, mu_, lmi, pair, best.get("stable", (None,) * 3)[2])
        verdicts[form], values[form] = verdict, value
        if verdict != "undecided" and verdict not in best:
            best[verdict] = (form, value, gain, P)
        if verdict != "undecided" and not cross_check:
            break
    decided = {v for v in verdicts.values() if v != "undecided"}
    if len(decided) > 1:
        raise CrossCheckError(f"stabilisable set at mu = {mu_.tolist()}: the forms disagree ({verdicts}; a "
                              "stabilising gain's radius and an infeasibility certificate's margin)", values)
    pairs = tuple(verdicts.items())
    if not decided:
        return Membership(mu_, "undecided", None, float("nan"), None, float("nan"), pairs,
                          f"no form could check a certificate at mu = {mu_.tolist()} in exact arithmetic (near the "
                          "boundary, on an ill-conditioned plant, or a solver failure)")
    verdict = decided.pop()
    _, value, gain, P = best[verdict]
    if verdict == "stable":
        return Membership(mu_, verdict, gain, value, None, float("nan"), pairs)
    return Membership(mu_, verdict, None, float("nan"), P, value, pairs)


def _run(form: str, system: System, A: np.ndarray, B: np.ndarray, mu: np.ndarray, lmi: LazyLmi | None,
         riccati: tuple[float, np.ndarray, np.ndarray] | None = None, proved: np.ndarray | None = None
         ) -> tuple[str, float, np.ndarray | None, np.ndarray | None]:
    """One form's verdict, its number (a radius or a certificate margin), and its certificate. ``proved``: a gain
    an earlier form proved stabilising, where the "dp" form's policy iteration starts (dp_riccati's ``gain``: the
    same stabilising solution, without the value iteration's crawl near the boundary)."""
    if form == "dp":
        try:
            dp = dp_riccati(system, mu, gain=proved)
        except NumericalError:   # no convergence, divergence or a bad residual: not a verdict
            return "undecided", float("nan"), None, None
        verdict, radius = _inside(A, B, mu, dp.gain)
        return verdict, radius, dp.gain, None
    if form == "riccati":
        lam, P, K = homogeneous_riccati(A, B, mu) if riccati is None else riccati
        unreached = _unreached(A, B, mu)
        if unreached is not None:
            return "unstable", unreached[0], None, unreached[1]
        if lam < 1.0:
            verdict, radius = _inside(A, B, mu, K)
            if verdict == "undecided":   # P vanishes on a block (decoupled plants): its minimiser leaves it gain 0
                K = _homogeneous_step(P + _LIFT * np.eye(A.shape[0]), A, B, mu)[0]
                verdict, radius = _inside(A, B, mu, K)
            return verdict, radius, K, None
        verdict, margin, P_ = _outside(A, B, mu, P, eigenvalue=lam)
        if verdict == "undecided":   # no certificate that checks: lambda may be wrong, and its gain is a candidate
            inside, radius = _inside(A, B, mu, K)
            if inside == "stable":
                return inside, radius, K, None
        return verdict, margin, None, P_
    lmi = LazyLmi(A, B) if lmi is None else lmi
    try:
        t, K, _ = lmi.stabilise(mu)
        if t > 0:
            verdict, radius = _inside(A, B, mu, K)
            return verdict, radius, K, None
        _, P, _ = lmi.certify(mu)
    except SolverError:
        return "undecided", float("nan"), None, None
    verdict, margin, P = _outside(A, B, mu, P)
    return verdict, margin, None, P
