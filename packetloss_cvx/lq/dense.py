"""Theorem 1's dense kernels: the Hessian factor G of eq:opt-law-1/2, the constant term C, the cost of a plan and the
optimal law in stacked form, on the paper's prediction matrices ([`prediction`][packetloss_cvx.lq.prediction], the dense
structure of a system) and a channel (its Vbar). The policy (`policy`) chooses this form or the
recursion and checks the answer; nothing here checks.

.. math:: G = \\Omega_g \\bar V + \\Psi\\ [+\\ \\Omega_d (I - \\bar V)],\\qquad
   C = x'(Q + \\Omega_p)x + \\mathrm{tr}(\\Omega_l\\Sigma_W)
"""

from __future__ import annotations

import numpy as np

from ..linalg import solve_checked
from ..model.system import System
from .prediction import Prediction, prediction

__all__ = ["dense_constant", "dense_cost", "dense_law", "hessian_diagonal", "hessian_factor", "loss_variance_term"]


def hessian_factor(pred: Prediction, protocol: str, v: np.ndarray | None = None,
                   rows: np.ndarray | None = None, block: np.ndarray | None = None) -> np.ndarray:
    """G of Theorem 1 (the Hessian of J is Vbar G): eq:opt-law-1, and eq:opt-law-2 for the UDP-like protocol.

    .. math:: G = \\Omega_g \\bar V + \\Psi\\ [+\\ \\Omega_d (I - \\bar V)]

    ``v``: the stacked delivery probabilities, (N m,) or a batch (points, N m) (default: the prediction's Vbar);
    the result is (N m, N m) or (points, N m, N m). ``rows``: a boolean mask of the entries to keep, for the
    principal block G[rows, rows] alone (one point; the line's fixed channels; or the ascending indices of
    those entries); ``block``: Omega_g[rows, rows]
    where the caller keeps it (the line's, per channel: the fancy index costs more than the product). The one
    dense form of the Hessian (closed_form, the evaluator's batches, its pointwise and line paths, the cost difference).
    O(points (N m)^2).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> p = prediction(s)                          # Omega_g = [[5, 2], [2, 1]], Vbar = 0.5 I, Psi = I
    >>> hessian_factor(p, "tcp").tolist()          # Omega_g Vbar + Psi
    [[3.5, 1.0], [1.0, 1.5]]
    >>> hessian_factor(p, "udp").tolist()          # + Omega_d (I - Vbar) = diag(2.5, 0.5)
    [[6.0, 1.0], [1.0, 2.0]]
    >>> hessian_factor(p, "udp", np.array([[1.0, 1.0], [0.5, 0.5]]))[1].tolist()    # a batch of two
    [[6.0, 1.0], [1.0, 2.0]]
    """
    v = pred.Vbar if v is None else v
    if rows is not None:
        G = (pred.Omega_g[np.ix_(rows, rows)] if block is None else block) * v[rows]
        G.flat[:: G.shape[0] + 1] += hessian_diagonal(pred, protocol, v)[rows]
        return G
    k = v.shape[-1]
    G = pred.Omega_g * v[..., None, :]
    G.reshape(*v.shape[:-1], k * k)[..., :: k + 1] += hessian_diagonal(pred, protocol, v)
    return G


def hessian_diagonal(pred: Prediction, protocol: str, v: np.ndarray) -> np.ndarray:
    """What G adds to ``Omega_g Vbar`` on its diagonal: ``Psi + [UDP] Omega_d (1 - v)``, shaped like v. O(N m).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> hessian_diagonal(prediction(s), "udp", np.array([0.5, 0.5])).tolist()    # 1 + (5, 1) / 2
    [3.5, 1.5]
    """
    return pred.Psi + (pred.Omega_d * (1.0 - v) if protocol == "udp" else 0.0)


def loss_variance_term(pred: Prediction, u: np.ndarray) -> float:
    """U' Vbar Omega_d (I - Vbar) U: what the UDP-like cost adds to the TCP-like one (Lemma 1, eq:UDP-err).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> loss_variance_term(prediction(s), np.array([1.0, 1.0]))     # 0.5 * 0.5 * (5 + 1)
    1.5
    """
    v = pred.Vbar
    return float(np.sum(v * pred.Omega_d * (1.0 - v) * u * u))


def dense_constant(system: System, pred: Prediction, x: np.ndarray) -> float | np.ndarray:
    """C = x'(Q + Omega_p)x + tr(Omega_l Sigma_W): the part of the dense cost no plan changes (eq:opt-lqg-simplest),
    for one state x (n,) (a float) or a batch (points, n) (an array (points,)). O(n^2) a point once Omega_p is built.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> dense_constant(s, prediction(s), s.x0), dense_constant(s, prediction(s), np.array([[1.0], [2.0]])).tolist()
    (20.0, [20.0, 80.0])
    """
    M = system.initial_weight + pred.Omega_p
    if x.ndim == 1:
        return float(x @ M @ x) + pred.noise_term
    return np.einsum("pi,ij,pj->p", x, M, x) + pred.noise_term


def dense_cost(system: System, U: np.ndarray, protocol: str, pred: Prediction | None = None) -> float:
    """J(U) by the paper's dense quadratic form (eq:opt-lqg-simplest, with eq:plant4 for E[U' Y' Psi Y U]).

    Time O((N n)^2 N m) to build, O((N m)^2) to evaluate.
    """
    pred = prediction(system) if pred is None else pred
    u = U.ravel()
    v = pred.Vbar
    vu = v * u
    value = dense_constant(system, pred, system.x0) + 2.0 * vu @ (pred.Omega_gp @ system.x0)
    value += vu @ pred.Omega_g @ vu + np.sum(v * pred.Psi * u * u)
    if protocol == "udp":
        value += loss_variance_term(pred, u)
    return float(value)


def dense_law(system: System, protocol: str, pred: Prediction | None = None) -> tuple[float, np.ndarray, np.ndarray]:
    """Theorem 1 in stacked form at the system's channel and x0: ``(C - g'Vbar G^{-1} g, U*, F)`` with
    ``F = G^{-1} Omega_gp`` ((N m)×n: the first m rows are the receding-horizon gain) and ``U* = -F x``
    (N×m), g = Omega_gp x; unchecked (the policy checks it). NumericalError where the solve's residual is not
    small (`solve_checked`). O((N m)^3 + (N n)^2 N m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> cost, U, F = dense_law(s, "tcp")       # min (1 + u)^2 + u^2 at u = -1/2
    >>> cost, U.tolist(), F.tolist()
    (0.5, [[-0.5]], [[0.5]])
    """
    pred = prediction(system) if pred is None else pred
    G = hessian_factor(pred, protocol)
    F = solve_checked(G, pred.Omega_gp, "G^-1 Omega_gp (Theorem 1)")     # (N m)×n
    u = -F @ system.x0
    g = pred.Omega_gp @ system.x0
    cost = dense_constant(system, pred, system.x0) + float(g @ (pred.Vbar * u))      # C - g' Vbar G^{-1} g
    return cost, u.reshape(system.horizon, system.m), F
