"""Expected costs J_tcp(U), J_udp(U) and Theorem 1 in closed form.

.. math::
   J_{tcp}(U) = x'(Q + \\Omega_p)x + \\mathrm{tr}(\\Omega_l\\Sigma_W) + 2U'\\bar V\\Omega_{gp}x
                + U'(\\bar V\\Omega_g\\bar V + \\bar V\\Psi)U,\\qquad
   J_{udp}(U) = J_{tcp}(U) + U'\\bar V\\Omega_d(I - \\bar V)U

(eq:opt-lqg-simplest with Lemma 1). Theorem 1: ``U* = -G^{-1} Omega_gp x`` with
``G_tcp = Omega_g Vbar + Psi`` and ``G_udp = G_tcp + Omega_d (I - Vbar)``.
The minimum is ``C - x' Omega_gp' Vbar G^{-1} Omega_gp x``; the paper prints
``G^{-1} Vbar`` in place of ``Vbar G^{-1}``, which differs whenever Vbar is not a
multiple of the identity (see docs/claims.md, :func:`paper_optimal_cost`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .errors import DimensionError, InputError, NumericalError
from .model import System, numeric_array
from .prediction import Prediction, prediction
from .protocols import check_protocol
from .recursion import backward_pass, mean_trajectory, recursion_cost
from .results import Solution

__all__ = [
    "check_inputs", "closed_form", "expected_cost", "hessian_factor", "loss_variance_term", "paper_optimal_cost",
    "pick_method",
]

#: ``method="auto"`` uses the dense form up to this many decision variables N*m
#: (measured crossover for n = 4, m = 2 between N*m = 160 and 200: docs/performance.md) ...
AUTO_DENSE_MAX = 160
#: ... and only while the open-loop growth rho(A)^(2N) stays below this, beyond which the
#: dense products lose digits (at rho = 1.2, N = 60 the dense gain is off by 1e-7).
AUTO_DENSE_GROWTH = 1e4


def pick_method(system: System, method: str) -> str:
    """Resolve ``"auto"`` to the faster exact path: ``"dense"`` for small, well-conditioned
    problems, ``"recursion"`` otherwise."""
    if method == "auto":
        rho = float(max(abs(np.linalg.eigvals(system.A))))
        small = system.horizon * system.m <= AUTO_DENSE_MAX
        tame = 2 * system.horizon * np.log10(max(rho, 1e-300)) <= np.log10(AUTO_DENSE_GROWTH)
        return "dense" if small and tame else "recursion"
    if method not in ("dense", "recursion"):
        raise InputError("method", f"expected 'dense', 'recursion' or 'auto', found {method!r}")
    return method


def check_inputs(system: System, inputs: npt.ArrayLike) -> np.ndarray:
    """The N×m input sequence as a float array, or :class:`InputError` naming ``inputs``."""
    U = numeric_array(inputs, "inputs")
    shape = (system.horizon, system.m)
    if U.shape != shape:
        raise DimensionError("inputs", f"expected shape {shape} but found {U.shape}")
    return U


def hessian_factor(pred: Prediction, protocol: str) -> np.ndarray:
    """G of Theorem 1 (the Hessian of J is Vbar G)."""
    G = pred.Omega_g * pred.Vbar[None, :] + np.diag(pred.Psi)
    if protocol == "udp":
        G = G + np.diag(pred.Omega_d * (1.0 - pred.Vbar))
    return G


def loss_variance_term(pred: Prediction, u: np.ndarray) -> float:
    """U' Vbar Omega_d (I - Vbar) U: what the UDP-like cost adds to the TCP-like one (Lemma 1)."""
    v = pred.Vbar
    return float(np.sum(v * pred.Omega_d * (1.0 - v) * u * u))


def _constant(system: System, pred: Prediction) -> float:
    x = system.x0
    return float(x @ (system.initial_weight + pred.Omega_p) @ x) + pred.noise_term


def dense_cost(system: System, U: np.ndarray, protocol: str, pred: Prediction | None = None) -> float:
    """J(U) by the paper's dense quadratic form. Time O((N n)^2 N m) to build, O((N m)^2) to evaluate."""
    pred = prediction(system) if pred is None else pred
    u = U.ravel()
    v = pred.Vbar
    vu = v * u
    value = _constant(system, pred) + 2.0 * vu @ (pred.Omega_gp @ system.x0)
    value += vu @ pred.Omega_g @ vu + np.sum(v * pred.Psi * u * u)
    if protocol == "udp":
        value += loss_variance_term(pred, u)
    return float(value)


