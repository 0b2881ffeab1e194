"""Which channels each actuator strategy can stabilise: membership with exact certificates, and critical mu.

A channel mu is in the region of a strategy (zero, hold, buffer:L, buffer:L:hold) when some TCP-like linear law
of that strategy, ``u = -K_s z`` over its information modes (closedloop.actuator_design), is mean-square stable.
The loop of a law is the information modes' map (its nonzero spectrum is that of the engine's map over the modes
(s, d): the engine's second moments at (t, e) are ``p_te`` times the information map's at t)

.. math:: \\mathcal L_K(X)_t = \\sum_{s,d} p_{sd} R_{sd}(t)\\, (A_{sd} - B_{sd}K_s) X_s (A_{sd} - B_{sd}K_s)'.

- **stable**: the strategy's DP law (`actuator_dp`) and ``X > 0`` with ``c X - L_K(X) > 0``, ``c = 1 -
  MEAN_SQUARE_MARGIN``, checked in exact arithmetic (X the solution of ``X = L_K(X) / r + I``, r between the law's
  radius and c): a positive map, so ``rho(L_K) < c`` (certificates.inside_proved's argument over the modes).
- **unstable**: a tuple P, not blockwise negative semidefinite, with, for every mode s, the homogeneous Bellman
  matrix ``Theta_s = sum_d p_sd [A B]_sd' E_sd [A B]_sd - c (P_s ⊕ 0) >= 0`` (``E_sd = sum_t R_sd(t) P_t``), exactly,
  at c = 1: then ``L_K^*(P)_s = [I; -K_s]' (Theta_s + P_s ⊕ 0) [I; -K_s] >= P_s`` for every K, and every law's
  radius is at least 1 (certificates.outside_proved's argument). P is the homogeneous Bellman map's direction
  (`least_radius`; or it snapped, or rounded to a few bits), or, where an actuator never delivers, its held
  input (hold and buffer:L:hold: ``w_i+ = w_i`` whatever the law).
- **undecided** otherwise, with the reason (a numerical failure is never a verdict).

The region is monotone in mu: a TCP-like controller can resend what the actuator would play on a loss (the held
input; the rest of the plan, zeros or its last entry after it), so a delivery never costs stability, and bisection
along a ray finds its one boundary (`actuator_critical`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..errors import InputError, NumericalError
from ..linalg import Dyadic, exact_psd, frobenius
from ..model.channel import MarkovChannel
from ..model.system import System, check_system
from ..results.region import CriticalPoint, Membership
from ..tolerances import CRITICAL_MU_TOL, MEAN_SQUARE_MARGIN, MOMENT_DENSE_MAX_N
from .actuator import Actuator
from .actuator_design import DesignModes, actuator_dp, actuator_dp_finite, check_protocol, design_modes
from .certificates import exact_transition, snapped, tilted_by
from .chain_radius import symmetric_perron
from .markov_region import chain_at_rate, critical_rate_unproved
from .moments import solve_fixed_point, stationary_channel

__all__ = ["LeastRadius", "actuator_critical", "actuator_membership", "least_radius", "strategy_inside_proved",
           "strategy_outside_proved"]

#: Rows S N^2 of the information map beyond which no exact certificate is attempted (its witness is a dense solve).
MAX_CERTIFIED_ROWS = MOMENT_DENSE_MAX_N ** 2
#: The weighted DP's value steps in a membership (an inside candidate beside the least-radius law; where the DP finds
#: no stabilising solution that close to the boundary, its value iteration's greedy law after as many steps: the
#: scalar buffer:2:hold 1e-6 above its critical mu, whose least-radius law leaves the held entry free), and the
#: homogeneous power iteration's steps and the relative change of its growth at which it stops.
_DP_STEPS = 2000
HOMOGENEOUS_STEPS = 5000
GROWTH_RTOL = 1e-13
#: The policy iteration that finishes the power iteration (`least_radius`): its steps, and the relative residual
#: ``||min_K L_K^*(P) - lambda P|| / (lambda ||P||)`` at which its eigenpair is kept (measured: 1e-15 within 5 steps
#: on the two-actuator hold at its boundary, where the power iteration's growth is still 1.3e-6 high after 5000).
POLICY_STEPS = 12
POLICY_RTOL = 1e-12
#: An outside candidate P (largest entry 1) is also tried rounded to these bits: a rank-deficient direction (the
#: scalar hold's ``(x + w)^2``) proves its bound only with its exact kernel, which the iteration leaves at rounding.
_ROUNDED_BITS = (12, 24, 36)
#: Where the lower end of a critical bracket is undecided, `actuator_critical` steps down from it by tol times
#: powers of this factor until a point is proved unstable (the two-actuator hold: within 4 tol).
_STEP_DOWN = 4.0
#: ... at most this many steps (4^6 tol: 4e-3 at the default tol; the two-actuator hold needs 3 to 5).
_STEPS_DOWN = 6


def _exact_weights(modes: DesignModes, transition: Dyadic | None) -> tuple[list, list]:
    """``p_sd`` and ``R_sd(t)`` exactly: per (s, d) a Dyadic scalar, and a list of (t, Dyadic scalar) with
    ``R_sd(t) > 0``. ``transition`` the channel's exact chain (None: Bernoulli, one state). O(S D (m + S))."""
    one = Dyadic.of(1.0)
    h = [[Dyadic.of(float(v)) for v in row] for row in modes.h]
    p, R = [], []
    for s in range(modes.modes):
        c = int(modes.state[s])
        row_p, row_R = [], []
        for k, d in enumerate(modes.patterns.astype(bool)):
            w = one
            for i, delivered in enumerate(d):
                w = w * (h[c][i] if delivered else one - h[c][i])
            row_p.append(w)
            targets = np.flatnonzero(modes.moves[s, k])
            row_R.append([(int(t), one if transition is None else
                           Dyadic(transition.ints[c, int(modes.state[t])], transition.exp)) for t in targets])
        p.append(row_p)
        R.append(row_R)
    return p, R


