"""The dynamic-programming optimum for Bernoulli packet losses with full state: a modified Riccati equation.

With ``x+ = A x + B V u + w``, ``V = diag(v)``, ``v_i ~ Bernoulli(mu_i)`` independent, the input sent
before its delivery is known, and stage cost ``x'Omega x + (V u)' Psi (V u)`` (Psi diagonal), a quadratic
cost-to-go ``x'P x`` gives (``E[V X V] = M X M + diag(mu (1 - mu)) ∘ X`` for any X, and ``v_i^2 = v_i``)

.. math:: x'Px = \\min_u\\ x'(\\Omega + A'PA)x + 2 x'A'PBM u + u'(M\\Psi + MB'PBM + D(P)) u,
   \\qquad D(P) = \\mathrm{diag}(\\mu_i (1 - \\mu_i) (B'PB)_{ii}),

so ``P = Omega + A'PA - A'PBM (M Psi + M B'PB M + D(P))^{-1} M B'PA`` (Schenato et al. 2007, Proc. IEEE
95(1), eq. for the TCP-like LQG controller; Garone et al., IEEE TAC 57(2), 2012, for independent multiple channels).
The Hessian factors as ``M G`` with ``G = Psi + B'PB M + diag((1 - mu) diag(B'PB))``, which stays
invertible when some ``mu_i = 0``; the law is ``u = -G^{-1} B'PA x``, the same minimiser, and
``P = Omega + A'PA - A'PBM K``. At ``mu = 1`` this is the DARE with ``R = Psi``. Noise adds
``tr(P Sigma_W)`` per step (the average stage cost of the optimal law).

No causal law over these losses does better: the optimum over all laws is linear and stationary.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..errors import InputError, NumericalError
from ..linalg import frobenius
from ..lq.recursion import riccati_step
from ..model.system import System
from ..results import Riccati
from ..tolerances import MOMENT_RESIDUAL_RTOL, RICCATI_DIVERGENCE, RICCATI_MAX_ITER, RICCATI_RTOL
from .certificates import no_law_proved
from .modes import mode_radius
from .moments import check_steps, law_cost_to_go, mode_cost_to_go, stationary_channel
from .stability import check_law, is_mean_square_stable, mean_square_radius

__all__ = ["NO_SOLUTION", "Bellman", "channel_bellman", "dp_backward", "dp_backward_nodes", "dp_finite_horizon",
           "dp_input_hessian", "dp_riccati", "dp_step", "mixture_step", "mode_riccati", "modified_riccati_step",
           "solve_bellman"]

#: Every NumericalError of :func:`dp_riccati` that means "no law holds the second moment" starts its
#: reason with this (callers that treat the absence of a stabilising law as a case, not an error, test it).
NO_SOLUTION = "modified Riccati equation: no stabilising solution"

_CHECK_EVERY = 25   # value-iteration steps between tries of the faster policy iteration
_POLICY_MAX_ITER = 100


def modified_riccati_step(P: np.ndarray, A: np.ndarray, B: np.ndarray, mu: np.ndarray, Omega: np.ndarray,
                 psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One step of the modified Riccati map: the optimal gain for cost-to-go P and the new cost-to-go.

    Returns ``(K, P_prev)`` with ``K = G^{-1} B'PA`` and ``P_prev = Omega + A'PA - A'PBM K``
    (module docstring): Theorem 1's step
    ([`packetloss_cvx.lq.recursion.riccati_step`][packetloss_cvx.lq.recursion.riccati_step] on one point) with the loss
    variance weighted by P itself. Time O(n^3 + m^3).

    >>> K, P = modified_riccati_step(np.eye(1), np.eye(1), np.eye(1), np.array([1.0]), np.eye(1), np.array([1.0]))
    >>> float(K[0, 0]), float(P[0, 0])    # scalar DARE step: K = 1/2, P = 1 + 1 - 1/2
    (0.5, 1.5)
    """
    try:
        return riccati_step(P, A, B, mu, psi, Omega, variance=True)
    except np.linalg.LinAlgError:
        raise NumericalError("modified Riccati step: the input Hessian G is singular") from None


