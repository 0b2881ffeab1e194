"""The exact O(N) backward recursion for both protocols (DESIGN.md §2).

Both expected costs are deterministic LQ problems in the mean state

.. math:: \\hat x_{t+1} = A \\hat x_t + B M_t u_t,

with stage input weight ``M_t Psi_t`` and, for the UDP-like protocol, the extra
diagonal weight ``diag(Omega_g)_t M_t (I - M_t)``, where ``diag(Omega_g)_t =
diag(B' S_t B)`` and ``S_t = sum_{s>t} (A^{s-t-1})' Omega_s A^{s-t-1}`` is a
backward Lyapunov sum. The Hessian of stage t factors as ``M_t G_t`` with

.. math:: G_t = \\Psi_t + D_t + B' P_{t+1} B M_t, \\qquad D_t = \\mathrm{diag}(B'S_tB)(I - M_t)
   \\ (\\text{UDP}),\\ 0\\ (\\text{TCP}),

which is invertible even when some mu = 0; ``u_t = -G_t^{-1} B' P_{t+1} A \\hat x_t`` is then
the same minimiser as the paper's dense law ``-G^{-1} Omega_gp x`` (Theorem 1).

Time O(N (n^3 + m^3)), memory O(N n m) for the gains; no (N n)×(N m) matrix is formed.

This module holds the algebra once, batched over a leading axis (a single point is a batch of one,
as scipy.linalg's solvers batch; [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step] also takes the point itself,
as 2-D arrays, by the same code): [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step] (the Theorem-1 step, also
the closed-loop DP's and the Markov jump system's), `backward_batch` (N of them), `rollout_batch` /
`mean_states` (the mean state forward) and `forward_cost` (the referee every closed form is
checked against). [`backward_pass`][packetloss_cvx.lq.recursion.backward_pass],
[`mean_trajectory`][packetloss_cvx.lq.recursion.mean_trajectory] and `recursion_cost` are their one-point forms.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import NumericalError
from ..linalg import check_finite, lapack, lapack_dgesv
from ..model.protocols import check_protocol
from ..model.system import System
from ..tolerances import PLAN_COST_RTOL, STATIONARY_RTOL
from .roundoff import UNIT_ROUNDOFF, gamma, rollout_cost_error
from .settling import STATIONARY_RUN, all_steps_equal, leading_run, settled, spectral_radius, stationary_close
from .settling import drift as _drift
from .structure import Structure, condition_from, lyapunov_weights, structure_of

__all__ = [
    "FLAT_MIN", "STATIONARY_RUN", "backward_batch", "backward_pass", "check_plan_cost", "condition_estimate",
    "forward_cost", "input_weight", "leading_run", "lyapunov_cross_weights", "mean_states", "mean_trajectory",
    "optimal_plan", "overflow_error", "plan_cost", "recursion_cost", "riccati_step", "rollout_batch",
    "stationary_close", "states_by_powers", "udp_variance_weights", "weight_head",
]

#: What can carry an exact cost past 1e308 (the overflow does not say which: a stable plant with entries of 1e300
#: overflows as surely as an unstable one over a long horizon), and what to do about it.
OVERFLOW_CAUSES = ("entries of A, B, the weights, x0 or the noise that large, or the open-loop growth of an unstable "
                   "plant over this horizon")
OVERFLOW_ADVICE = "rescale the model's units, shorten the horizon or stabilise the plant"

#: From this many points on, each step's products are one (points k)×k by k×l product instead of ``points`` small
#: ones.
FLAT_MIN = 64


def _finite(name: str, value: np.ndarray | float, protocol: str) -> None:
    check_finite(name, value, why=f"the exact {protocol}-like expected cost exceeds the double-precision range, "
                 f"1e308: {OVERFLOW_CAUSES}", advice=OVERFLOW_ADVICE)


def udp_variance_weights(system: System) -> tuple[np.ndarray, float]:
    """The diagonal of Omega_g per step and the noise term tr(Omega_l Sigma_W).

    Omega_d (I - Vbar) is the loss-variance term of the UDP-like law, eq:opt-law-2.

    Returns ``(d, noise)`` with ``d[t, i] = (B' S_t B)_{ii}`` and
    ``noise = sum_t tr(S_t Sigma_W)``. Time O(N n^3), memory O(N m), the first time for a system
    structure: kept on its `Structure` (``d`` read-only; it depends on neither
    mu nor x0).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> d, noise = udp_variance_weights(s)         # S_1 = 1, S_0 = 1 + A' S_1 A = 5
    >>> d.ravel().tolist(), noise
    ([5.0, 1.0], 0.0)
    >>> from packetloss_cvx.lq.prediction import prediction
    >>> bool(np.allclose(d.ravel(), prediction(s).Omega_d))    # the dense diagonal of Omega_g
    True
    """
    return structure_of(system).variance_weights


def lyapunov_cross_weights(system: System) -> tuple[np.ndarray, float, np.ndarray]:
    """`udp_variance_weights` ``(d, noise)`` with the products ``B' S_t A`` (N, m, n) of the same backward
    Lyapunov sum ``S_t = Omega_{t+1} + A' S_{t+1} A``, which the exact cost under Markov losses pairs with the
    state-chain correlations (markov/augmented.py: row i of its cross term is ``b_i' S_t A``). One kernel for both
    (`lyapunov_weights`): time O(N n^3 + N m n^2), memory O(N m n); not kept (d is,
    on the structure).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> d, noise, BSA = lyapunov_cross_weights(s)      # S_1 = 1, S_0 = 5: B'S_tA = 2 S_t
    >>> d.ravel().tolist(), BSA.ravel().tolist()
    ([5.0, 1.0], [10.0, 2.0])
    """
    return lyapunov_weights(structure_of(system), cross=True)


def weight_head(system: System | Structure) -> np.ndarray:
    """The leading state weights equal to the first, ``state_weights[:h + 1]`` (a read-only view; all N for a
    time-invariant weight): `weight_head`. O(1) after the first call for
    a structure.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weights=[[1.0], [1.0], [2.0]], input_weight=[1.0],
    ...            mu=[1.0], x0=[1.0])
    >>> len(weight_head(s)), weight_head(s.with_mu([0.5])) is weight_head(s)    # Omega_1 = Omega_2 != Omega_3
    (2, True)
    """
    return structure_of(system).weight_head


def _near(change: np.ndarray, size: np.ndarray) -> bool:
    """A necessary condition of `settled` with a contraction q >= 0.01 (whose geometric factor
    q / (1 - q) is then at least 1/99): change <= 100 STATIONARY_RTOL size at every point. O(points)."""
    return bool((change <= 100.0 * STATIONARY_RTOL * size).all())


def condition_estimate(system: System, weights: tuple[np.ndarray, float] | None = None) -> float:
    """``(trace Omega_g + max Psi) / min Psi``: an upper estimate of the spread of curvatures of
    both expected costs (trace Omega_g bounds its largest eigenvalue, min Psi bounds the smallest
    curvature per delivered input). The dense formulas lose about ``log10(estimate * eps)``
    digits; the recursion does not depend on it. ``inf`` when Omega_g overflows.
    Time O(N n^3) (the Lyapunov sums of `udp_variance_weights`), no dense matrix; O(1) once kept
    on the system's structure (with ``weights`` None or the system's own).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> condition_estimate(s)                      # (trace Omega_g + max Psi) / min Psi = (5 + 1 + 1) / 1
    7.0
    """
    structure = structure_of(system)
    if weights is None or weights is structure.variance_weights:                # the system's own weights
        return structure.condition
    return condition_from(structure, weights[0])


def input_weight(structure: System | Structure, protocol: str, mu: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The stage input weight of the mean-state LQ problem per channel and step, ``(..., N, m)`` like
    ``mu``: ``psi_t + [UDP] (1 - mu_t) d_t`` where ``mu_t < 1`` (a perfect channel adds nothing, even where
    ``d`` overflowed). It is the diagonal Theorem 1 adds to ``B'PB M`` in G, and the weight of ``mu u^2`` in
    the forward cost. O(size of mu).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[2.0], mu=[0.5], x0=[1.0])
    >>> input_weight(s, "udp", np.array([[0.5]]), np.array([[3.0]])).tolist()     # 2 + 0.5 * 3
    [[3.5]]
    """
    psi = structure.input_weights
    if protocol == "tcp":
        return np.broadcast_to(psi, mu.shape)
    with np.errstate(over="ignore", invalid="ignore"):
        return psi + np.where(mu < 1.0, d * (1.0 - mu), 0.0)