def strategy_outside_proved(modes: DesignModes, P: np.ndarray, c: float = 1.0,
                            transition: Dyadic | None = None) -> bool:
    """Does the tuple P (S, N, N) prove, exactly, that every law of the strategy has radius >= c: ``Theta_s >= 0``
    for every mode and P not blockwise negative semidefinite (module docstring)? ``transition`` the channel's exact
    chain (certificates.exact_transition; None for Bernoulli links). Time O(S D (N + r)^3) integer operations.

    >>> m = design_modes([[2.0]], [[1.0]], [0.75], "zero")   # every law's radius >= a^2 (1 - mu) = 1 at mu = 3/4
    >>> strategy_outside_proved(m, np.ones((1, 1, 1))), strategy_outside_proved(design_modes([[2.0]], [[1.0]],
    ...     [0.75 + 2.0 ** -40], "zero"), np.ones((1, 1, 1)))
    (True, False)
    """
    if P is None or np.shape(P) != (modes.modes, *modes.A.shape[-2:]) or not np.all(np.isfinite(P)) or not c > 0:
        return False
    P = 0.5 * (P + P.transpose(0, 2, 1))
    p, R = _exact_weights(modes, transition)
    exact_P = [Dyadic.of(Ps) for Ps in P]
    N, r = modes.A.shape[-1], modes.B.shape[-1]
    cee = Dyadic.of(float(c))
    for s in range(modes.modes):
        padded = np.zeros((N + r, N + r))
        padded[:N, :N] = P[s]
        theta = -(cee * Dyadic.of(padded))
        for k in range(len(modes.patterns)):
            if not R[s][k]:
                continue
            E = None
            for t, w in R[s][k]:
                E = w * exact_P[t] if E is None else E + w * exact_P[t]
            AB = Dyadic.of(np.concatenate([modes.A[s, k], modes.B[s, k]], axis=1))
            theta = theta + p[s][k] * (AB.T @ E @ AB)
        if not exact_psd(theta):
            return False
    return not all(exact_psd(-Dyadic.of(Ps)) for Ps in P)


def _information_map(modes: DesignModes, K: np.ndarray):
    """``X -> L_K(X)`` (module docstring) in floats, and its dense matrix on row-major vec (S N^2 square)."""
    closed = modes.A - modes.B @ K[:, None]                                     # (S, D, N, N)
    weight = modes.p[:, :, None] * modes.R                                      # (S, D, S)

    def apply(X: np.ndarray) -> np.ndarray:
        Y = closed @ X[:, None] @ closed.mT                                     # (S, D, N, N)
        return np.einsum("sdt,sdij->tij", weight, Y)

    def matrix() -> np.ndarray:
        S, D, N, _ = closed.shape
        kron = np.einsum("sdij,sdkl->sdikjl", closed, closed).reshape(S, D, N * N, N * N)
        return np.einsum("sdt,sdab->tasb", weight, kron).reshape(S * N * N, S * N * N)

    return apply, matrix