def dp_input_hessian(B: np.ndarray, P: np.ndarray, mu: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """The DP's input Hessian at cost-to-go P: ``H = M Psi + M B'PB M + diag(mu (1 - mu) diag(B'PB))``, the
    expectation over the deliveries V of ``V Psi V + V B'PB V`` (``M G`` of `modified_riccati_step`'s G). For
    any u, ``E[stage + x+'P x+ | x, u] = x'P x + (u + K x)' H (u + K x) + tr(P Sigma_W)`` at the DP's fixed point
    (P, K): the cost split of a loop run on an estimate (sensing.loop) and its simulated check (claims.sensing) both
    read it. Time O(n^2 m + n m^2).

    >>> float(dp_input_hessian(np.array([[2.0]]), np.array([[3.0]]), np.array([0.5]), np.array([1.0]))[0, 0])
    6.5
    """
    BPB = B.T @ P @ B
    return np.diag(mu * psi) + (B * mu).T @ P @ (B * mu) + np.diag(mu * (1.0 - mu) * np.diag(BPB))


def _weights(system: System, mu: npt.ArrayLike | None) -> tuple[np.ndarray, ...]:
    A, B, _, mu_ = check_law(system.A, system.B, np.zeros((system.m, system.n)),
                             stationary_channel(system) if mu is None else mu)
    return A, B, mu_, system.state_weights[0], system.input_weights[0]


def dp_riccati(system: System, mu: npt.ArrayLike | None = None, gain: np.ndarray | None = None) -> Riccati:
    """The stationary DP optimum: the stabilising solution of the modified Riccati equation.

    `mode_riccati` at one mode: value iteration from ``P = Omega`` until the gain is mean-square stabilising,
    then policy iteration (Hewer's, each step a linear solve for the law's cost-to-go, quadratic convergence)
    until ``||P_next - P|| <= RICCATI_RTOL ||P||``. Stage weights as in
    [`closed_loop`][packetloss_cvx.closedloop.moments.closed_loop]. Time
    O(iterations (n^3 + m^3)) plus O(n^6) per policy step (n <= 30; GMRES beyond).

    With ``gain``, a law already proved mean-square stabilising at mu (its radius checked here again) and
    ``Omega > 0``, the policy iteration starts from it: the stabilising solution is unique, so the answer is the
    same to RICCATI_RTOL and passes the same checks, without the value iteration, which crawls near the boundary
    of the stabilisable set (1e-7 inside it on two_actuator: 1,433 value steps against 8 policy steps).
    A gain that is not stabilising there, or from which the policy iteration does not converge, is ignored.

    Parameters
    ----------
    system : System
    mu : array_like, optional
        Another channel (default: the system's stationary channel).
    gain : ndarray (m, n), optional
        A mean-square stabilising law at mu to start the policy iteration from.

    Returns
    -------
    Riccati

    Raises
    ------
    NumericalError
        Its reason starts with `NO_SOLUTION` only where that is proved: the value iteration grows past
        ``RICCATI_DIVERGENCE`` times the weights and its direction P proves, in exact arithmetic, every law's
        mean-square radius at least 1 (certificates.no_law_proved; asked again each time ``||P||`` grows by
        ``RICCATI_DIVERGENCE^(1/4)``). Growth alone proves nothing: on a chain of integrators the optimum's
        ``||P||`` is 2e16 (at mu = 0.0186, 1.001 on the diagonal), past the 2e14 that had been read as divergence.
        Other reasons (no verdict): the iteration overflows or does not converge in ``RICCATI_MAX_ITER`` steps,
        or ends at a law that is not mean-square stabilising (e.g. an unstable mode that Omega does not see).

    Examples
    --------
    >>> from scipy.linalg import solve_discrete_are
    >>> from packetloss_cvx import load_example
    >>> s = load_example("two_actuator").with_mu([1.0, 1.0])
    >>> dp = dp_riccati(s)
    >>> bool(np.allclose(dp.cost_to_go, solve_discrete_are(s.A, s.B, s.state_weights[0],
    ...                                                     np.diag(s.input_weights[0])), rtol=1e-9))
    True
    """
    A, B, mu_, Omega, psi = _weights(system, mu)
    K, P, iterations, residual, radius = mode_riccati(
        A, B, Omega, psi, mu_, proves=lambda P: no_law_proved(A, B, mu_, P), gain=gain,
        where=f" at mu = {mu_.tolist()}")
    return Riccati(K, P, float(np.sum(P * system.noise_cov)), radius, iterations, residual)


def mode_riccati(A: np.ndarray, B: np.ndarray, Omega: np.ndarray, psi: np.ndarray, h: np.ndarray,
                 T: np.ndarray | None = None, *, proves: Callable[[np.ndarray], bool], gain: np.ndarray | None = None,
                 max_iter: int = RICCATI_MAX_ITER, label: str = "modified Riccati equation",
                 where: str = "") -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """The stabilising solution of the DP's Riccati equation over a channel with M modes, the mode known to the
    controller: ``(K, P, iterations, residual, radius)``. One mode (``T=None``, Bernoulli, ``h = mu`` (m,), P
    (n, n), K (m, n)) is the modified Riccati equation ([`dp_riccati`][packetloss_cvx.closedloop.riccati.dp_riccati]);
    with T (M, M) and h (M, m) the
    coupled equations (`coupled_riccati`; P (M, n, n), K (M, m, n)):

    .. math:: P_a = \\Omega + A'E_aA - A'E_aBH_a K_a,\\quad K_a = G_a^{-1} B'E_aA,\\quad E_a = \\sum_b T_{ab} P_b

    with ``G_a = B'E_aB H_a + diag(psi + (1 - h_a) diag(B'E_aB))`` (`dp_step`).

    Value iteration from ``P_a = Omega``; every ``_CHECK_EVERY`` steps, once the greedy gains are mean-square
    stabilising (the engine's radius, `mode_radius`), policy iteration
    (Hewer's: each step the law's cost-to-go from the coupled Lyapunov equations, the engine's adjoint map solved by
    `mode_cost_to_go`; quadratic convergence) until ``||P_next - P|| <= RICCATI_RTOL ||P||``
    (Frobenius norms over the stacked modes): the answer is the fixed point to rounding, not a stopped iteration.
    ``gain`` (a stabilising law, Omega > 0) starts the policy iteration directly. Once ``||P||`` passes
    ``RICCATI_DIVERGENCE`` times the weights, ``proves(P)`` is asked whether P's direction proves exactly that no
    law is mean-square stable (certificates.no_law_proved at one mode, certificates.chain_outside_proved behind a
    chain); ``label`` and ``where`` name the equation and the channel in the errors.

    *An actuator that never delivers in a mode* (``h_{a,i} = 0``): its gain row does not reach the loop (it is
    multiplied by ``h_{a,i}`` in the moments and the costs), and the equation leaves it free. It is the row of
    ``K_a = G_a^{-1} B'E_aA``: the input that actuator would best send were its packet to arrive (the first-order
    condition of the Bellman right-hand side given ``v_i = 1``, the other inputs as they are), which is the limit
    of the optimal row as ``h_{a,i} -> 0+``. So the gain is continuous in the delivery probabilities, finite
    wherever the step is (G_a invertible), and the same at one mode and behind a chain, with no special case.
    Time O(iterations M (M n^2 + n^3 + m^3)) plus O((M n^2)^3) per policy step (M n^2 <= MOMENT_DENSE_MAX_N^2;
    GMRES beyond).

    Raises
    ------
    NumericalError
        Starting ``{label}: no stabilising solution`` (`NO_SOLUTION` at one mode) only where ``proves``
        proved it; otherwise (no verdict) an overflow, no convergence within ``max_iter`` steps, a limit whose law is
        not mean-square stabilising, or a residual ``||R(P) - P|| / ||P||`` above ``MOMENT_RESIDUAL_RTOL``.

    Examples
    --------
    >>> one = np.ones((1, 1))                  # scalar DARE: P = 1 + 4 P - 4 P^2 / (P + 1), P = 2 + sqrt(5)
    >>> K, P, _, _, _ = mode_riccati(2 * one, one, one, np.ones(1), np.ones(1), proves=lambda P: False)
    >>> bool(np.isclose(P[0, 0], 2 + 5 ** 0.5)), bool(np.isclose(K[0, 0], 2 * P[0, 0] / (P[0, 0] + 1)))
    (True, True)
    >>> K2, P2, _, _, _ = mode_riccati(2 * one, one, one, np.ones(1), np.ones((2, 1)), np.full((2, 2), 0.5),
    ...                                proves=lambda P: False)          # two equal modes: the same equation
    >>> bool(np.allclose(P2, P)), bool(np.allclose(K2, K))
    (True, True)
    """
    return solve_bellman(channel_bellman(A, B, Omega, psi, h, T), proves=proves, gain=gain, max_iter=max_iter,
                         label=label, where=where)


@dataclass(frozen=True)
class Bellman:
    """A coupled Riccati equation as the maps `solve_bellman` iterates: ``step(P) -> (K, P_prev)`` the Bellman
    step (greedy gains for the cost-to-go P and the new cost-to-go), ``radius(K)`` the engine's mean-square radius
    of the law K, ``cost_to_go(K)`` its exact cost-to-go (the coupled Lyapunov equations), ``start`` the value
    iteration's first P (the state weight per mode), ``scale`` the size a stabilising P is measured against (its
    divergence test), ``gain_shape`` K's shape, and ``definite``: the state weight is positive definite, so that a
    stabilising gain may start the policy iteration (`_started`). `channel_bellman` is the channel's equation
    (`mode_riccati`); closedloop.actuator_design builds the one of an actuator's strategy.

    >>> one = np.ones((1, 1))
    >>> problem = channel_bellman(2 * one, one, one, np.ones(1), np.ones(1))     # the scalar DARE
    >>> problem.gain_shape, problem.definite, [round(float(v), 12) for v in problem.step(one)[0].ravel()]
    ((1, 1), True, [1.0])
    """

    step: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    radius: Callable[[np.ndarray], float]
    cost_to_go: Callable[[np.ndarray], np.ndarray]
    start: np.ndarray
    scale: float
    gain_shape: tuple[int, ...]
    definite: bool


def channel_bellman(A: np.ndarray, B: np.ndarray, Omega: np.ndarray, psi: np.ndarray, h: np.ndarray,
                    T: np.ndarray | None = None) -> Bellman:
    """`mode_riccati`'s equation as a `Bellman`: `dp_step`, the engine's radius and the law's cost-to-go
    (moments.law_cost_to_go at one mode, moments.mode_cost_to_go behind a chain). O(n^3 + n m) to build.

    >>> one = np.ones((1, 1))                     # x+ = 2x - v K x, v ~ Bernoulli(1/2), K = 2: (2 - 1)^2 + 4/4
    >>> channel_bellman(2 * one, one, one, np.ones(1), np.array([0.5])).radius(2 * one)
    2.0
    """
    shape = (B.shape[1], A.shape[0]) if T is None else (T.shape[0], B.shape[1], A.shape[0])
    return Bellman(step=lambda P: dp_step(P, A, B, h, T, Omega, psi),
                   radius=lambda K: _radius(A, B, K, h, T),
                   cost_to_go=lambda K: _cost_to_go(K, A, B, h, T, Omega, psi),
                   start=Omega.copy() if T is None else np.repeat(Omega[None], T.shape[0], axis=0),
                   scale=_cost_to_go_scale(B, Omega, psi), gain_shape=shape,
                   definite=bool(np.linalg.eigvalsh(Omega)[0] > 0))


def solve_bellman(problem: Bellman, *, proves: Callable[[np.ndarray], bool], gain: np.ndarray | None = None,
                  max_iter: int = RICCATI_MAX_ITER, label: str = "modified Riccati equation",
                  where: str = "") -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """The stabilising solution of ``problem``'s coupled Riccati equation: ``(K, P, iterations, residual,
    radius)``, by `mode_riccati`'s iteration (value iteration, then Hewer's policy iteration once the greedy gains
    are mean-square stabilising; ``proves`` asked once P diverges; errors as `mode_riccati`'s). Time: the
    iterations' steps, plus one cost-to-go per policy step.

    >>> one = np.ones((1, 1))                     # scalar DARE: P = 1 + 4 P - 4 P^2 / (P + 1), P = 2 + sqrt(5)
    >>> K, P, _, _, _ = solve_bellman(channel_bellman(2 * one, one, one, np.ones(1), np.ones(1)),
    ...                               proves=lambda P: False)
    >>> bool(np.isclose(P[0, 0], 2 + 5 ** 0.5))
    True
    """
    scale = problem.scale
    if not RICCATI_DIVERGENCE * scale < np.finfo(float).max:
        raise NumericalError(f"{label}: the cost-to-go's scale (the weights, and the input weights "
                             f"over ||B e_i||^2: {scale:.3g}) leaves no room in double precision to tell divergence "
                             "from convergence; rescale the inputs (B by c and the input weights by c^2 is the same "
                             "problem)")
    P = problem.start.copy()
    iterations = 0
    started = _started(gain, problem, label)
    if started is not None:
        P, iterations = started
    check_at = RICCATI_DIVERGENCE * scale             # the next size at which a growing P is asked for a proof
    size = 0.0                                       # nothing has grown yet
    with np.errstate(over="ignore", invalid="ignore"):
        while started is None:
            try:
                K, P_next = problem.step(P)
            except NumericalError:
                if size <= RICCATI_DIVERGENCE * scale:
                    raise
                P_next = np.full_like(P, np.inf)     # a Hessian singular to rounding as P grows: as an overflow
            iterations += 1
            size = frobenius(P_next)
            if not np.isfinite(size):
                raise NumericalError(f"{label}: undecided{where}: the value iteration overflows after {iterations} "
                                     "steps and its direction proves no bound on the laws' radii (no stabilising "
                                     "solution found: the loop is not mean-square stabilisable, or only barely; a "
                                     "stabilising solution is denied only by proof)")
            if size > check_at:
                if proves(P_next):
                    raise NumericalError(f"{label}: no stabilising solution{where} (the value iteration diverges, "
                                         f"||P|| > {size:.3g}, and its direction proves every law's mean-square "
                                         "radius >= 1 in exact arithmetic: no law holds the second moment bounded; "
                                         "the loop is not mean-square stabilisable)")
                check_at = size * RICCATI_DIVERGENCE ** 0.25
            converged = frobenius(P_next - P) <= RICCATI_RTOL * size
            P = P_next
            if converged:
                break
            if iterations % _CHECK_EVERY == 0:
                K, _ = problem.step(P)
                if is_mean_square_stable(problem.radius(K)):
                    P, steps = _policy_iteration(K, problem, label)
                    iterations += steps
                    break
            if iterations >= max_iter:
                raise NumericalError(f"{label}: no convergence in {iterations} iterations{where} (no stabilising "
                                     "solution, or too close to the critical probability: the loop is not "
                                     "mean-square stabilisable, or only barely)")
    K, P_next = problem.step(P)
    residual = frobenius(P_next - P) / max(frobenius(P), np.finfo(float).tiny)
    radius = problem.radius(K)
    if not is_mean_square_stable(radius):
        raise NumericalError(f"{label}: the solution found{where} is not stabilising (its law has mean-square "
                             f"radius {radius:.6g} >= 1): a mode that Omega does not weigh")
    if residual > MOMENT_RESIDUAL_RTOL:
        raise NumericalError(f"{label}: relative residual {residual:.1e} after {iterations} iterations")
    return K, P, iterations, residual, radius


def dp_step(P: np.ndarray, A: np.ndarray, B: np.ndarray, h: np.ndarray, T: np.ndarray | None, Omega: np.ndarray,
            psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One backward step of `mode_riccati`'s equation: ``(K, P_prev)``. ``T=None``: one mode,
    `modified_riccati_step`. With T: every mode a as one batch of Theorem 1's step
    ([`packetloss_cvx.lq.recursion.riccati_step`][packetloss_cvx.lq.recursion.riccati_step] with ``mu = h_a``, ``P =
    E_a = sum_b T_ab P_b`` and the loss
    variance weighted by E_a), so ``K_a = G_a^{-1} B'E_aA`` on every actuator, those that cannot deliver in a mode
    included (`mode_riccati`). O(M (M n^2 + n^3 + m^3)).

    Raises
    ------
    NumericalError
        A Hessian factor G_a is singular.

    >>> one = np.ones((1, 1))                           # a two-mode chain that never delivers in mode 1
    >>> K, P = dp_step(np.ones((2, 1, 1)), one, one, np.array([[1.0], [0.0]]), np.full((2, 2), 0.5), one, np.ones(1))
    >>> K.ravel().tolist(), P.ravel().tolist()         # K = E / (psi + E) in both modes; P_1 = 1 + E
    ([0.5, 0.5], [1.5, 2.0])
    """
    if T is None:
        return modified_riccati_step(P, A, B, h, Omega, psi)
    E = np.einsum("ab,bij->aij", T, P)
    E = 0.5 * (E + E.transpose(0, 2, 1))
    try:
        return riccati_step(E, A, B, h, np.broadcast_to(psi, h.shape), Omega, variance=True)
    except np.linalg.LinAlgError:
        raise NumericalError("coupled Riccati step: an input Hessian G_a is singular") from None


def _radius(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray | None) -> float:
    """The mean-square radius of the law K: stability.mean_square_radius at one mode, the engine's behind a chain."""
    return mean_square_radius(A, B, K, h) if T is None else mode_radius(A, B, K, h, T)


def _cost_to_go_scale(B: np.ndarray, Omega: np.ndarray, psi: np.ndarray) -> float:
    """The size the stabilising cost-to-go is measured against (its divergence test): the larger of ||Omega|| and
    the input weights in state units, ``psi_i / ||B e_i||^2`` over the inputs that move the state (an input of
    weight psi through a column b costs like a state weight psi / ||b||^2; with B and Psi scaled by c and c^2 the
    problem is the same, and so is this scale). O(n m).

    >>> _cost_to_go_scale(np.array([[1e-100]]), np.array([[1.0]]), np.array([1.0]))     # P is about 1e200 here
    1e+200
    """
    top = float(np.abs(B).max(initial=0.0))
    columns = np.sqrt(np.sum(np.square(B / top), axis=0)) * top if top > 0 else np.zeros(B.shape[1])   # ||B e_i||
    moving = columns > 0
    with np.errstate(over="ignore"):
        inputs = float(np.max((np.sqrt(psi[moving]) / columns[moving]) ** 2, initial=0.0))
    return max(frobenius(Omega), float(np.max(psi, initial=0.0)), inputs)


def _started(gain: np.ndarray | None, problem: Bellman, label: str) -> tuple[np.ndarray, int] | None:
    """The policy iteration from ``gain`` where that law is finite, of the problem's gain shape ((m, n), or
    (M, m, n) behind a chain), mean-square stabilising and the iteration converges: ``(P, steps)``, else None (the
    value iteration then runs as without it). Only with a definite state weight: a singular Omega may not see an
    unstable mode, where the value iteration's limit (the optimum) is not the stabilising solution that Hewer's
    iteration reaches. O(steps n^6)."""
    if gain is None:
        return None
    K = np.asarray(gain, dtype=float)
    if K.shape != problem.gain_shape or not np.all(np.isfinite(K)) or not problem.definite:
        return None
    try:
        if not is_mean_square_stable(problem.radius(K)):
            return None
        with np.errstate(over="ignore", invalid="ignore"):
            P, steps = _policy_iteration(K, problem, label)
    except (NumericalError, np.linalg.LinAlgError):
        return None
    return (P, steps) if np.all(np.isfinite(P)) else None


def _policy_iteration(K: np.ndarray, problem: Bellman, label: str) -> tuple[np.ndarray, int]:
    """Hewer's iteration from a stabilising K: P_j = cost-to-go of K_j, K_{j+1} = the greedy gain of P_j.
    The P_j decrease to the stabilising solution (each K_j stays stabilising)."""
    P = problem.cost_to_go(K)
    for step in range(1, _POLICY_MAX_ITER + 1):
        K, _ = problem.step(P)
        P_next = problem.cost_to_go(K)
        if frobenius(P_next - P) <= RICCATI_RTOL * frobenius(P_next):
            return P_next, step
        P = P_next
    raise NumericalError(f"{label}: policy iteration did not converge in {_POLICY_MAX_ITER} steps")


def _cost_to_go(K: np.ndarray, A: np.ndarray, B: np.ndarray, h: np.ndarray, T: np.ndarray | None,
                Omega: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """The law's cost-to-go: moments.law_cost_to_go at one mode, the coupled Lyapunov equations behind a chain."""
    return law_cost_to_go(A, B, K, h, Omega, psi) if T is None else mode_cost_to_go(A, B, K, h, T, Omega, psi)


def mixture_step(P_next: np.ndarray, prob: np.ndarray, q: np.ndarray, A: np.ndarray, B: np.ndarray,
                 Omega: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One backward step of the DP at a batch of J information nodes, each with k outcomes: ``(K, P)``, (J, m, n) and
    (J, n, n). Outcome o of node j happens with probability ``prob[j, o]``; given it the deliveries are independent
    Bernoulli with ``q[j, o]`` (m,) and the cost-to-go after the step is ``x'P_next[j, o]x``. The input is chosen
    before the outcome is known, so

    .. math:: x'P_jx = \\min_u \\sum_o p_{jo}\\,E\\big[x'\\Omega x + (Vu)'\\Psi(Vu) + (Ax + BVu)'P_{jo}(Ax + BVu)\\big]
       = x'(\\Omega + \\textstyle\\sum_o p_{jo}A'P_{jo}A)x - L_j'K_j

    with Hessian ``H_j = sum_o p_jo Q_o G_o`` (``Q_o = diag(q_jo)``, ``G_o`` the modified Riccati step's factor at
    ``(P_jo, q_jo)``) and ``L_j = sum_o p_jo Q_o B'P_joA``. As at one outcome, H is solved in the factored form
    ``diag(mu) Ghat`` (``mu = sum_o p_o q_o`` the mean delivery): row i of ``Ghat`` and ``rhat`` is the outcomes'
    average weighted by ``p_o q_{o,i} / mu_i``, the step given that actuator i's packet arrives, so
    ``K = Ghat^{-1} rhat`` and ``P = Omega + sum_o p_o A'P_oA - (diag(mu) rhat)'K``. An actuator that never delivers
    at a node (``mu_i = 0``) takes the plain average of the rows (weights ``p_o``): its gain row does not reach the
    loop, and Ghat stays invertible for ``psi > 0`` (block triangular, that row's diagonal ``psi_i + (B'EB)_ii``).
    One outcome (k = 1) is the modified Riccati step itself (`modified_riccati_step`'s algebra, batched):
    Bernoulli losses, or a chain whose state the controller knows (`dp_step`). O(J k (n^3 + m^3)).

    Raises
    ------
    NumericalError
        A factor Ghat is singular.

    >>> one = np.ones((1, 1))                    # x+ = x + v u behind a delivery that is 1 or 0 with prob 1/2 each:
    >>> K, P = mixture_step(np.ones((1, 2, 1, 1)), np.full((1, 2), 0.5), np.array([[[1.0], [0.0]]]), one, one, one,
    ...                     np.ones(1))          # the Bernoulli(1/2) step: G = 1/2 + 1 + 1/2, K = 1/2, P = 2 - 1/4
    >>> K.ravel().tolist(), P.ravel().tolist()
    ([0.5], [1.75])
    """
    J, k, m = q.shape
    try:
        if k == 1:                                # one outcome: the modified Riccati step (prob is 1)
            return riccati_step(P_next[:, 0], A, B, q[:, 0], np.broadcast_to(psi, (J, m)), Omega, variance=True)
        PB = P_next @ B                                                   # (J, k, n, m)
        BPB = B.T @ PB
        rhs = PB.swapaxes(-1, -2) @ A                                     # B'P A, (J, k, m, n)
        APA = np.einsum("jo,joab->jab", prob, A.T @ (P_next @ A))
        G = BPB * q[..., None, :]
        diagonal = np.einsum("...ii->...i", G)                            # a view: G's diagonal
        diagonal += psi + (1.0 - q) * np.einsum("...ii->...i", BPB)
        w = prob[..., None] * q                                           # (J, k, m)
        mu = w.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.where(mu[:, None, :] > 0, w / mu[:, None, :], prob[..., None])
        Ghat = np.einsum("joi,joik->jik", c, G)
        rhat = np.einsum("joi,join->jin", c, rhs)
        K = np.linalg.solve(Ghat, rhat)
    except np.linalg.LinAlgError:
        raise NumericalError("DP step over an information node's outcomes: an input Hessian factor is singular") \
            from None
    P = Omega + APA - (mu[..., None] * rhat).swapaxes(-1, -2) @ K
    return K, 0.5 * (P + P.swapaxes(-1, -2))


def dp_backward_nodes(A: np.ndarray, B: np.ndarray, Omega: np.ndarray, psi: np.ndarray, noise_cov: np.ndarray,
                      layers: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]
                      ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """The finite-horizon DP's backward pass over information nodes: ``(gains, P_0, noise_0)``.

    ``layers[t] = (prob, q, nxt)``, each (J_t, k_t[, m]): the J_t nodes of step t (what the controller knows when it
    sends u_t), the probability and delivery probabilities of each outcome (`mixture_step`) and the node of step t + 1
    it leads to; the nodes of step N are ``max(nxt) + 1`` terminal ones with ``P = Omega[N]``. ``gains[t]`` (J_t, m, n)
    is the law ``u_t = -K_{t,j} x_t`` at node j, ``P_0`` (J_0, n, n) and ``noise_0`` (J_0,) the cost-to-go
    ``x'P_0x + noise_0`` at step 0: ``noise_t,j = sum_o p_o (tr(P_{t+1,o} Sigma_W) + noise_{t+1,o})``. Weights per
    step as `dp_backward`. One node and one outcome a step is `dp_backward` (Bernoulli losses); a chain behind
    acknowledgements is closedloop.chain_dp. Overflow is left to the caller (inf / nan). O(sum_t J_t k_t (n^3 + m^3)).

    >>> layer = (np.ones((1, 1)), np.ones((1, 1, 1)), np.zeros((1, 1), dtype=int))
    >>> gains, P0, noise = dp_backward_nodes(np.eye(1), np.eye(1), np.ones((2, 1, 1)), np.ones((1, 1)), 2 * np.eye(1),
    ...                                      [layer])
    >>> float(gains[0][0, 0, 0]), float(P0[0, 0, 0]), float(noise[0])       # as dp_backward's example
    (0.5, 1.5, 2.0)
    """
    steps = len(layers)
    terminal = int(np.max(layers[-1][2])) + 1 if steps else 1
    P = np.broadcast_to(np.asarray(Omega[steps], dtype=float), (terminal, *Omega.shape[1:]))
    noise = np.zeros(terminal)
    gains: list[np.ndarray] = [np.empty(0)] * steps
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps - 1, -1, -1):
            prob, q, nxt = layers[t]
            P_next = P[nxt]                                                 # (J, k, n, n)
            traces = (P_next * noise_cov).reshape(*nxt.shape, -1).sum(axis=-1)
            noise = np.sum(prob * (traces + noise[nxt]), axis=1)
            gains[t], P = mixture_step(P_next, prob, q, A, B, Omega[t], psi[t])
    return gains, P, noise


def dp_backward(A: np.ndarray, B: np.ndarray, mu: np.ndarray, Omega: np.ndarray, psi: np.ndarray,
                noise_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The finite-horizon DP's backward pass with a weight per step: ``(gains, P_0, noise)``, ``gains[t]`` (u_t = -K_t
    x_t) from `modified_riccati_step` at ``mu[t]`` (steps, m) and ``psi[t]`` (steps, m), ``P_N = Omega[N]``, the state
    weight ``Omega[t]`` added at step t (``Omega``: (steps + 1, n, n)), and ``noise = sum_t tr(P_{t+1} Sigma_W)``.
    `dp_backward_nodes` with one node and one outcome a step (Bernoulli losses). The one pass under
    `dp_finite_horizon` (stationary weights) and the attainable cost of allocation.attainable
    (the paper's time-varying ones). Overflow is left to the caller (inf / nan). O(steps (n^3 + m^3)).

    >>> gains, P0, noise = dp_backward(np.eye(1), np.eye(1), np.ones((1, 1)), np.ones((2, 1, 1)), np.ones((1, 1)),
    ...                                2 * np.eye(1))
    >>> float(gains[0, 0, 0]), float(P0[0, 0]), noise            # one DARE step from P = 1: K = 1/2, P0 = 1.5
    (0.5, 1.5, 2.0)
    """
    steps, m = psi.shape
    one, first = np.ones((1, 1)), np.zeros((1, 1), dtype=int)
    layers = [(one, np.asarray(mu[t], dtype=float)[None, None], first) for t in range(steps)]
    gains, P, noise = dp_backward_nodes(A, B, Omega, psi, noise_cov, layers)
    out = np.stack([g[0] for g in gains]) if steps else np.empty((0, m, A.shape[0]))
    return out, P[0], float(noise[0])


def dp_finite_horizon(system: System, steps: int,
                      mu: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The finite-horizon DP optimum over t = 0..steps-1 with terminal cost ``x_T' Omega x_T``.

    Parameters
    ----------
    system : System
        Plant, x0, noise; stage weights Omega_1 and Psi_0.
    steps : int
    mu : array_like, shape (m,) or (steps, m), optional
        The channel per step (default: the system's stationary channel).

    Returns
    -------
    (gains, P0, cost)
        Time-varying gains ``gains[t]`` (u_t = -K_t x_t), the cost-to-go at t = 0 and the optimal
        expected cost ``x0' P0 x0 + sum_t tr(P_{t+1} Sigma_W)``. Time O(steps (n^3 + m^3)).

    Raises
    ------
    NumericalError
        The cost-to-go overflows.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0],
    ...            noise_cov=[[2.0]])
    >>> gains, P0, cost = dp_finite_horizon(s, 1)   # one DARE step from P = 1: K = 1/2, P0 = 1.5; noise adds 2 * 1
    >>> float(gains[0, 0, 0]), float(P0[0, 0]), cost
    (0.5, 1.5, 3.5)
    >>> from packetloss_cvx.closedloop.moments import finite_horizon_costs
    >>> lossy = s.with_mu([0.6])
    >>> gains, _, cost = dp_finite_horizon(lossy, 4)   # the exact cost of its own time-varying law
    >>> stage, terminal = finite_horizon_costs(lossy, gains, 4)
    >>> bool(np.isclose(cost, stage.sum() + terminal))
    True
    """
    check_steps(steps, system.m * system.n)
    mu_all = np.asarray(stationary_channel(system) if mu is None else mu, dtype=float)
    mu_all = np.broadcast_to(mu_all, (steps, system.m)) if mu_all.ndim == 1 else mu_all
    if mu_all.shape != (steps, system.m):
        raise InputError("mu", f"expected ({system.m},) or ({steps}, {system.m}), found {mu_all.shape}")
    if not np.all((mu_all >= 0) & (mu_all <= 1)):
        raise InputError("mu", "expected probabilities in [0, 1]")
    A, B, _, Omega, psi = _weights(system, mu_all[0])
    gains, P, noise = dp_backward(A, B, mu_all, np.broadcast_to(Omega, (steps + 1, *Omega.shape)),
                                  np.broadcast_to(psi, (steps, system.m)), system.noise_cov)
    cost = float(system.x0 @ P @ system.x0) + noise
    if not (np.isfinite(cost) and np.all(np.isfinite(gains))):
        raise NumericalError("finite-horizon DP: the cost-to-go overflows (an unstable plant over a long horizon)")
    return gains, P, cost