def expected_cost(system: System, inputs: npt.ArrayLike, protocol: str, method: str = "auto") -> float:
    """Expected cost J(U) of the N×m input sequence ``inputs`` as the paper defines it.

    .. math:: J_{udp}(U) = J_{tcp}(U) + U'\\bar V\\Omega_d(I-\\bar V)U

    ``method="dense"`` evaluates the quadratic form of eq:opt-lqg-simplest
    (O((N n)^2 N m)); ``"recursion"`` rolls out the mean state (O(N n^3)).
    Note: for a fixed plan U, the sampled expectation of the realised cost is
    J_udp(U) under both protocols; J_tcp(U) drops the loss-variance term
    (docs/claims.md, expected-cost-tcp).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> # J_udp = E[(1 + v u)^2 + v u^2] with u = -1: 0.5*0 + 0.5*1 + 0.5 = 1.0
    >>> bool(np.isclose(expected_cost(s, [[-1.0]], "udp"), 1.0))
    True
    """
    protocol = check_protocol(protocol)
    U = check_inputs(system, inputs)
    if pick_method(system, method) == "dense":
        return dense_cost(system, U, protocol)
    value = recursion_cost(system, U, protocol)
    if not np.isfinite(value):
        raise NumericalError("the expected cost exceeds the double-precision range")
    return value


def _eigs(system: System, K: np.ndarray) -> np.ndarray:
    return np.linalg.eigvals(system.A - system.B @ K)


def closed_form(system: System, protocol: str, method: str = "dense") -> Solution:
    """Theorem 1: the optimal plan, its expected cost, gain and closed-loop eigenvalues.

    .. math:: U^* = -G^{-1}\\Omega_{gp}x,\\qquad J^* = C - x'\\Omega_{gp}'\\bar V G^{-1}\\Omega_{gp}x

    Parameters
    ----------
    system : System
    protocol : {"tcp", "udp"}
    method : {"dense", "recursion", "auto"}
        ``"dense"`` solves the (N m)×(N m) system of eq:opt-law-1/2: O((N m)^3 + (N n)^3);
        ``"recursion"`` is the exact backward recursion: O(N (n^3 + m^3)).

    Returns
    -------
    Solution

    Raises
    ------
    NumericalError
        When the dense matrices overflow (unstable A, long N) or the exact cost exceeds
        the double range.

    References
    ----------
    eq:opt-law-1, eq:opt-law-2, eq:TCP-opt-cost, eq:UDP-opt-cost (corrected).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> sol = closed_form(s, "tcp")      # min (1 + u)^2 + u^2 at u = -1/2
    >>> bool(np.allclose([sol.inputs[0, 0], sol.cost], [-0.5, 0.5]))
    True
    """
    protocol = check_protocol(protocol)
    method = pick_method(system, method)
    if method == "recursion":
        K, P0, noise = backward_pass(system, protocol)
        U, _ = mean_trajectory(system, K)
        x = system.x0
        cost = float(x @ (system.initial_weight + P0) @ x) + noise
        gain = K[0]
    else:
        pred = prediction(system)
        G = hessian_factor(pred, protocol)
        F = np.linalg.solve(G, pred.Omega_gp)       # G^{-1} Omega_gp, (N m)×n
        if not np.all(np.isfinite(F)):
            raise NumericalError("G^{-1} Omega_gp is not finite; use method='recursion'")
        u = -F @ system.x0
        g = pred.Omega_gp @ system.x0
        cost = _constant(system, pred) + float(g @ (pred.Vbar * u))  # C - g' Vbar G^{-1} g
        U = u.reshape(system.horizon, system.m)
        gain = F[: system.m]
    if not np.isfinite(cost):
        raise NumericalError("the optimal expected cost exceeds the double-precision range")
    return Solution(
        protocol=protocol, cost=cost, inputs=U, gain=gain,
        closed_loop_eigenvalues=_eigs(system, gain), method=method,
    )


def paper_optimal_cost(system: System, protocol: str) -> float:
    """The optimal cost exactly as printed in eq:TCP-opt-cost / eq:UDP-opt-cost.

    .. math:: C - x'\\Omega_{gp}' G^{-1}\\bar V \\Omega_{gp} x

    Kept for the audit: it equals the true minimum only when Vbar commutes with
    G (e.g. one shared channel, Vbar = nu I). Use :func:`closed_form` for the cost.
    """
    protocol = check_protocol(protocol)
    pred = prediction(system)
    G = hessian_factor(pred, protocol)
    g = pred.Omega_gp @ system.x0
    return _constant(system, pred) - float(g @ np.linalg.solve(G, pred.Vbar * g))