def overflow_error(name: str, protocol: str) -> NumericalError:
    """The error of an exact cost beyond the double range (`OVERFLOW_CAUSES`). O(1).

    Examples
    --------
    >>> str(overflow_error("the cost-to-go matrix", "tcp")).split(" (")[0]
    'the cost-to-go matrix overflowed'
    """
    return NumericalError(f"{name} overflowed (the exact {protocol}-like expected cost exceeds the double-precision "
                          f"range, 1e308: {OVERFLOW_CAUSES}); {OVERFLOW_ADVICE}")


def riccati_step(P: np.ndarray, A: np.ndarray, B: np.ndarray, mu: np.ndarray, added: np.ndarray,
                 Omega: np.ndarray | None = None, *, variance: bool = False,
                 least_squares: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """One backward step of Theorem 1's recursion for a batch of points or for one point: the Hessian
    factor, the gain and the previous cost-to-go (eq:control-laws).

    .. math:: G = B'PB M + \\mathrm{diag}(a)\\ [+\\ \\mathrm{diag}((1 - \\mu) \\mathrm{diag}(B'PB))],\\quad
              K = G^{-1} B'PA,\\quad P^- = A'PA - (B'PA)' M K + \\Omega

    with ``M = diag(mu)`` and ``a = added`` (``psi``, plus ``(1 - mu) d`` for the open-loop UDP-like law:
    `input_weight`). ``variance=True`` adds the loss variance weighted by the cost-to-go itself: the
    closed-loop DP's modified Riccati map (simulation.riccati) and, per mode, the Markov jump system's coupled
    equations (markov.mjls, h = mu). The Hessian of the step is ``M G`` (invertible G even where mu = 0).

    ``least_squares=True`` solves the Hessian ``M G`` itself by its minimum-norm least-squares solution (pinv with
    lstsq's cutoff, ``eps m s_max``), for the homogeneous maps whose Hessian may be singular (no weights:
    simulation.region's modified Riccati map); a point whose Hessian is not finite gets K = nan. ``P_prev`` is the
    same expression, ``A'PA - (MB'PA)'K``.

    Parameters: ``P`` (points, n, n) symmetric, ``mu`` and ``added`` (points, m), or one point: ``P`` (n, n),
    ``mu`` and ``added`` (m,); ``Omega`` (n, n) or None. Returns ``(K, P_prev)``, (points, m, n) and (points, n, n)
    (one point: (m, n) and (n, n)), P_prev symmetrised. Raises ``numpy.linalg.LinAlgError`` where a G is singular
    (callers name the cause). The algebra is written once for both ranks (``@``-style products: ``np.dot`` on a point,
    ``np.matmul`` on a stack; the last two axes transposed; mu broadcast as G's row). A batch of one is taken as
    the point: two-dimensional products and LAPACK's gesv without the stacked wrappers' overhead,
    the same BLAS calls in the same order as a point of a stack, so the same floats. From ``FLAT_MIN`` points on,
    the products B'PB, B'PA, A'PA are one (points n)×n by n×m (n×n) product each (`_flat_products`).
    Time O(points (n^3 + m^3)); a point's answer does not depend on the batch it is in below ``FLAT_MIN`` points.

    Examples
    --------
    >>> K, P = riccati_step(np.ones((1, 1, 1)), np.eye(1), np.eye(1), np.ones((1, 1)), np.ones((1, 1)), np.eye(1))
    >>> float(K[0, 0, 0]), float(P[0, 0, 0])    # scalar DARE step: G = 2, K = 1/2, P = 1 + 1 - 1/2
    (0.5, 1.5)
    >>> K, P = riccati_step(np.ones((1, 1)), np.eye(1), np.eye(1), np.ones(1), np.ones(1), np.eye(1))   # one point
    >>> K.tolist(), P.tolist()
    ([[0.5]], [[1.5]])
    """
    if P.ndim == 3 and P.shape[0] == 1 and not least_squares:          # a batch of one is the point
        K, P_prev = riccati_step(P[0], A, B, mu[0], added[0], Omega, variance=variance)
        return K[None], P_prev[None]
    m = B.shape[1]
    mm = np.dot if P.ndim == 2 else np.matmul          # np.dot: a 2-D product without matmul's stack set-up
    if P.ndim == 3 and P.shape[0] >= FLAT_MIN:
        BPB, rhs, APA = _flat_products(P, A, B)
    else:                 # P B once, then B'(P B), (P B)'A and A'(P A)
        PB = mm(P, B)
        BPB = mm(B.T, PB)
        rhs = mm(PB.swapaxes(-1, -2), A)
        APA = mm(A.T, mm(P, A))
    row = mu[..., None, :]                                                 # mu as a row: G's columns
    G = np.multiply(BPB, row, order="C")
    diagonal = G.reshape(G.shape[:-2] + (m * m,))[..., :: m + 1]          # a view: G's diagonal
    diagonal += added
    if variance:
        diagonal += (1.0 - mu) * np.diagonal(BPB, axis1=-2, axis2=-1)
    if least_squares:
        K = _least_squares(G, rhs, mu)
    elif G.ndim == 3:
        K = np.linalg.solve(G, rhs)
    else:                                        # LAPACK's gesv directly: no stacked-solve wrapper for one point
        _, _, K, info = lapack_dgesv()(G, rhs)
        if info != 0:
            raise np.linalg.LinAlgError("singular G")
    P_prev = APA - mm(rhs.swapaxes(-1, -2) * row, K)
    if Omega is not None:
        P_prev += Omega
    P_prev += P_prev.swapaxes(-1, -2)                                      # numpy buffers the overlap
    P_prev *= 0.5
    return K, P_prev


def _flat_products(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """B'PB, B'PA and A'PA of a stack P (points, n, n) as one (points n)×n by n×m (n×n) product each instead of
    ``points`` small ones: [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step]'s products for points >=
    FLAT_MIN. O(points n^2 (n + m))."""
    points, n, m = P.shape[0], A.shape[0], B.shape[1]
    PBT = (P.reshape(points * n, n) @ B).reshape(points, n, m).transpose(0, 2, 1).reshape(points * m, n)
    BPB = (PBT @ B).reshape(points, m, m).transpose(0, 2, 1)
    rhs = (PBT @ A).reshape(points, m, n)
    APA = (P.reshape(points * n, n) @ A).reshape(points, n, n).transpose(0, 2, 1).reshape(points * n, n) @ A
    return BPB, rhs, APA.reshape(points, n, n).transpose(0, 2, 1)                # A'(P A)


def _least_squares(G: np.ndarray, rhs: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The minimum-norm least-squares solution of ``H K = M rhs``, H = M G possibly singular (pinv with lstsq's
    cutoff ``eps m s_max``), per point of a stack; nan where H is not finite. O(k (m^3 + m^2 n))."""
    m = G.shape[-1]
    H = G * mu[..., :, None]
    finite = np.all(np.isfinite(H), axis=(-2, -1))
    K = np.full(rhs.shape, np.nan)
    K[finite] = np.linalg.pinv(H[finite], rcond=np.finfo(float).eps * m) @ (rhs * mu[..., :, None])[finite]
    return K


def backward_batch(structure: Structure, protocol: str, mu: np.ndarray,
                   added: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gains K (points, N, m, n) and cost-to-go P_0 (points, n, n) (without Q) of the schedules ``mu`` (points, N, m),
    ``added`` (points, N, m) the diagonal each step's G gets (`input_weight`): N calls of
    [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step] from ``P_N = Omega_N`` (a stationary tail closed, and for
    one point whose steps are one map, the steps before it by doubling: `_doubled_backward`). O(points N (n^3 + m^3));
    NumericalError (`overflow_error`) where a step's G is singular or anything overflows.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> K, P0 = backward_batch(structure_of(s), "tcp", np.array([[[1.0]]]), np.array([[[1.0]]]))   # K = 1/2, P0 = 1/2
    >>> K.ravel().tolist(), P0.ravel().tolist()
    ([0.5], [0.5])
    """
    K, Pm, _ = _backward(structure, protocol, mu, added)
    return K, Pm


def _backward(structure: Structure, protocol: str, mu: np.ndarray, added: np.ndarray,
              copies: bool = True) -> tuple[np.ndarray, np.ndarray, tuple[int, int] | None]:
    """`backward_batch`, and the run ``(1, b)`` of steps 1..b-1 whose gains are one copied gain when the
    pass closed its stationary tail (None otherwise), for the rollout (`_roll_out`) to take as it is. With
    ``copies`` False the run's gains after the first (K[:, 2:b]) are left unwritten, for a caller that reads
    only K[:, 1] of the run."""
    A, B, W, N = structure.A, structure.B, structure.state_weights, structure.horizon
    n, m = structure.n, structure.m
    points = mu.shape[0]
    K = np.empty((N, points, m, n))
    Pm = np.empty((points, n, n))
    Pm[:] = W[N - 1]
    settle = N >= 2 * STATIONARY_RUN                    # only long horizons are worth the checks
    # one point whose steps 1..N-1 are one map: once its drift predicts more than DOUBLING_AFTER steps to
    # settle, the rest of the pass by doubling (_doubled_backward)
    doubling = settle and _one_map(structure, mu, added)
    # steps 1..head share mu, the added diagonal and Omega: only there can a tail close, so only there is the
    # drift weighed (an unstable plant's UDP-like pass, whose added diagonal grows at every step, never is)
    head = min(leading_run(mu[:, 1:]), leading_run(added[:, 1:]), len(structure.weight_head)) if settle else 0
    q = None             # the contraction per step, measured once the iterates are near settling
    run = None
    check, last = min(N - 9, head), None                # the next step whose drift is weighed; the last weighing
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for t in range(N - 1, -1, -1):
            try:
                K[t], new = riccati_step(Pm, A, B, mu[:, t], added[:, t], W[t - 1] if t > 0 else None)
                if settle and t == check and 2 <= t <= head:
                    drift = _drift(new, Pm)
                    excess = _excess(*drift)
                    if doubling and last is not None and _to_settle(excess, last, t) > DOUBLING_AFTER:
                        doubled = _doubled_backward(structure, mu, added, K[:, 0], copies, t, new[0], q)
                        if doubled is not None:
                            Pm, run = doubled
                            break
                        doubling = False                # not finite there: step by step, which says why
                    check, last = t - _wait(excess, last, t), (t, excess)
                    if excess <= 1.0 or _near(*drift):
                        q = _contraction(A, B, mu[:, t], K[t]) if q is None else q
                        if settled(*drift, q):
                            # steps 1..t are one map and P_t = P_{t-1} = ... = P_1 to rounding: one more
                            # step gives the gain of P_t for every step 1..t-1, then step 0 (no Omega)
                            K[1], Pm = riccati_step(new, A, B, mu[:, 1], added[:, 1], W[0])
                            if copies:
                                _repeat_first(K[1:t])
                            K[0], Pm = riccati_step(Pm, A, B, mu[:, 0], added[:, 0], None)
                            run = (1, t)
                            break
            except np.linalg.LinAlgError:
                raise overflow_error("the cost-to-go matrix", protocol) from None
            Pm = new
    computed = (K,) if run is None else (K[:2], K[run[1]:])          # the copies repeat K[1]
    if not (np.all(np.isfinite(Pm)) and all(np.all(np.isfinite(k)) for k in computed)):
        raise overflow_error("the cost-to-go matrix", protocol)
    return K.transpose(1, 0, 2, 3), Pm, run


#: A backward pass of one map hands over to :func:`_doubled_backward` where it predicts more steps than this to
#: settle (:func:`_to_settle`).
DOUBLING_AFTER = 64
#: The chunk of :func:`_doubled_backward`: the cost-to-go is reached at every DOUBLING_CHUNK-th step by doubling,
#: then the steps between by DOUBLING_CHUNK batched Riccati steps.
DOUBLING_CHUNK = 8


def _one_map(structure: Structure, mu: np.ndarray, added: np.ndarray) -> bool:
    """Whether the backward pass of one point is one map at every step 1..N-1: the same channel and added diagonal
    there (finite), and one state weight at every step (the terminal one included). O(N (m + n^2)) at most."""
    return bool(mu.shape[0] == 1 and structure.time_invariant_weight and all_steps_equal(mu[:, 1:])
                and all_steps_equal(added[:, 1:]) and np.all(np.isfinite(added[:, 1])))


def _doubled_backward(structure: Structure, mu: np.ndarray, added: np.ndarray, K: np.ndarray, copies: bool, top: int,
                      P_top: np.ndarray, q: float | None) -> tuple[np.ndarray, tuple[int, int] | None] | None:
    """The rest of `_backward` of one point from step ``top`` down (``P_top``: its cost-to-go; q: the
    contraction if measured), where every step 1..top-1 is one Riccati map Phi (`_one_map`), without a
    Python step per step. Phi is the linear fractional map ``P -> Q + A'P (I + F F'P)^{-1} A`` with
    ``F = B (M diag(added)^{-1})^{1/2}`` (Woodbury on [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step]'s P^-),
    whose powers are again such maps (the structure-preserving doubling of Chu, Fan and Lin, Linear Algebra Appl. 396
    (2005) 55-80, here in square-root form: `_doubling`). The cost-to-go at every c-th step back from P_top (c =
    DOUBLING_CHUNK) comes from doubling, 2^k points at a time (`_power`); the c - 1 steps between them and every
    gain from c batched [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step] calls over those points
    (`_fine_steps`). The stationary tail closes at the first step whose drift `settled` accepts (the step-by-step pass
    weighs only some steps and closes at or after it; both are within STATIONARY_RTOL of the fixed point), as
    `_backward` closes it: K[1] from P_t, copies for steps 1..t-1, then step 0. Writes K[:top] (K: (N, m, n)); returns
    ``(P_0 (1, n, n), run)``, or None where anything is not finite (the step-by-step pass then goes on from
    ``top`` and raises the overflow where there is one). Agrees with the step-by-step pass to rounding: within 2.7e-14
    of an 80-bit pass (4.2e-14 under OPENBLAS_CORETYPE=Prescott) where the step-by-step one is within 8.3e-14 (8.6e-14)
    (the slowly converging plant, benchmarks/slow_plant.py). Time O(L (n^3 + m^3)) for a tail settling in L steps, in
    O(c + log L) batched calls; memory O(L n^2)."""
    A, B, Q = structure.A, structure.B, structure.state_weights[0]
    c = DOUBLING_CHUNK
    mu1, add1 = mu[:, 1], added[:, 1]                  # (1, m): the map of steps 1..N-1
    last = (top - 2) // c + 1                          # the c-th points j c <= top - 2 (step top - j c - 1 >= 1)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        try:
            maps = (A, B * np.sqrt(mu1[0] / add1[0]), Q)                   # Phi itself
            for _ in range(c.bit_length() - 1):
                maps = _doubling(*maps)                                    # Phi^c
            reach = 1                                                      # maps = Phi^(c reach)
            coarse = P_top[None]                                           # coarse[j] = P_{top - j c}
            floor = 1
            while True:
                J = coarse.shape[0]
                trigger = None
                if J > floor:                  # the first c-th point (past the last fine attempt) that looks settled
                    change, size = _drift(coarse[floor:], coarse[floor - 1:-1])
                    near = change <= 100.0 * STATIONARY_RTOL * size
                    if q is None and near.any():
                        gain, _ = riccati_step(coarse[floor + int(np.argmax(near))][None], A, B, mu1, add1, Q)
                        q = float(_contraction(A, B, mu1, gain)[0])
                    if q is not None and q < 1.0:      # the drift of c steps against that of the last one
                        hit = near & (change * (q / (1.0 - q ** c)) <= STATIONARY_RTOL * size)
                        trigger = floor + int(np.argmax(hit)) if hit.any() else None
                if trigger is None and J < last:
                    if reach < J:                      # doubled only when a power needs it, not after the last
                        maps, reach = _doubling(*maps), 2 * reach
                    coarse = np.concatenate([coarse, _power(*maps, coarse[:min(J, last - J)])])
                    continue
                used = J if trigger is None else trigger + 1
                q, t, Pt = _fine_steps(structure, coarse[:used], mu1, add1, K, q, top)
                if t is None and Pt is None:           # no step of that stretch settled: reach further
                    floor = used
                    continue
                break
            if t is None:                              # every step 1..top-1 computed: no stationary tail
                P1, run = Pt[None], None
            else:                                      # steps 1..t are one map and P_t = ... = P_1 to rounding
                K[1:2], P1 = riccati_step(Pt[None], A, B, mu1, add1, Q)
                if copies:
                    _repeat_first(K[1:t])
                run = (1, t)
            K[0:1], P0 = riccati_step(P1, A, B, mu[:, 0], added[:, 0], None)
        except np.linalg.LinAlgError:
            return None
    computed = K[:top] if run is None else K[np.r_[0, 1, run[1]:top]]
    if not (np.all(np.isfinite(P0)) and np.all(np.isfinite(computed))):
        return None
    return P0, run


def _power(A: np.ndarray, F: np.ndarray, H: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``H + A'P (I + F F'P)^{-1} A`` for a stack P (points, n, n): the doubled map of `_doubling` applied to each
    point, a [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step] with input matrix F and unit input weight.
    O(points n^3)."""
    r = F.shape[1]
    return riccati_step(P, A, F, np.ones((P.shape[0], r)), np.ones((P.shape[0], r)), H)[1]


def _fine_steps(structure: Structure, starts: np.ndarray, mu1: np.ndarray, add1: np.ndarray, K: np.ndarray,
                q: float | None, top: int) -> tuple[float | None, int | None, np.ndarray | None]:
    """The steps between the c-th points ``starts[j] = P_{top - j c}`` (J, n, n) of `_doubled_backward`: c
    batched [`riccati_step`][packetloss_cvx.lq.recursion.riccati_step] calls over the J points write the gains K_t of
    steps top-1 down to max(1, top - J c) into K. Returns ``(q, t, P_t)`` at the first step t >= 2 whose drift `settled`
    accepts with the contraction q (measured, if None, as `_backward` measures it: at the first step whose
    drift is near), ``(q, None, P_1)`` where none does and step 1 was reached, ``(q, None, None)`` otherwise.
    O(J c (n^3 + m^3)) in c calls."""
    A, B, Q, n, m = structure.A, structure.B, structure.state_weights[0], structure.n, structure.m
    c, J = DOUBLING_CHUNK, starts.shape[0]
    count = min(J * c, top - 1)                                # steps top-1 .. top-count
    Ps, Ks = np.empty((J, c, n, n)), np.empty((J, c, m, n))
    P, mus, adds = starts, np.repeat(mu1, J, axis=0), np.repeat(add1, J, axis=0)
    for i in range(c):
        Ks[:, i], Ps[:, i] = riccati_step(P, A, B, mus, adds, Q)
        P = Ps[:, i]
    seq = Ps.reshape(J * c, n, n)[:count]                      # seq[i] = P_{top-1-i}
    K[top - count:top] = Ks.reshape(J * c, m, n)[count - 1::-1]    # K_{top-1-i}, the gain of P_{top-i}
    change, size = _drift(seq, np.concatenate([starts[:1], seq[:-1]]))
    near = change <= 100.0 * STATIONARY_RTOL * size
    if q is None and near.any():
        q = float(_contraction(A, B, mu1, K[top - 1 - int(np.argmax(near))][None])[0])
    if q is not None and q < 1.0:
        settled = near & (change * (q / (1.0 - q)) <= STATIONARY_RTOL * size) & np.isfinite(size)
        settled[top - 1 - np.arange(count) < 2] = False
        if settled.any():
            i = int(np.argmax(settled))
            return q, top - 1 - i, seq[i]
    return q, None, (seq[top - 2] if count == top - 1 else None)


def _doubling(A: np.ndarray, F: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The map ``Phi(P) = H + A'P (I + F F'P)^{-1} A`` composed with itself, as the same kind of map (the doubling
    step of `_doubled_backward`). Phi is the Riccati step with input matrix F and unit input weight, whose
    gain at P = H is ``K = S^{-1} F'HA`` (S = I + F'HF = C C'); then ``Phi(Phi(P))`` has ``H_2 = Phi(H) = H + A'HA -
    (F'HA)'K``, ``A_2 = A (A - F K)`` and ``F_2 F_2' = F F' + A F S^{-1} F'A'``: the factor ``[F, A F C'^{-1}]``,
    compressed to n columns by a QR factorisation. One Cholesky factor of S serves the gain and the factor (one
    triangular solve for ``C^{-1} [F'HA, (A F)']``, one more for K), not a general solve of S besides. G = F F' is never
    formed: rounding G would give every direction some control, and the cost-to-go in the directions B reaches weakly is
    sensitive to it (3.9e-13 against 1.2e-14 relative on a rank-one B M, measured against an 80-bit pass). The
    factorisations are LAPACK's own (``dpotrf``, the triangular solve ``dtrtrs``, ``dgeqrf``): on n rows NumPy's
    wrappers cost several times their work. O(n^3); raises ``numpy.linalg.LinAlgError`` where S is not positive definite
    (a map that is not finite)."""
    n, r = A.shape[0], F.shape[1]
    HA = H @ A
    S = F.T @ (H @ F)
    S.flat[:: r + 1] += 1.0
    C, info = lapack("dpotrf")(S, lower=1, clean=1)               # S = C C'
    if info != 0:
        raise np.linalg.LinAlgError("S = I + F'HF is not positive definite")
    FHA_FA = F.T @ np.concatenate([HA, A.T], axis=1)              # [F'HA, (A F)']
    ZY, info = lapack("dtrtrs")(C, FHA_FA, lower=1)               # C^-1 [F'HA, (A F)']
    if info != 0:
        raise np.linalg.LinAlgError("singular Cholesky factor")
    K = lapack("dtrtrs")(C, ZY[:, :n], lower=1, trans=1)[0]       # S^-1 F'HA = C'^-1 (C^-1 F'HA)
    H2 = A.T @ HA - FHA_FA[:, :n].T @ K + H                        # Phi(H) = H + A'HA - (F'HA)' K
    H2 += H2.T
    H2 *= 0.5
    factor = np.concatenate([F, ZY[:, n:].T], axis=1)
    if factor.shape[1] > n:                                        # R of factor' = Q R: factor factor' = R'R
        qr = lapack("dgeqrf")(factor.T)[0]
        factor = np.triu(qr[:n]).T
    return A @ (A - F @ K), factor, H2


#: The most steps a backward pass lets pass between two weighings of its drift (:func:`_wait`).
MAX_WAIT = 8


def _wait(excess: float, last: tuple[int, float] | None, t: int) -> int:
    """How many steps a backward pass may go before weighing its drift again (1 to MAX_WAIT): the steps until
    ``excess`` (the largest change over `_near`'s bound), shrinking by the factor f per step seen since the
    ``last`` weighing (step, excess), meets the closing bound of `settled` with f for the contraction
    (``(1 - f) / (100 f)`` in units of the near bound). A pass that settles faster than that closes the few
    steps later; one that does not shrink is weighed every step. O(1)."""
    if last is None or not 0.0 < excess < math.inf or not 0.0 < last[1] < math.inf:
        return 1
    factor = (excess / last[1]) ** (1.0 / (last[0] - t))
    if not 0.0 < factor < 1.0:
        return 1
    target = (1.0 - factor) / (100.0 * factor)
    if excess <= target:
        return 1
    return int(min(MAX_WAIT, max(1.0, math.floor(math.log(excess / target) / -math.log(factor)))))


def _to_settle(excess: float, last: tuple[int, float], t: int) -> float:
    """The steps a backward pass still needs to settle, by `_wait`'s estimate: the excess shrinking by the
    factor f per step seen since the ``last`` weighing, until it meets the closing bound ``(1 - f) / (100 f)``;
    inf where it does not shrink. O(1)."""
    if not 0.0 < excess < math.inf or not 0.0 < last[1] < math.inf:
        return 0.0 if excess == 0.0 else math.inf
    factor = (excess / last[1]) ** (1.0 / (last[0] - t))
    if not 0.0 < factor < 1.0:
        return math.inf
    target = (1.0 - factor) / (100.0 * factor)
    return max(0.0, math.log(excess / target) / -math.log(factor))


def _excess(change: np.ndarray, size: np.ndarray) -> float:
    """The largest ``change / (100 STATIONARY_RTOL size)`` over a batch (`_near` holds where it is <= 1);
    nan where a size is 0 or not finite. O(points)."""
    return float((change / (100.0 * STATIONARY_RTOL * size)).max())


def _repeat_first(rows: np.ndarray) -> None:
    """``rows[1:] = rows[0]`` in place by doubling copies of contiguous blocks (log2 L copies of memory instead
    of L broadcast copies of one small block, each with NumPy's per-copy overhead). O(L k)."""
    L, done = rows.shape[0], 1
    while done < L:
        step = min(done, L - done)
        rows[done:done + step] = rows[:step]
        done += step


def _closed_loop(A: np.ndarray, B: np.ndarray, mu: np.ndarray, K: np.ndarray) -> np.ndarray:
    """The mean closed loop ``A - B M K`` of gains K (points, m, n) at channels mu (points, m), per point: the map the
    stationary closure's contraction is measured on (`_contraction`) and the rollout by powers takes
    (`_closed_run`). O(points n^2 m).

    Examples
    --------
    >>> _closed_loop(np.eye(1), np.eye(1), np.array([[0.5]]), np.array([[[1.0]]])).tolist()     # 1 - 0.5 * 1
    [[[0.5]]]
    """
    return A - np.matmul(B * mu[:, None, :], K)


def _contraction(A: np.ndarray, B: np.ndarray, mu: np.ndarray, K: np.ndarray) -> np.ndarray:
    """rho(A - B M K)^2 per point: the Riccati map's contraction per step near its fixed point (measured
    once the change is already below 100 STATIONARY_RTOL, where the gain has settled to 1e-12); inf where
    the loop is not finite. O(points n^3)."""
    with np.errstate(over="ignore", invalid="ignore"):
        loop = _closed_loop(A, B, mu, K)
        if not np.all(np.isfinite(loop)):
            return np.full(loop.shape[0], np.inf)
        return spectral_radius(loop) ** 2


def backward_pass(system: System, protocol: str,
                  weights: tuple[np.ndarray, float] | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Riccati recursion of the mean-state LQ problem: the laws of Theorem 1 (eq:control-laws), step by step.

    Returns ``(K, P0, noise)``: the gains ``K[t]`` (m×n, ``u_t = -K[t] xhat_t``),
    the cost-to-go matrix at step 0 (without Q) and the noise term. ``weights``: the result of
    `udp_variance_weights` if the caller has it. `backward_batch` on a batch of one.
    Time O(N (n^3 + m^3)), memory O(N m n).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> K, P0, noise = backward_pass(s, "udp")
    >>> # J_udp(u) = 0.5 (1 + u)^2 + 0.5 + 0.5 u^2 is least at u = -1/2, where it is 0.75
    >>> float(K[0, 0, 0]), float(P0[0, 0]), noise
    (0.5, 0.75, 0.0)
    """
    K, P0, noise, _ = _one_point_backward(system, structure_of(system), protocol, weights)
    return K, P0, noise


def _one_point_backward(system: System, structure: Structure, protocol: str,
                        weights: tuple[np.ndarray, float] | None,
                        copies: bool = True) -> tuple[np.ndarray, np.ndarray, float, tuple[int, int] | None]:
    """[`backward_pass`][packetloss_cvx.lq.recursion.backward_pass] (``structure``: the system's), and the run of copied
    gains its stationary tail closed (`_backward`)."""
    protocol = check_protocol(protocol)
    d, noise = structure.variance_weights if weights is None else weights
    mu = system.mu_schedule
    if protocol == "udp":
        _finite("diag(Omega_g)", d[mu < 1.0], protocol)
    _finite("the noise term tr(Omega_l Sigma_W)", noise, protocol)
    K, P0, run = _backward(structure, protocol, mu[None], input_weight(structure, protocol, mu, d)[None], copies)
    return K[0], P0[0], noise, run


def optimal_plan(system: System, protocol: str, weights: tuple[np.ndarray, float] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """[`backward_pass`][packetloss_cvx.lq.recursion.backward_pass] then
    [`mean_trajectory`][packetloss_cvx.lq.recursion.mean_trajectory]: ``(K0, P0, noise, U, X)`` with K0 = K[0], the
    receding-horizon gain (the whole K is not kept: a closed stationary tail's copies of one gain are not written), the
    rollout taking the run of one gain that the backward pass closed as it is, instead of searching K for it. Time O(N
    (n^3 + m^3)) without a stationary tail; with one that settles in L steps, O(L (n^3 + m^3)) for the pass (in O(log L)
    batched calls where the steps are one map) plus O(N n (n + m)) of memory-bound work for the plan and its states.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> K0, P0, noise, U, X = optimal_plan(s, "udp")       # backward_pass's example, rolled out
    >>> float(K0[0, 0]), float(P0[0, 0]), U.tolist(), X.ravel().tolist()
    (0.5, 0.75, [[-0.5]], [1.0, 0.75])
    """
    structure = structure_of(system)
    K, P0, noise, run = _one_point_backward(system, structure, protocol, weights, copies=False)
    if run is not None and _by_powers(structure, run, system.mu_schedule[None], K[None]) is None:   # step by step
        _repeat_first(K[run[0]:run[1]])
        run = None
    U = np.empty((1, system.horizon, system.m))
    X = _roll_out(structure, system.mu_schedule[None], U, system.x0[None], K[None], run, start=True)
    return K[0], P0, noise, U[0], X[0]


def rollout_batch(structure: Structure, mu: np.ndarray, K: np.ndarray,
                  x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plans u_t = -K_t x_t (points, N, m) and their mean states x_1..x_N (points, N, n) from x (points, n), by
    `mean_states`' arithmetic (so the referee, rolling the plan forward again, meets the same
    states to the bit, even where A is unstable). O(points N n (n + m)).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> U, X = rollout_batch(structure_of(s), np.full((1, 2, 1), 0.5), np.full((1, 2, 1, 1), 0.5), np.array([[2.0]]))
    >>> U.ravel().tolist(), X.ravel().tolist()     # x1 = 2 + 0.5 (-1), x2 = 1.5 + 0.5 (-0.75)
    ([-1.0, -0.75], [1.5, 1.125])
    """
    U = np.empty((mu.shape[0], structure.horizon, structure.m))
    return U, mean_states(structure, mu, U, x, K)


def mean_trajectory(system: System, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll out ``u_t = -K[t] xhat_t``: returns inputs (N×m) and mean states (N+1×n).

    The mean states are the expected trajectory of eq:pred-err, Xhat = Phi x + Gamma Vbar U, step by step.
    Time O(N n (n + m)).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> u, x = mean_trajectory(s, np.array([[[0.5]]]))     # u_0 = -0.5, xhat_1 = 1 + 0.5 (-0.5)
    >>> u.tolist(), x.ravel().tolist()
    ([[-0.5]], [1.0, 0.75])
    """
    U, X = rollout_batch(structure_of(system), system.mu_schedule[None], K[None], system.x0[None])
    return U[0], np.concatenate([system.x0[None], X[0]])


def recursion_cost(system: System, inputs: np.ndarray, protocol: str,
                   weights: tuple[np.ndarray, float] | None = None, states: np.ndarray | None = None) -> float:
    """J(U) of eq:opt-lqg-simplest with Lemma 1, by a forward pass of the mean state.

    Every term added is nonnegative (stage costs of the mean state, the input and loss-variance
    weights, the noise term), so the sum has no cancellation: this is the referee the closed
    forms check their costs against. ``weights`` reuses ``udp_variance_weights(system)``; ``states``: the
    plan's mean states x_1..x_N (N, n) if the caller rolled them out with the plan (closed_form's law: its cost
    is that of those states), else they are rolled forward here from the plan, open loop, and the value is
    returned only where [`plan_cost`][packetloss_cvx.lq.recursion.plan_cost]'s error bound is within ``PLAN_COST_RTOL``
    of it. Time O(N n^3) (the Lyapunov sums), memory O(N m); rolled out here, O(N n (n + m) L) more for the bound (L =
    32).

    Raises
    ------
    NumericalError
        The states rolled out here: the cost exceeds the double range, or the plan's rounding, amplified by the
        open-loop growth of A over the horizon, may move it by more than ``PLAN_COST_RTOL`` (relative).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> # J_tcp = xhat_1^2 + mu psi u^2 = 0.5625 + 0.125; J_udp adds mu (1 - mu) (B'S B) u^2 = 0.0625
    >>> recursion_cost(s, np.array([[-0.5]]), "tcp"), recursion_cost(s, np.array([[-0.5]]), "udp")
    (0.6875, 0.75)
    """
    protocol = check_protocol(protocol)
    if states is None:
        value, bound = plan_cost(system, inputs, protocol, weights)
        check_plan_cost(system, protocol, value, bound)
        return value
    structure = structure_of(system)
    d, noise = structure.variance_weights if weights is None else weights
    x = system.x0
    mu = system.mu_schedule[None]
    with np.errstate(over="ignore", invalid="ignore"):
        base = float(x @ system.initial_weight @ x) + noise
    return float(forward_cost(structure, mu, inputs[None], states[None], input_weight(structure, protocol, mu, d),
                              base)[0])


def plan_cost(system: System, inputs: np.ndarray, protocol: str,
              weights: tuple[np.ndarray, float] | None = None, states: np.ndarray | None = None) -> tuple[float, float]:
    """J(U) of a fixed plan by the forward pass of its mean state rolled out open loop (the value
    `recursion_cost` returns), and a bound on that value's error: ``(value, bound)`` with ``|value - J(U)|
    <= bound``, J(U) the exact cost of these floats (A, B, mu, x0, the plan, the weights; ``weights`` as
    `udp_variance_weights` computed them, sums of positive semidefinite terms, taken as given).

    The forward pass has no cancellation, but its states are not the plan's: an unstable A amplifies their
    rounding like A^t while a plan that steers the state to zero keeps the states small (the pendulum's optimal
    plan over N = 2000 steps: 1.5e80 where its cost is about 3e76, and the optimum 25445).
    The bound (`rollout_cost_error`) is the states' error estimated from their
    residuals in twice the working precision plus what the rest of their rounding can change; to it is added the
    rounding of the sum itself, measured against ``math.fsum`` of the same stage terms. inf where the value is not
    finite. ``states``: the plan's mean states x_1..x_N (N, n) as the caller rolled them out from x0 open loop by its
    own arithmetic (the value and the bound are then those of these states: the bound measures their residuals),
    else `mean_states`'. O(N n (n + m) L) with L = 32 (no Python loop over the steps), O(N n^3) for the Lyapunov sums
    if ``weights`` is None.

    Examples
    --------
    >>> def held(N):                   # x_t = 0.1 held by u_t = -0.2 (0.2 is 2 * 0.1 in binary too): J = 0.05 N
    ...     s = System(A=[[3.0]], B=[[1.0]], horizon=N, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[0.1])
    ...     return plan_cost(s, np.full((N, 1), -0.2), "tcp")
    >>> value, bound = held(5)
    >>> bool(abs(value - 0.25) <= bound < 1e-15)                  # resolved
    True
    >>> value, bound = held(40)                   # the rolled-out states drift from 0.1 like 3^t
    >>> f"{value:.4g}", bool(abs(value - 2.0) <= bound), bool(bound > 1e-9 * value)      # and the bound says so
    ('1.427e+04', True, True)
    """
    structure = structure_of(system)
    d, noise = structure.variance_weights if weights is None else weights
    x = system.x0
    mu, U = system.mu_schedule[None], inputs[None]
    Q = system.state_weights[0] if structure.time_invariant_weight else system.state_weights
    with np.errstate(over="ignore", invalid="ignore"):
        first = float(x @ system.initial_weight @ x)
        X = mean_states(structure, mu, U, x[None]) if states is None else states[None]
        weight = input_weight(structure, protocol, mu, d)
        value = float(forward_cost(structure, mu, U, X, weight, first + noise)[0])
        if not np.isfinite(value):
            return value, math.inf
        bound = float(rollout_cost_error(system.A, system.B, mu, U, x[None], X, Q, PLAN_COST_RTOL * value)[0])
        return value, bound + _sum_error(system, mu, U, X, Q, weight, first, noise, value)


def _sum_error(system: System, mu: np.ndarray, U: np.ndarray, X: np.ndarray, Q: np.ndarray, weight: np.ndarray,
               first: float, noise: float, value: float) -> float:
    """A bound on ``|value - J|``, value the forward pass's sum of the stage terms of states X (1, N, n) and J
    their exact sum: the terms computed step by step (each within gamma_{2n+1} |x|'|Q||x|, or gamma_{m+6} of its
    nonnegative input term) and summed by ``math.fsum`` (correctly rounded), so the order in which forward_cost
    summed them does not enter: its rounding is measured, not bounded by gamma_{N n}. O(N n^2)."""
    n, m = system.n, system.m
    aX = np.abs(X[0])
    if Q.ndim == 2:
        states = np.einsum("tj,tj->t", X[0] @ Q, X[0])
        size = float(np.einsum("tj,tj->", aX @ np.abs(Q), aX))
    else:
        states = np.einsum("tj,tj->t", np.einsum("ti,tij->tj", X[0], Q), X[0])
        size = float(np.einsum("ti,tij,tj->", aX, np.abs(Q), aX))
    inputs = np.einsum("tk,tk->t", (mu * U)[0], (weight * U)[0])
    x = np.abs(system.x0)
    size += float(x @ np.abs(system.initial_weight) @ x)
    total = math.fsum([first, noise, *states.tolist(), *inputs.tolist()])
    return ((1.0 + UNIT_ROUNDOFF) * abs(value - total) + UNIT_ROUNDOFF * abs(total) + gamma(2 * n + 2) * size
            + gamma(m + 6) * float(np.sum(inputs)))


def check_plan_cost(system: System, protocol: str, value: float, bound: float) -> None:
    """Raise unless ``value`` ([`plan_cost`][packetloss_cvx.lq.recursion.plan_cost]) is finite and its error bound
    within ``PLAN_COST_RTOL`` of it: the error says why (the open-loop growth of A over the horizon amplifies the plan's
    rounding) and what to use instead. O(n^3) (A's spectral radius, for the message).

    Examples
    --------
    >>> s = System(A=[[3.0]], B=[[1.0]], horizon=40, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[0.1])
    >>> check_plan_cost(s, "tcp", 0.4, 1e-12)          # resolved: nothing to say
    >>> check_plan_cost(s, "tcp", 0.4, 0.02)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.NumericalError: the tcp-like expected cost of this plan is not resolved: ...
    """
    if not np.isfinite(value):
        raise NumericalError(f"the {protocol}-like expected cost of these inputs exceeds the double-precision "
                             "range (about 1e308)")
    if bound <= PLAN_COST_RTOL * value:
        return
    rho = float(spectral_radius(system.A))
    raise NumericalError(
        f"the {protocol}-like expected cost of this plan is not resolved: its forward pass gives {value:.6g}, but "
        f"rounding may move that by up to {bound:.2g} ({bound / value if value > 0 else math.inf:.1e} relative, "
        f"more than PLAN_COST_RTOL = {PLAN_COST_RTOL:.0e}): the open-loop growth of A over the horizon (spectral "
        f"radius {rho:.4g}, N = {system.horizon}) amplifies the plan's rounding, so the cost of a fixed plan is "
        "not computable to that accuracy here; use the closed form's own cost (closed_form(...).cost, checked "
        "on the states its law rolls out), a shorter horizon, or a feedback law (closed loop) instead of a plan")


def mean_states(structure: Structure, mu: np.ndarray, U: np.ndarray, x: np.ndarray,
                K: np.ndarray | None = None) -> np.ndarray:
    """The mean states x_1..x_N (points, N, n) of plans U (points, N, m) from x (points, n) (eq:pred-err):
    ``x_{t+1} = A x_t + B (mu_t u_t)``, one stacked product a step. With gains K (points, N, m, n) the plan is
    the law's, ``u_t = -K_t x_t``, written into U as it goes (`rollout_batch`); a stationary run of
    one gain (a settled backward pass, at least STATIONARY_RUN steps) is rolled out by powers of its closed
    loop and the time-varying steps after it by a scan of their closed-loop products (`_scanned_run`)
    where A is stable or the run's closed loop is (`_by_powers`; otherwise step by step, to the bit).
    O(points N n (n + m)).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> X = mean_states(structure_of(s), np.full((1, 2, 1), 0.5), np.array([[[-2.0], [2.0]]]), np.array([[1.0]]))
    >>> X.ravel().tolist()
    [0.0, 1.0]
    """
    run = _gain_run(mu, K) if K is not None and structure.horizon >= 2 * STATIONARY_RUN else None
    return _roll_out(structure, mu, U, x, K, _by_powers(structure, run, mu, K) if run is not None else None)


def _by_powers(structure: Structure, run: tuple[int, int] | None, mu: np.ndarray,
               K: np.ndarray) -> tuple[int, int] | None:
    """``run`` where it may be rolled out by powers of its closed loop, and the steps after it by a scan
    (`_scanned_run`): where A is stable (rho(A) < 1), or the run's closed loop ``A - B M K`` (mu[:, 1],
    K[:, 1]) is at every point (a closed stationary tail's is: its contraction q < 1). None otherwise: an
    unstable plant under an unstable loop is rolled out step by step, to the bit. O(points n^3).

    The plan of an unstable plant (rho(A) > 1) is then not the float-for-float rollout of the recursion
    ``x_{t+1} = A x_t + B M u_t`` that `mean_states` runs open loop: rolled forward again from its inputs
    alone, its rounding grows with A's unstable modes, so its open-loop cost (expected_cost of the plan) is not
    resolved over long horizons, and [`plan_cost`][packetloss_cvx.lq.recursion.plan_cost] says so (the pendulum at N =
    2000: a forward pass of 1.48e80, the plan's exact open-loop cost 1.47e80, the optimum 25445). Neither is that of a
    plan rolled out step by step (a float forward pass meets 25175 there only by repeating the rollout's own rounding).
    The plan's cost is checked on the closed-loop states it was rolled out with (the law's states)."""
    if run is None:
        return None
    if structure.open_loop_radius < 1.0:
        return run
    loop = _closed_loop(structure.A, structure.B, mu[:, run[0]], K[:, run[0]])
    return run if np.all(np.isfinite(loop)) and np.all(spectral_radius(loop) < 1.0) else None


def _roll_out(structure: Structure, mu: np.ndarray, U: np.ndarray, x: np.ndarray, K: np.ndarray | None,
            run: tuple[int, int] | None, start: bool = False) -> np.ndarray:
    """`mean_states` with the run ``(1, b)`` of one gain and channel to roll out by powers already known and
    vetted (`_by_powers`; None: step by step; only K[:, 1] of the run is read). After the run, a state
    that is exactly zero at every point (a stable closed loop underflows after some hundreds of steps) stays
    zero under any finite gains: the rest of the plan and its states are zeros, as the steps give them (to the
    sign of zero); otherwise the steps after the run are a scan of their closed-loop products
    (`_scanned_run`) in blocks of at most SCAN_BLOCK_ENTRIES entries (points n^2 per step; step by step where a
    block would hold fewer than SCAN_MIN steps). ``start``: return x_0..x_N (points, N + 1, n)."""
    AT, BT, N = structure.A.T, structure.B.T, structure.horizon
    if start:
        full = np.empty((U.shape[0], N + 1, structure.n))
        full[:, 0] = x
        X = full[:, 1:]
    else:
        X = np.empty((U.shape[0], N, structure.n))
    block = 1 << max(0, (SCAN_BLOCK_ENTRIES // (U.shape[0] * structure.n ** 2)).bit_length() - 1)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):     # callers check finiteness
        state = x
        t = 0
        while t < N:
            if run is not None and t == run[0]:
                state = _closed_run(structure, mu[:, t], K[:, t], X, U, *run)
                t = run[1]
                if not state.any() and np.all(np.isfinite(K[:, t:])):
                    U[:, t:] = 0.0
                    X[:, t:] = 0.0
                    break
                if block >= SCAN_MIN:
                    while t < N:
                        end = min(N, t + block)
                        state = _scanned_run(structure, mu, K, X, U, state, t, end)
                        t = end
                    break
                continue
            if K is not None:
                U[:, t] = -np.matmul(K[:, t], state[:, :, None])[:, :, 0]
            state = X[:, t] = state @ AT + (mu[:, t] * U[:, t]) @ BT
            t += 1
    return full if start else X


#: The scan of the steps after a stationary run (:func:`_scanned_run`) holds the closed-loop matrices of a block of
#: steps, points n^2 entries each: at most this many entries at once (2 MiB), and not below SCAN_MIN steps a block.
SCAN_BLOCK_ENTRIES = 2**18
SCAN_MIN = 16


def _scanned_run(structure: Structure, mu: np.ndarray, K: np.ndarray, X: np.ndarray, U: np.ndarray, state: np.ndarray,
                 a: int, b: int) -> np.ndarray:
    """Steps a..b-1 of the time-varying gains K[:, a:b] from x_a = ``state`` (points, n) by a work-efficient scan
    (Blelloch's up-sweep of pairwise products of the closed loops ``L_t = A - B M_t K_t``, then a down-sweep of
    the states at the block starts; row vectors, ``x_{t+1}' = x_t' L_t'``): 2 log2(b - a) stacked products
    instead of b - a steps, written into X (x_{a+1}..x_b) and U (u_a..u_{b-1}) in place. Returns x_b. A level of
    odd length carries its last entry up unpaired: the products a padding to a power of two with identities gives,
    without the padding's work (the down-sweep reads no product that holds the last step's loop, which enters only
    x_b). O(points (b - a) n^3)."""
    points, n, m, L = state.shape[0], structure.n, structure.m, b - a
    loops = np.empty((points, L, n, n))                           # L_t' = A' - (M K_t)' B', as one flat product
    MK = np.ascontiguousarray((K[:, a:b] * mu[:, a:b, :, None]).swapaxes(-1, -2))
    np.subtract(structure.A.T, (MK.reshape(-1, m) @ structure.B.T).reshape(points, L, n, n), out=loops)
    levels = [loops]
    while levels[-1].shape[1] > 1:                           # products of 2, 4, ... consecutive steps
        level = levels[-1]
        k = level.shape[1]
        half = k // 2
        up = np.empty((points, k - half, n, n))
        np.matmul(level[:, 0:2 * half:2], level[:, 1:2 * half:2], out=up[:, :half])
        if k % 2:
            up[:, half] = level[:, k - 1]
        levels.append(up)
    starts = state[:, None, None, :]                          # (points, blocks, 1, n): the state at each block's start
    for level in reversed(levels[:-1]):
        k = level.shape[1]
        inner = np.empty((points, k, 1, n))
        inner[:, 0::2] = starts
        np.matmul(starts[:, :k // 2], level[:, 0:k - k % 2:2], out=inner[:, 1::2])
        starts = inner
    xs = starts[:, :L, 0]                                     # x_a .. x_{b-1}
    np.negative(np.einsum("ptij,ptj->pti", K[:, a:b], xs), out=U[:, a:b])
    X[:, a:b - 1] = xs[:, 1:]
    X[:, b - 1] = np.matmul(starts[:, L - 1], loops[:, L - 1])[:, 0]
    return X[:, b - 1]


def _gain_run(mu: np.ndarray, K: np.ndarray) -> tuple[int, int] | None:
    """The run of steps 1..b-1 whose gains and channels equal step 1's for every point (the stationary head
    a settled backward pass fills), if it has at least STATIONARY_RUN steps: its end found by bisection on
    single steps, then the whole run verified entry by entry. O(points N m n) at most, O(points m n log N) when
    absent."""
    N = K.shape[1]
    if N < 2 * STATIONARY_RUN or not np.array_equal(K[:, 2], K[:, 1]):
        return None
    lo, hi = 2, N                                   # K[:, lo] equals K[:, 1]; K[:, hi] (if any) is taken not to
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if np.array_equal(K[:, mid], K[:, 1]) else (lo, mid)
    b = lo + 1
    if b - 1 < STATIONARY_RUN or not (all_steps_equal(K[:, 1:b]) and all_steps_equal(mu[:, 1:b])):
        return None
    return 1, b


def _closed_run(structure: Structure, mu: np.ndarray, K: np.ndarray, X: np.ndarray, U: np.ndarray,
                a: int, b: int) -> np.ndarray:
    """Steps a..b-1 (a >= 1) of one gain K (points, m, n) and channel mu (points, m) from x_a = ``X[:, a - 1]``:
    the states x_a (A - B M K)'^k for k = 1..b-a by `states_by_powers`, written into X and U in place. Returns x_b.
    O(points (b - a) n^2 + points n^3 log(b - a))."""
    L = b - a
    Y = X[:, a - 1:b]                                      # x_a .. x_b, x_a already written
    rows = min(states_by_powers(Y, _closed_loop(structure.A, structure.B, mu, K).transpose(0, 2, 1)), L)
    plan = U[:, a:b]                                       # the states from ``rows`` on are 0, and so is their input
    np.matmul(Y[:, :rows], np.ascontiguousarray(K.transpose(0, 2, 1)), out=plan[:, :rows])   # BLAS: contiguous
    np.negative(plan[:, :rows], out=plan[:, :rows])
    plan[:, rows:] = 0.0
    return Y[:, L]


def states_by_powers(Y: np.ndarray, loop: np.ndarray) -> int:
    """``Y[:, k] = Y[:, 0] loop^k`` for every k >= 1 (Y (points, L + 1, d) in place, row vectors; loop (points, d, d) or
    (d, d), the transposed closed loop) by repeated squaring: log2(L) stacked products, every state still computed.
    Once a power underflows to 0 (a stable loop after some hundreds of steps) the later states are written as 0.
    Returns the number of leading rows computed as products (L + 1 when none underflowed).
    O(points L d^2 + points d^3 log L).

    Examples
    --------
    >>> Y = np.zeros((1, 4, 1)); Y[0, 0] = 1.0
    >>> states_by_powers(Y, np.array([[0.5]])), Y.ravel().tolist()
    (4, [1.0, 0.5, 0.25, 0.125])
    """
    L = Y.shape[1] - 1
    power, k = loop, 1
    while k < L + 1:                                       # Y[:, k:2k] = Y[:, :k] loop^k
        j = min(k, L + 1 - k)
        if not power.any() and np.isfinite(Y[:, :k]).all():
            Y[:, k:] = 0.0                                 # the power underflowed to 0: so does every later state
            return k
        np.matmul(Y[:, :j], power, out=Y[:, k:k + j])
        power, k = np.matmul(power, power), k + j
    return k


def forward_cost(structure: Structure, mu: np.ndarray, U: np.ndarray, X: np.ndarray, weight: np.ndarray,
                 base: np.ndarray | float, Omega: np.ndarray | None = None) -> np.ndarray:
    """The referee: the expected cost of plans U (points, N, m) whose mean states are X (points, N, n) (x_1..x_N),
    ``base + sum_t mu_t u_t (weight_t u_t) + x_{t+1}' Omega_{t+1} x_{t+1}``: every term nonnegative, so
    no cancellation (``weight``: `input_weight`; ``base``: x0'Q x0 + the noise term). Every closed
    form (dense, recursion, batched, pointwise, QP) checks its cost against this sum for its own plan.
    ``Omega``: blkdiag(Omega_1..Omega_N) as one (N n)×(N n) matrix if the caller keeps one (one product
    instead of N). Returns (points,). O(points N (n^2 + m)), O(points (N n)^2) with ``Omega``.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[2.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> forward_cost(structure_of(s), np.full((1, 1, 1), 0.5), np.full((1, 1, 1), -1.0), np.full((1, 1, 1), 0.5),
    ...              np.ones((1, 1)), 1.0).tolist()        # 1 + 0.5 * 1 + 2 * 0.25
    [2.0]
    """
    points = X.shape[0]
    with np.errstate(over="ignore", invalid="ignore"):
        # mu u (weight u): the products in this order stay in range when mu is tiny and u huge
        inputs = np.einsum("ptk,ptk->p", mu * U, weight * U)
        if Omega is not None:
            flat = X.reshape(points, -1)
            states = np.einsum("pk,pk->p", flat @ Omega, flat)
        elif structure.time_invariant_weight:    # one weight for every step: one product
            states = np.einsum("ptj,ptj->p", X @ structure.state_weights[0], X)
        else:
            states = np.einsum("ptj,ptj->p", np.einsum("pti,tij->ptj", X, structure.state_weights), X)
        return base + (inputs + states)
