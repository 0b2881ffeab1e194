"""Exact closed-loop costs of linear laws ``u_t = -K_t x_t`` over Bernoulli channels, from second moments.

Stage cost ``x'Omega x + (V u)' Psi (V u)`` with diagonal ``Psi``: since ``v_i^2 = v_i``,
``E[(V u)' Psi (V u)] = u' M Psi u`` (= ``u'(M Psi M + diag(mu (1 - mu)) Psi) u``), so the expected
stage cost of ``u = -K x`` is ``tr((Omega + K' M Psi K) S)`` with ``S = E[x x']``. The second moment
follows ``S+ = L(S) + Sigma_W`` (`.stability`); the stationary one solves ``S = L(S) + Sigma_W``
and the law's cost-to-go ``P_K = Omega + K' M Psi K + L*(P_K)``. The average stage cost is
``tr((Omega + K' M Psi K) S) = tr(P_K Sigma_W)``; both are computed and must agree.

Monte Carlo is then a check of these numbers, not the answer.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ..errors import CrossCheckError, InputError, NumericalError
from ..linalg import frobenius
from ..model.system import System, loop_weights
from ..model.validation import MAX_ENTRIES
from ..results import ClosedLoop
from ..tolerances import MOMENT_DENSE_MAX_N, MOMENT_RESIDUAL_RTOL
from .modes import mode_adjoint_step, mode_matrix, mode_stage_costs
from .stability import (
    check_law,
    is_mean_square_stable,
    law_radius,
    second_moment_adjoint,
    second_moment_matrix,
    second_moment_step,
)

__all__ = ["check_steps", "closed_loop", "finite_horizon_costs", "law_cost_to_go", "mode_cost_to_go",
           "solve_fixed_point", "stationary_channel", "stationary_second_moment"]


def check_steps(steps: object, per_step: int) -> None:
    """A horizon of ``steps`` >= 1 whose per-step arrays (``per_step`` numbers each) fit in MAX_ENTRIES.

    Refused before anything is allocated or looped over (``steps = 10**9`` is not a long wait but an error).

    >>> try:
    ...     check_steps(10**9, 4)
    ... except InputError as err:
    ...     print(err.field)
    steps
    """
    if isinstance(steps, bool) or not isinstance(steps, int | np.integer) or steps < 1:
        raise InputError("steps", f"expected an integer >= 1, found {steps!r}")
    if steps * max(per_step, 1) > MAX_ENTRIES:
        raise InputError("steps", f"expected an integer >= 1 with at most {MAX_ENTRIES} numbers over the horizon "
                                  f"({MAX_ENTRIES // max(per_step, 1)} steps of {per_step}), found {steps}")


def stationary_channel(system: System) -> np.ndarray:
    """The system's delivery probabilities for a loop run for ever: refused for a non-stationary channel.

    Raises
    ------
    InputError
        Field ``mu_schedule``: a closed loop run for ever needs one mu per actuator. Field ``channel``: a
        Gilbert-Elliott chain's losses are correlated, so the Bernoulli second moments would not describe its
        loop (a Bernoulli radius of 0.47 where the chain's is 1.06): ``packetloss_cvx.closedloop.mjls`` has its
        mean-square radius and optimal gains; pass ``mu=`` to the caller for the Bernoulli twin on purpose.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0])
    >>> stationary_channel(s).tolist()
    [0.3]
    >>> try:
    ...     stationary_channel(s.with_mu([[0.3], [0.6]]))
    ... except InputError as err:
    ...     print(err.field)
    mu_schedule
    """
    if system.channel is not None:
        raise InputError("channel", "a Gilbert-Elliott channel's losses are correlated, so the closed loop over "
                                    "independent (Bernoulli) losses does not describe it: use "
                                    "packetloss_cvx.closedloop.mjls (mean_square_radius, coupled_riccati), or give mu= "
                                    "(--mu) for the Bernoulli twin")
    if not system.is_stationary:
        raise InputError("mu_schedule", "the closed loop runs for ever over one channel: expected a stationary "
                                        "channel (mu), found a schedule that changes over the horizon")
    return system.mu_schedule[0]


def solve_fixed_point(apply: Callable[[np.ndarray], np.ndarray], matrix: Callable[[], np.ndarray],
                      C: np.ndarray, what: str) -> np.ndarray:
    """X = apply(X) + C for a stable positive map, X of C's shape ((n, n), or (M, n, n) over M modes): dense LU on
    the (M n^2)×(M n^2) matrix up to MOMENT_DENSE_MAX_N^2 rows (O((M n^2)^3)), GMRES on the operator beyond
    (O(n^3 m) per product and mode). Residual checked; a singular system, a GMRES failure or a lost residual raise
    NumericalError.

    >>> X = solve_fixed_point(lambda X: 0.5 * X, lambda: 0.5 * np.eye(1), np.array([[1.0]]), "a demo")
    >>> float(X[0, 0])        # X = X/2 + 1
    2.0
    """
    shape, dim = C.shape, C.size
    with np.errstate(over="ignore", invalid="ignore"):
        if dim <= MOMENT_DENSE_MAX_N ** 2:
            try:
                X = np.linalg.solve(np.eye(dim) - matrix(), C.ravel()).reshape(shape)
            except np.linalg.LinAlgError:   # exactly singular: the map has the eigenvalue 1 (not stable)
                raise NumericalError(f"{what}: the linear system is singular (the map has the eigenvalue 1 to "
                                     "working precision: not mean-square stable)") from None
        else:
            from scipy.sparse.linalg import LinearOperator, gmres  # optional.LAZY_IMPORTS

            op = LinearOperator((dim, dim), dtype=float,
                                matvec=lambda v: v - apply(v.reshape(shape)).ravel())
            vec, info = gmres(op, C.ravel(), rtol=1e-13, atol=0.0, restart=min(dim, 200), maxiter=50)
            if info != 0:
                raise NumericalError(f"{what}: GMRES did not converge (info {info})")
            X = vec.reshape(shape)
        X = 0.5 * (X + np.swapaxes(X, -1, -2))
        scale = max(frobenius(X), frobenius(C), np.finfo(float).tiny)
        residual = frobenius(X - apply(X) - C) / scale
    if not (np.all(np.isfinite(X)) and residual <= MOMENT_RESIDUAL_RTOL):
        raise NumericalError(f"{what}: the linear solve lost its digits (relative residual {residual:.1e})")
    return X


def stationary_second_moment(A: npt.ArrayLike, B: npt.ArrayLike, K: npt.ArrayLike, mu: npt.ArrayLike,
                             noise_cov: npt.ArrayLike) -> np.ndarray:
    """The stationary ``S = lim E[x x']`` of ``u = -K x``: the solution of ``S = L(S) + Sigma_W``.

    The caller checks mean-square stability first (otherwise the solution is not the limit).
    Time O(n^6) for n <= MOMENT_DENSE_MAX_N, else GMRES; residual checked (NumericalError).

    >>> S = stationary_second_moment([[0.5]], [[1.0]], [[0.0]], [1.0], [[0.75]])
    >>> float(S[0, 0])   # S = 0.25 S + 0.75
    1.0
    """
    return _second_moment(*check_law(A, B, K, mu), np.asarray(noise_cov, dtype=float))


def _second_moment(A_: np.ndarray, B_: np.ndarray, K_: np.ndarray, mu_: np.ndarray, Sigma: np.ndarray,
                   matrix: Callable[[], np.ndarray] | None = None) -> np.ndarray:
    """[`stationary_second_moment`][packetloss_cvx.closedloop.moments.stationary_second_moment] of a checked law;
    ``matrix``: its second_moment_matrix when the caller keeps it
    ([`closed_loop`][packetloss_cvx.closedloop.moments.closed_loop])."""
    matrix = (lambda: second_moment_matrix(A_, B_, K_, mu_)) if matrix is None else matrix
    return solve_fixed_point(second_moment_step(A_, B_, K_, mu_), matrix, Sigma, "the stationary second moment")


def law_cost_to_go(A: npt.ArrayLike, B: npt.ArrayLike, K: npt.ArrayLike, mu: npt.ArrayLike,
                   Omega: npt.ArrayLike, psi: npt.ArrayLike) -> np.ndarray:
    """``P_K = Omega + K' M Psi K + L*(P_K)``: ``x0' P_K x0`` is the law's total expected cost from x0
    without noise. Needs a mean-square stable law. Time as
    [`stationary_second_moment`][packetloss_cvx.closedloop.moments.stationary_second_moment].

    Examples
    --------
    >>> P = law_cost_to_go([[2.0]], [[1.0]], [[2.0]], [0.9], [[1.0]], [1.0])
    >>> r = (2 - 0.9 * 2) ** 2 + 0.9 * 0.1 * 2 ** 2          # scalar L*: (a - mu k)^2 + mu (1 - mu) k^2 = 0.4
    >>> bool(np.isclose(P[0, 0], (1 + 0.9 * 2 ** 2) / (1 - r)))   # P = Omega + mu psi k^2 + r P
    True
    """
    return _cost_to_go(*check_law(A, B, K, mu), Omega, psi)


def _cost_to_go(A_: np.ndarray, B_: np.ndarray, K_: np.ndarray, mu_: np.ndarray, Omega: npt.ArrayLike,
                psi: npt.ArrayLike, matrix: Callable[[], np.ndarray] | None = None) -> np.ndarray:
    """[`law_cost_to_go`][packetloss_cvx.closedloop.moments.law_cost_to_go] of a checked law; ``matrix``: its
    second_moment_matrix when the caller keeps it ([`closed_loop`][packetloss_cvx.closedloop.moments.closed_loop]; the
    adjoint's matrix is its transpose)."""
    Q = np.asarray(Omega, dtype=float) + (K_.T * (mu_ * np.asarray(psi, dtype=float))) @ K_
    matrix = (lambda: second_moment_matrix(A_, B_, K_, mu_)) if matrix is None else matrix
    return solve_fixed_point(lambda P: second_moment_adjoint(P, A_, B_, K_, mu_), lambda: matrix().T, Q,
                             "the cost-to-go of the law")


def mode_cost_to_go(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray,
                    Omega: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """The cost-to-go of the mode-dependent law ``u = -K_a x`` behind a chain (the mode known to the controller):
    ``P_a = Omega + K_a' diag(psi h_a) K_a + L*(P)_a`` (`mode_adjoint_step`),
    the coupled Lyapunov equations; ``x0' P_a x0`` is the law's total expected cost from x0 in mode a without noise.
    [`law_cost_to_go`][packetloss_cvx.closedloop.moments.law_cost_to_go] is the one-mode case. Arrays checked by the
    caller: K (M, m, n), h (M, m), T (M, M). Needs
    a mean-square stable law. Time O((M n^2)^3) up to MOMENT_DENSE_MAX_N^2 rows, else GMRES.

    Examples
    --------
    >>> one = np.ones((1, 1))       # a memoryless two-mode chain of equal modes is Bernoulli: law_cost_to_go's value
    >>> P = mode_cost_to_go(2 * one, one, np.full((2, 1, 1), 2.0), np.full((2, 1), 0.9), np.full((2, 2), 0.5), one,
    ...                     np.ones(1))
    >>> bool(np.allclose(P, law_cost_to_go([[2.0]], [[1.0]], [[2.0]], [0.9], [[1.0]], [1.0])))
    True
    """
    W = Omega + (K.mT * (h * psi)[:, None, :]) @ K
    adjoint = mode_adjoint_step(A, B, K, h, T)
    return solve_fixed_point(adjoint, lambda: mode_matrix(A, B, K, h, T).T, W, "the cost-to-go of the mode law")


def closed_loop(system: System, gain: npt.ArrayLike, law: str = "", mu: npt.ArrayLike | None = None,
                method: str = "auto") -> ClosedLoop:
    """Mean-square stability and exact costs of ``u = -K x`` run for ever on ``system``'s plant.

    Stage weights the system's one ``Omega`` and ``Psi`` (`loop_weights`: time-varying weights are refused), noise
    ``Sigma_W``; channel ``mu`` (default: the system's stationary channel).

    Parameters
    ----------
    system : System
    gain : array_like, shape (m, n)
    law : str
        A label for the result.
    mu : array_like, optional
        Another channel to run the loop over.
    method : {"auto", "kronecker", "krylov"}
        For the spectral radius ([`mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius]).

    Returns
    -------
    ClosedLoop
        ``average_stage_cost`` is ``inf`` with a ``reason`` when the loop is not proved mean-square stable.

    Raises
    ------
    InputError
        Time-varying weights (`loop_weights`).
    CrossCheckError
        ``tr((Omega + K'M Psi K) S)`` and ``tr(P_K Sigma_W)`` disagree beyond ``MOMENT_RESIDUAL_RTOL``.

    Examples
    --------
    >>> from packetloss_cvx import load_example
    >>> s = load_example("pendulum")
    >>> loop = closed_loop(s, [[0.0, 0.0, 0.0, 0.0]])   # no input: the unstable pendulum
    >>> loop.stable, loop.average_stage_cost
    (False, inf)
    """
    mu_ = stationary_channel(system) if mu is None else mu
    A, B, K, mu_ = check_law(system.A, system.B, gain, mu_)          # checked once for the radius and both solves
    # the law's n^2 x n^2 matrix, built on first use and read again by the radius and both solves
    matrix = functools.cache(lambda: second_moment_matrix(A, B, K, mu_))
    radius = law_radius(A, B, K, mu_, method=method, matrix=matrix)
    if not is_mean_square_stable(radius):
        reason = (f"not mean-square stable: the second-moment operator has spectral radius {radius:.6g} >= 1, "
                  "so E[x x'] and the average cost grow without bound")
        return ClosedLoop(law, K, mu_, radius, False, float("inf"), None, None, reason)
    (Omega, psi), Sigma = loop_weights(system), system.noise_cov
    P = _cost_to_go(A, B, K, mu_, Omega, psi, matrix)
    S = _second_moment(A, B, K, mu_, np.asarray(Sigma, dtype=float), matrix)
    by_cost_to_go = float(np.sum(P * Sigma))
    by_moment = float(np.sum((Omega + (K.T * (mu_ * psi)) @ K) * S))
    if abs(by_cost_to_go - by_moment) > MOMENT_RESIDUAL_RTOL * max(abs(by_moment), abs(by_cost_to_go)):
        raise CrossCheckError("average stage cost: tr(P_K Sigma_W) and tr((Omega + K'M Psi K) S) disagree",
                              {"cost_to_go": by_cost_to_go, "second_moment": by_moment})
    return ClosedLoop(law, K, mu_, radius, True, by_moment, P, S)


def finite_horizon_costs(system: System, gains: npt.ArrayLike, steps: int,
                         mu: npt.ArrayLike | None = None) -> tuple[np.ndarray, float]:
    """Exact expected stage costs of ``u_t = -K_t x_t`` for t = 0..steps-1 from the system's x0.

    Parameters
    ----------
    system : System
        Plant, x0, noise; its one stage weight as in
        [`closed_loop`][packetloss_cvx.closedloop.moments.closed_loop].
    gains : array_like, shape (m, n) or (steps, m, n)
        One gain for every step, or a time-varying law.
    steps : int
    mu : array_like, shape (m,) or (steps, m), optional
        Default: the system's stationary channel.

    Returns
    -------
    (stage, terminal)
        ``stage[t] = E[x_t' Omega x_t + (V_t u_t)' Psi (V_t u_t)]`` and ``terminal = E[x_T' Omega x_T]``: the
        mode engine's costs at one mode (`mode_stage_costs`).
        Time O(steps (n^3 + n^2 m)). Non-finite entries (an unstable loop over a long horizon) stay inf.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> stage, terminal = finite_horizon_costs(s, [[2.0]], 3)   # E[x_t^2] = 0.4^t (radius 0.4, no noise)
    >>> bool(np.allclose(stage, (1 + 0.9 * 4) * 0.4 ** np.arange(3))), bool(np.isclose(terminal, 0.4 ** 3))
    (True, True)
    """
    check_steps(steps, system.m * system.n)
    K_all = np.asarray(gains, dtype=float)
    mu_all = np.asarray(stationary_channel(system) if mu is None else mu, dtype=float)
    # one law broadcast over the steps (stride 0): the engine forms its map once
    K_all = np.broadcast_to(K_all, (steps, *K_all.shape)) if K_all.ndim == 2 else K_all
    mu_all = np.broadcast_to(mu_all, (steps, system.m)) if mu_all.ndim == 1 else mu_all
    if K_all.shape != (steps, system.m, system.n) or mu_all.shape != (steps, system.m):
        raise InputError("gains", f"expected ({system.m}, {system.n}) or ({steps}, {system.m}, {system.n}) gains "
                                  f"and mu of shape ({system.m},) or ({steps}, {system.m})")
    A, B, _, _ = check_law(system.A, system.B, K_all[0], mu_all[0])
    if not (np.all(np.isfinite(K_all)) and np.all((mu_all >= 0) & (mu_all <= 1))):
        raise InputError("gains", "expected finite gains and probabilities in [0, 1]")
    return mode_stage_costs(A, B, *loop_weights(system), system.noise_cov, system.x0, K_all, mu_all)