def strategy_inside_proved(modes: DesignModes, K: np.ndarray, X: np.ndarray | None, c: float,
                           transition: Dyadic | None = None) -> bool:
    """Does X (S, N, N) prove ``rho(L_K) < c`` exactly: every ``X_s > 0`` and ``c X_t - L_K(X)_t > 0``? Time
    O(S D (N^3 + S N^2)) integer operations.

    >>> m = design_modes([[2.0]], [[1.0]], [0.875], "zero")     # L_K(x) = a^2 (1 - mu) x = x / 2 for k = a
    >>> [strategy_inside_proved(m, np.full((1, 1, 1), 2.0), np.ones((1, 1, 1)), c) for c in (0.5 + 2.0 ** -50, 0.5)]
    [True, False]
    """
    if X is None or not (np.all(np.isfinite(X)) and np.all(np.isfinite(K))):
        return False
    X = 0.5 * (X + X.transpose(0, 2, 1))
    p, R = _exact_weights(modes, transition)
    exact_X = [Dyadic.of(Xs) for Xs in X]
    if not all(exact_psd(Xs, strict=True) for Xs in exact_X):
        return False
    image: list[Dyadic | None] = [None] * modes.modes
    for s in range(modes.modes):
        K_s = Dyadic.of(K[s])
        for k in range(len(modes.patterns)):
            closed = Dyadic.of(modes.A[s, k]) - Dyadic.of(modes.B[s, k]) @ K_s
            Y = p[s][k] * (closed @ exact_X[s] @ closed.T)
            for t, w in R[s][k]:
                image[t] = w * Y if image[t] is None else image[t] + w * Y
    cee = Dyadic.of(float(c))
    return all(exact_psd(cee * exact_X[t] - (image[t] if image[t] is not None else Dyadic.of(np.zeros(X.shape[1:]))),
                         strict=True) for t in range(modes.modes))


def _witness(modes: DesignModes, K: np.ndarray, radius: float, c: float) -> np.ndarray | None:
    """X solving ``X = L_K(X) / r + I``, r the midpoint of the radius and c (certificates.stability_witness over
    the information modes); None where the radius is not below c or the solve fails. O((S N^2)^3)."""
    if not (np.isfinite(radius) and radius < c):
        return None
    r = max(0.5 * (max(radius, 0.0) + c), 0.5 * c)
    apply, matrix = _information_map(modes, K)
    N = modes.A.shape[-1]
    try:
        return solve_fixed_point(lambda X: apply(X) / r, lambda: matrix() / r,
                                 np.broadcast_to(np.eye(N), (modes.modes, N, N)).copy(), "a stability witness")
    except (NumericalError, np.linalg.LinAlgError):
        return None


@dataclass(frozen=True)
class LeastRadius:
    """The homogeneous Bellman map's power iteration (`least_radius`): ``growth`` its estimate of the least radius
    over the strategy's laws (floats: evidence, not a verdict), ``P`` its normalised direction (an outside
    candidate), ``K`` the greedy law of P (an inside candidate where growth < 1), ``steps`` taken."""

    growth: float
    P: np.ndarray
    K: np.ndarray
    steps: int


def least_radius(modes: DesignModes, steps: int | None = None) -> LeastRadius:
    """The power iteration of the homogeneous Bellman map (no weights: ``P_s <- min_K L_K^*(P)_s``, the least
    radius over laws its growth), normalised, until the growth settles to `GROWTH_RTOL` or ``steps`` (default
    `HOMOGENEOUS_STEPS`). Converges at the map's spectral gap, not at the distance to the boundary, where the
    weighted DP crawls. O(steps S D (S N^2 + (N + r)^3)).

    >>> round(least_radius(design_modes([[2.0]], [[1.0]], [0.5], "hold")).growth, 9)   # a^2 (1 - mu)
    2.0
    """
    N = modes.A.shape[-1]
    P = np.broadcast_to(np.eye(N), (modes.modes, N, N)) / np.sqrt(modes.modes * N)
    zero_Omega, zero_psi = np.zeros((N, N)), np.zeros(modes.F.shape[2])
    growth, last, K = float("nan"), float("nan"), np.zeros((modes.modes, modes.B.shape[-1], N))
    limit = HOMOGENEOUS_STEPS if steps is None else steps
    taken, settled = 0, False
    with np.errstate(over="ignore", invalid="ignore"):
        for taken in range(1, limit + 1):  # noqa: B007 (the count is returned)
            K, P_next = modes.step(P, zero_Omega, zero_psi, least_squares=True)
            growth = frobenius(P_next)
            if not (np.isfinite(growth) and growth > 0):
                break
            P = P_next / growth
            if abs(growth - last) <= GROWTH_RTOL * growth:
                settled = True
                break
            last = growth
        K, _ = modes.step(P, zero_Omega, zero_psi, least_squares=True)
    if not settled and np.isfinite(growth) and np.all(np.isfinite(K)):
        # unsettled: a map that rounding keeps from vanishing (mu = 1: the deadbeat law's map is nilpotent, and
        # the normalised iterates are rounding noise) has no meaningful growth; its greedy law's own radius is an
        # upper bound on the least radius, computed by the engine
        try:
            growth = min(growth, modes.loop(K).radius())
        except NumericalError:
            pass
    found = LeastRadius(float(growth), P, K, taken)
    refined = _policy(modes, found) if np.isfinite(growth) else None
    return found if refined is None else refined


def _policy(modes: DesignModes, found: LeastRadius) -> LeastRadius | None:
    """The power iteration's eigenpair finished by a policy iteration: from its greedy law K, P the Perron
    eigenvector of ``L_K^*`` on symmetric tuples (chain_radius.symmetric_perron, lambda its root), K the greedy law
    of P, until P is the homogeneous Bellman map's eigenvector to `POLICY_RTOL`; None beyond `MAX_CERTIFIED_ROWS`
    rows or where it does not settle within `POLICY_STEPS`. Where the map's spectral gap is small (hold's held
    input, at the boundary) the power iteration converges slowly from above; the policy iteration does not.
    O(POLICY_STEPS (S N^2)^3)."""
    S, N = modes.modes, modes.A.shape[-1]
    if S * N * N > MAX_CERTIFIED_ROWS:
        return None
    zero_Omega, zero_psi = np.zeros((N, N)), np.zeros(modes.F.shape[2])
    K = found.K
    with np.errstate(all="ignore"):
        for step in range(1, POLICY_STEPS + 1):
            if not np.all(np.isfinite(K)):
                return None
            pair = symmetric_perron(_information_map(modes, K)[1]().T, S, N)
            if pair is None:
                return None
            lam, P = pair[0], pair[1] / frobenius(pair[1])
            try:
                K, image = modes.step(P, zero_Omega, zero_psi, least_squares=True)
            except NumericalError:
                return None
            if lam > 0 and frobenius(image - lam * P) <= POLICY_RTOL * lam:
                return LeastRadius(float(lam), P, K, found.steps + step)
    return None


def _stein(modes: DesignModes, K: np.ndarray, c: float) -> np.ndarray | None:
    """S (S, N, N) with ``c S - L_K^*(S) = I`` blockwise (the information map's adjoint, its dense matrix
    transposed): the tilt of an outside candidate, whose Theta gains ``t (c S - L_K^*(S)) = t I`` on ``[x; -K_s x]``
    (certificates.tilted's argument over the modes; K the law minimising at P, or 0 for the open loop). None beyond
    `MAX_CERTIFIED_ROWS` rows or where the solve fails. O((S N^2)^3)."""
    rows, N = modes.modes * modes.A.shape[-1] ** 2, modes.A.shape[-1]
    if rows > MAX_CERTIFIED_ROWS or not np.all(np.isfinite(K)):
        return None
    with np.errstate(all="ignore"):
        try:
            S = np.linalg.solve(c * np.eye(rows) - _information_map(modes, K)[1]().T,
                                np.tile(np.eye(N).ravel(), modes.modes)).reshape(modes.modes, N, N)
        except np.linalg.LinAlgError:
            return None
    return 0.5 * (S + S.transpose(0, 2, 1))


def _tilted_outside(modes: DesignModes, P: np.ndarray, found: LeastRadius,
                    transition: Dyadic | None) -> tuple[float, np.ndarray] | None:
    """``(c, Q)``: a tilt Q of P or P snapped (certificates.tilted_by, the least tilt first) by a Stein solution
    (`_stein`: the closed loop of the greedy law at P, then the open loop) that proves every law's radius >= c >= 1
    exactly, or None. The c tried: halfway between 1 and the growth lambda where lambda > 1 (a tilt spends part of
    the margin, and the Stein equation at c = 1 may have no solution: an input held on a sure loss), then 1. A
    rank-deficient direction (hold's and the buffer's: the held input or the plan's entries a loss leaves to play)
    proves its bound only with its exact kernel, which the rounding misses; tilted, Theta is definite there by a
    margin the rounding cannot undo. At most 2 c x 2 S x 18 exact checks."""
    tries = ([1.0 + 0.5 * (found.growth - 1.0)] if found.growth > 1.0 else []) + [1.0]
    for c in tries:
        for K in (found.K, np.zeros_like(found.K)):
            S = _stein(modes, K, c)
            for Q in (P, *snapped(P)):
                for tilted_Q in reversed(tilted_by(Q, S)):
                    if strategy_outside_proved(modes, tilted_Q, c, transition):
                        return c, tilted_Q
    return None


def _never_delivers(modes: DesignModes) -> list[np.ndarray]:
    """A holding strategy's candidates (hold, buffer:L:hold) where an actuator never delivers in any channel state:
    ``e_w e_w'`` on the input it holds (its memory's last entry) in every mode (``w+ = w`` whatever the law on every
    loss: Theta = 0)."""
    if not (modes.actuator.kind == "hold" or modes.actuator.exhausted == "hold"):
        return []
    n, m = modes.embed.shape[1], modes.patterns.shape[1]
    width = (modes.A.shape[-1] - n) // m
    out = []
    for i in np.flatnonzero(np.all(modes.h == 0.0, axis=0)):
        P = np.zeros((modes.modes, *modes.A.shape[-2:]))
        P[:, n + (i + 1) * width - 1, n + (i + 1) * width - 1] = 1.0
        out.append(P)
    return out


def actuator_membership(system: System, actuator: str | Actuator = "zero",
                        mu: npt.ArrayLike | None = None, protocol: str = "tcp") -> Membership:
    """Is ``mu`` (default: the system's stationary channel, or its chain) in the region of ``actuator``? A
    `Membership` (module docstring): "stable" with the DP law's gains (S, r, N) and radius, "unstable" with the
    certificate tuple P, or "undecided" with the reason. ``forms``: (("dp", verdict),). ``protocol="udp"``: where a
    UDP-like controller can run the TCP-like laws (`.actuator_design.check_protocol`), the region is theirs; an
    "unstable" certificate bounds every causal law, whatever it knows (Theta_s >= 0 holds for every input). Time:
    `actuator_dp` plus the exact checks, O(S D (N + r)^3) integer operations, and the witness's dense solve
    O((S N^2)^3).

    Raises
    ------
    UnobservedModeError
        Field ``protocol``: a UDP-like request whose laws are not computed (`.actuator_design.check_protocol`).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> [actuator_membership(s, a, [mu]).verdict for a in ("zero", "hold") for mu in (0.7, 0.8)]
    ['unstable', 'stable', 'unstable', 'stable']
    """
    system = check_system(system)
    strategy = check_protocol(system, actuator, protocol, mu)
    chain = system.channel if system.channel is not None and mu is None else None
    channel = chain if chain is not None else (stationary_channel(system) if mu is None else mu)
    modes = design_modes(system.A, system.B, channel, strategy)
    rates = np.asarray(modes.h if chain is not None else channel, dtype=float)
    transition = exact_transition(chain) if isinstance(chain, MarkovChannel) else None
    rows = modes.modes * modes.A.shape[-1] ** 2

    def verdict(kind: str, gain=None, radius=float("nan"), certificate=None, margin=float("nan"), reason=""):
        return Membership(rates, kind, gain, radius, certificate, margin, (("dp", kind),), reason)

    if rows > MAX_CERTIFIED_ROWS:
        return verdict("undecided", reason=f"{strategy}'s information map has {rows} rows, beyond the "
                                           f"{MAX_CERTIFIED_ROWS} of an exact certificate: use a shorter buffer")
    for P in _never_delivers(modes):
        if strategy_outside_proved(modes, P, 1.0, transition):
            return verdict("unstable", certificate=P, margin=0.0)
    found = least_radius(modes)
    c = 1.0 - MEAN_SQUARE_MARGIN
    if found.growth < 1.0:
        laws = [found.K]
        weighted = None if chain is not None else channel
        try:
            laws.append(actuator_dp(system, strategy, weighted, max_iter=_DP_STEPS).K)
        except NumericalError:
            try:
                laws.append(actuator_dp_finite(system, _DP_STEPS, strategy, weighted)[0][0])
            except NumericalError:
                pass
        for K in laws:
            try:
                radius = modes.loop(K).radius()
            except NumericalError:
                continue
            if strategy_inside_proved(modes, K, _witness(modes, K, radius, c), c, transition):
                return verdict("stable", gain=K, radius=radius)
    if found.growth >= c:       # at the boundary to rounding both are tried: the float growth decides neither
        P = found.P / max(float(np.abs(found.P).max(initial=0.0)), np.finfo(float).tiny)
        for Q in (P, *snapped(P), *(np.round(P * 2.0 ** bits) / 2.0 ** bits for bits in _ROUNDED_BITS)):
            if strategy_outside_proved(modes, Q, 1.0, transition):
                return verdict("unstable", certificate=Q, margin=0.0)
        proved = _tilted_outside(modes, P, found, transition)
        if proved is not None:
            return verdict("unstable", certificate=proved[1], margin=proved[0] - 1.0)
    return verdict("undecided", reason=f"the least radius over {strategy}'s laws is about {found.growth:.9g} "
                                       "(floats), but neither a law's witness below 1 nor the map's direction checks "
                                       "in exact arithmetic")


def actuator_critical(system: System, actuator: str | Actuator = "zero", direction: npt.ArrayLike | None = None,
                      tol: float = CRITICAL_MU_TOL, protocol: str = "tcp") -> CriticalPoint:
    """The critical mu of a strategy along ``mu = t * direction`` (default all ones): on Bernoulli links the
    delivery probabilities ``t * direction``; behind the system's Gilbert–Elliott chain its mean rates (the chain
    at each rate with its burstiness and h kept, markov_region.chain_at_rate; t up to ``min_i h_good_i /
    direction_i``), offered only where the region is proved monotone along the ray (markov_region.
    critical_rate_unproved: ``h_bad = 0`` and burstiness >= 0; the thinning argument of docs/mathematics.md holds for
    every strategy, nothing sent being a loss). Bisection in t on the least radius over the strategy's laws
    (`least_radius`, floats; the region is monotone, module docstring) to a bracket ``[lower, t]`` of width tol, then
    both ends decided by `actuator_membership`: ``inside`` at t ("stable": a law proved exactly), ``outside`` at
    lower ("unstable" with its exact certificate, or "undecided" with the reason). Where the float crossing's side is
    undecided (a direction whose certificate margin vanishes there), ``lower`` steps down by tol times powers of
    `_STEP_DOWN` to the first point proved unstable (at most `_STEPS_DOWN` steps), and ``note`` says how far below the
    crossing it lies (the two-actuator hold along the diagonal: 6.5e-5); where none is proved (the two-actuator
    buffer's rank-one direction, whose tilt the unreached plan entries make indefinite), ``lower`` stays the float
    crossing, ``outside`` undecided and the note says so: then only ``t`` is evidence. ``t`` is inf when even the
    ray's end is not below 1, 0.0 when mu = 0 is. ``protocol``: as `actuator_membership`. Time O(log2(1 / tol))
    power iterations plus two memberships.

    Raises
    ------
    InputError
        A bad direction or tol; behind a chain: not two-state, or outside the monotonicity proof (the reason).
    UnobservedModeError
        Field ``protocol``: a UDP-like request whose laws are not computed (`.actuator_design.check_protocol`).
    NumericalError
        The least radius is not finite at a point of the ray; or the ray's end (floats: no law stabilises) is not
        proved unstable, or mu = 0 (floats: stable) is not proved stable: the end's membership and its reason.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> point = actuator_critical(s, "buffer:2", tol=1e-6)      # 1 - 1/a^2, as for zero
    >>> bool(point.lower <= 0.75 <= point.t <= point.lower + 1e-6), point.inside.verdict, point.outside.verdict
    (True, 'stable', 'unstable')
    """
    system = check_system(system)
    strategy = check_protocol(system, actuator, protocol, None if system.channel is not None else np.ones(system.m))
    d = np.asarray(np.ones(system.m) if direction is None else direction, dtype=float).reshape(-1)
    if d.shape != (system.m,) or np.any(d < 0) or not np.any(d > 0) or not np.all(np.isfinite(d)):
        raise InputError("direction", f"expected {system.m} nonnegative numbers, not all zero")
    if not tol > 0:
        raise InputError("tol", f"expected a positive width, found {tol!r}")
    channel_at, end = _ray(system, d)

    def below(t: float) -> bool:
        growth = least_radius(design_modes(system.A, system.B, channel_at(t), strategy)).growth
        if not np.isfinite(growth):
            raise NumericalError(f"critical mu ({strategy}): the least radius at mu = {(t * d).tolist()} is not "
                                 "finite")
        return growth < 1.0 - MEAN_SQUARE_MARGIN

    def member(t: float) -> Membership:
        channel = channel_at(t)
        if isinstance(channel, MarkovChannel):
            return actuator_membership(system.with_channel(channel), strategy, protocol=protocol)
        return actuator_membership(system, strategy, channel, protocol=protocol)

    lo, hi = 0.0, end
    if not below(hi):
        end = member(hi)
        if end.verdict != "unstable":   # floats say no law stabilises; only a certificate may say it
            raise NumericalError(f"critical mu ({strategy}): the ray's end mu = {(hi * d).tolist()} is "
                                 f"{end.verdict} ({end.reason or 'a law proved stable there, the floats disagree'})")
        return CriticalPoint(str(strategy), d, float("inf"), hi, None, end)
    if below(lo):
        start = member(lo)
        if start.verdict != "stable":
            raise NumericalError(f"critical mu ({strategy}): mu = 0 is {start.verdict} ({start.reason})")
        return CriticalPoint(str(strategy), d, 0.0, 0.0, start, None)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        lo, hi = (lo, mid) if below(mid) else (mid, hi)
    outside, note, crossing, step = member(lo), "", lo, tol
    for _ in range(_STEPS_DOWN if outside.verdict == "undecided" else 0):   # the crossing's side undecided
        step *= _STEP_DOWN
        lo = max(crossing - step, 0.0)
        below_member = member(lo)
        if below_member.verdict == "unstable":
            outside = below_member
            note = (f"the lower end is proved {crossing - lo:.3g} below the float crossing {crossing!r} (between them "
                    "no certificate checks: the direction's margin vanishes at the boundary)")
            break
        if below_member.verdict == "stable" or lo == 0.0:   # floats said unstable: not a proof either way
            break
    if outside.verdict == "undecided":
        lo = crossing
        note = (f"no point within {step:.3g} below the float crossing {crossing!r} could be proved unstable: the "
                "lower end is a float estimate" if step > tol else "")
    return CriticalPoint(str(strategy), d, hi, lo, member(hi), outside, note)


def _ray(system: System, d: np.ndarray):
    """``(channel_at, end)``: the channel at ``t`` on the ray (Bernoulli ``t d``, or the system's chain at mean rates
    ``t d``, markov_region.chain_at_rate) and the ray's end in t.

    Raises
    ------
    InputError
        Behind a chain with other than two states, or one outside the monotonicity proof (critical_rate_unproved).
    """
    chain = system.channel
    if chain is None:
        return (lambda t: t * d), 1.0 / float(d.max())
    if not chain.two_state:
        raise InputError("channel", f"the critical mean rate is defined along the Gilbert-Elliott family (two states, "
                                    f"burstiness kept); this channel's chains have {list(chain.sizes)} states")
    reason = critical_rate_unproved(chain)
    if reason is not None:
        raise InputError("channel", reason)
    end = float(np.min(chain.h_good[d > 0] / d[d > 0]))
    return (lambda t: chain_at_rate(chain, np.minimum(t * d, chain.h_good))), end
