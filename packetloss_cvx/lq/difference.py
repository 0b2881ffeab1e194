"""The cost difference J_Delta = `J*_udp` - `J*_tcp` between the protocols (§IV): its value, its derivative
(Lemma 2), the roots of det f (Lemma 3), Theorem 4's maximiser and robust numerical maximisers.

For a shared ("scalar") channel every actuator has delivery probability nu, Vbar = nu I, and

.. math:: J_\\Delta(\\nu) = J^*_{udp} - J^*_{tcp} = \\nu(1-\\nu)\\, g' G_G \\Omega_d G_F g,\\quad
   G_F = (\\nu\\Omega_g + \\Psi)^{-1},\\ G_G = (\\nu\\Omega_h + \\Omega_d + \\Psi)^{-1},\\ g = \\Omega_{gp}x

(eq:cost-diff-eq). For per-channel mu the same difference is ``g' Vbar G_tcp^{-1} Omega_d (I - Vbar) G_udp^{-1} g``:
computed without cancellation.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
from scipy.optimize import minimize, minimize_scalar

from ..errors import InputError
from ..model.system import System
from ..results import Maximiser
from .costs import hessian_factor
from .evaluator import CHUNK_BYTES
from .prediction import Prediction, prediction

__all__ = [
    "G_maps",
    "Maximiser",
    "cost_difference",
    "cost_difference_derivative",
    "cost_differences",
    "cost_difference_fd",
    "det_roots",
    "lemma2_matrix",
    "lemma3_candidates",
    "maximise_cost_difference",
    "maximise_cost_difference_2d",
    "scalar_channel",
    "shared_channel_differences",
    "theorem4_maximiser",
]

def scalar_channel(system: System, nu: float) -> System:
    """The same system with every actuator behind one channel of delivery probability nu.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1, 1]], horizon=1, state_weight=[1], input_weight=[1, 1], mu=[.9, .1], x0=[1])
    >>> scalar_channel(s, 0.3).mu_schedule.tolist()
    [[0.3, 0.3]]
    """
    return system.with_mu(np.full(system.m, float(nu)))


def _mu_vector(system: System, mu) -> np.ndarray:
    if mu is None:
        return system.mu_schedule.ravel()
    if np.ndim(mu) == 0:
        nu = float(mu)
        if 0.0 <= nu <= 1.0:     # what scalar_channel(...).mu_schedule.ravel() holds, without a System
            return np.full(system.horizon * system.m, nu)
        return scalar_channel(system, nu).mu_schedule.ravel()       # raises ProbabilityError
    return system.with_mu(mu).mu_schedule.ravel()


def cost_difference(system: System, mu=None, pred: Prediction | None = None) -> float:
    """`J*_udp` - `J*_tcp` at ``mu`` (scalar nu, m-vector, N×m schedule, or the system's own):
    eq:cost-diff-def, and eq:cost-diff-eq for a shared channel.

    Dense and cancellation-free: O((N m)^3). Pass ``pred`` to reuse the prediction.

    >>> from packetloss_cvx import closed_form, load_example
    >>> s = load_example("two_actuator")
    >>> d = cost_difference(s)
    >>> bool(np.isclose(d, closed_form(s, "udp").cost - closed_form(s, "tcp").cost, rtol=1e-9))
    True
    """
    pred = prediction(system) if pred is None else pred
    return float(cost_differences(system, _mu_vector(system, mu)[None], pred)[0])


def cost_differences(system: System, V: np.ndarray, pred: Prediction | None = None) -> np.ndarray:
    """J_Delta at each row of ``V`` (points, N m), stacked delivery probabilities in [0, 1] (unchecked):
    eq:cost-diff-def in the batched form of [`cost_difference`][packetloss_cvx.lq.difference.cost_difference] (a
    point is a batch of one, the same bits), ``g' Vbar G_tcp^{-1} Omega_d (I - Vbar) G_udp^{-1} g`` with two stacked
    LU solves per chunk of about ``CHUNK_BYTES``. O(points (N m)^3) time, O(CHUNK_BYTES) memory.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> nus = np.array([0.0, 0.25, 0.5, 1.0])          # J_Delta = 1 - nu/2 - 1/(1 + nu)
    >>> bool(np.allclose(cost_differences(s, nus[:, None]), 1 - nus / 2 - 1 / (1 + nus), rtol=1e-14, atol=0))
    True
    """
    pred = prediction(system) if pred is None else pred
    g = pred.Omega_gp @ system.x0
    points, k = V.shape
    out = np.empty(points)
    chunk = max(1, CHUNK_BYTES // (8 * k * k))
    for start in range(0, points, chunk):
        v = V[start:start + chunk]
        a = np.linalg.solve(hessian_factor(pred, "udp", v), np.broadcast_to(g, v.shape)[..., None])[..., 0]
        b = np.linalg.solve(hessian_factor(pred, "tcp", v).transpose(0, 2, 1), (v * g)[..., None])[..., 0]
        c = pred.Omega_d * (1.0 - v) * a                    # G_udp^{-1} g, then G_tcp^{-T} Vbar g: dotted per row
        out[start:start + len(v)] = [b[i] @ c[i] for i in range(len(v))]
    return out


def shared_channel_differences(system: System, nus: np.ndarray, pred: Prediction | None = None) -> np.ndarray:
    """J_Delta(nu) of eq:cost-diff-eq at every shared-channel probability in ``nus`` (each in [0, 1]) at once.

    .. math:: G_F g = \\Psi^{-1/2} Q_F (\\nu L_F + I)^{-1} Q_F' \\Psi^{-1/2} g,\\qquad
              G_G g = D^{-1/2} Q_G (\\nu L_G + I)^{-1} Q_G' D^{-1/2} g

    with ``Psi^{-1/2} Omega_g Psi^{-1/2} = Q_F L_F Q_F'``, ``D^{-1/2} Omega_h D^{-1/2} = Q_G L_G Q_G'`` and
    ``D = Omega_d + Psi`` (both denominators are positive on [0, 1]: nu Omega_g + Psi and
    nu Omega_g + (1 - nu) Omega_d + Psi are positive definite), then
    ``J_Delta = nu (1 - nu) (G_F g)' Omega_d (G_G g)``. Two symmetric eigendecompositions, O((N m)^3), then
    O((N m)^2) per nu; [`cost_difference`][packetloss_cvx.lq.difference.cost_difference] (an LU solve per nu) agrees to
    rounding.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> nus = np.array([0.0, 0.25, 0.5, 1.0])          # J_Delta = 1 - nu/2 - 1/(1 + nu)
    >>> bool(np.allclose(shared_channel_differences(s, nus), 1 - nus / 2 - 1 / (1 + nus), rtol=1e-14, atol=1e-15))
    True
    """
    nus = np.asarray(nus, dtype=float)
    if nus.ndim != 1 or np.any(~(nus >= 0.0) | (nus > 1.0)):
        raise InputError("nus", "expected a vector of shared delivery probabilities in [0, 1]")
    return _shared_channel_curve(system, prediction(system) if pred is None else pred)(nus)


def _shared_channel_curve(system: System, pred: Prediction) -> Callable[[np.ndarray], np.ndarray]:
    """The two eigendecompositions of `shared_channel_differences`, and J_Delta on a vector of nu in
    [0, 1] from them (unchecked)."""
    g = pred.Omega_gp @ system.x0
    parts = []
    for diag, off in ((pred.Psi, pred.Omega_g), (pred.Omega_d + pred.Psi, pred.Omega_h)):
        scale = 1.0 / np.sqrt(diag)
        L, Q = np.linalg.eigh(scale[:, None] * off * scale[None, :])
        parts.append((scale, Q, L[:, None], (Q.T @ (scale * g))[:, None]))
    weight = pred.Omega_d[:, None]

    def curve(nus: np.ndarray) -> np.ndarray:
        F, G = (scale[:, None] * (Q @ (h / (nus[None, :] * L + 1.0))) for scale, Q, L, h in parts)
        return nus * (1.0 - nus) * np.sum(F * weight * G, axis=0)

    return curve


def G_maps(pred: Prediction, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """G_F = (nu Omega_g + Psi)^-1 and G_G = (nu Omega_h + Omega_d + Psi)^-1 of eq:cost-diff-eq.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> [float(G[0, 0]) for G in G_maps(prediction(s), 1.0)]   # Omega_g = Psi = Omega_d = 1, Omega_h = 0
    [0.5, 0.5]
    """
    shared = np.full(pred.Psi.shape, float(nu))       # one channel nu for every entry: Vbar = nu I
    # Theorem 1's G at Vbar = nu I (costs.hessian_factor, the one dense Hessian): nu Omega_g + Psi for the
    # TCP-like law; + Omega_d (1 - nu) for the UDP-like one, which is the paper's nu Omega_h + Omega_d + Psi
    return tuple(np.linalg.inv(hessian_factor(pred, protocol, shared)) for protocol in ("tcp", "udp"))


def lemma2_matrix(pred: Prediction, nu: float) -> np.ndarray:
    """f(nu) of Lemma 2 / Theorem 4: the matrix inside the quadratic form of eq:cost-diff-deriv. O((N m)^3).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> bool(np.isclose(lemma2_matrix(prediction(s), 0.5)[0, 0], -1 / 18))  # J_Delta' = 1/(1 + nu)^2 - 1/2, g = 1
    True
    """
    return _lemma2_from_maps(pred, nu, *G_maps(pred, nu))


def _lemma2_from_maps(pred: Prediction, nu: float, GF: np.ndarray, GG: np.ndarray) -> np.ndarray:
    """lemma2_matrix with G_F, G_G given (G_maps(pred, nu))."""
    Od = np.diag(pred.Omega_d)
    inner = (1 - 2 * nu) * Od - nu * (1 - nu) * (pred.Omega_h @ GG @ Od + Od @ GF @ pred.Omega_g)
    return GG @ inner @ GF


def cost_difference_derivative(system: System, nu: float, pred: Prediction | None = None) -> float:
    """dJ_Delta/dnu for a shared channel by Lemma 2 (eq:cost-diff-deriv): g' f(nu) g. O((N m)^3).

    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> bool(np.isclose(cost_difference_derivative(s, 0.5), -1 / 18))   # d/dnu (1 - nu/2 - 1/(1 + nu))
    True
    """
    pred = prediction(system) if pred is None else pred
    g = pred.Omega_gp @ system.x0
    return float(g @ lemma2_matrix(pred, nu) @ g)


def cost_difference_fd(system: System, nu: float, h: float | None = None,
                       pred: Prediction | None = None) -> float:
    """Central finite difference of J_Delta(nu) for a shared channel.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> bool(np.isclose(cost_difference_fd(s, 0.5), -1 / 18))   # J_Delta = 1 - nu/2 - 1/(1 + nu)
    True
    """
    pred = prediction(system) if pred is None else pred
    h = 1e-6 * min(nu, 1 - nu) if h is None else h
    return (cost_difference(system, nu + h, pred) - cost_difference(system, nu - h, pred)) / (2 * h)


def _lemma3_T(pred: Prediction) -> tuple[np.ndarray, np.ndarray]:
    Od_inv = np.diag(1.0 / pred.Omega_d)
    Psi = np.diag(pred.Psi)
    T = pred.Omega_g @ Od_inv @ (pred.Omega_g + Psi) + Psi @ Od_inv @ pred.Omega_h
    return T, Psi


def lemma3_candidates(system: System, variant: str = "lemma", pred: Prediction | None = None) -> np.ndarray:
    """Lemma 3's 2Nm points nu = 1 / (1 ± sqrt(1 + lambda_i)) (eq:det-sol; complex where 1 + lambda < 0).

    ``variant="lemma"``: lambda are the eigenvalues of ``T (Omega_g + Psi)^{-1} Omega_d Psi^{-1}`` as printed
    in the lemma; ``variant="proof"``: of ``T H^{-1}`` with ``H = Psi Omega_d^{-1} (Omega_d + Psi)`` as derived
    in its proof; ``T = Omega_g Omega_d^{-1} (Omega_g + Psi) + Psi Omega_d^{-1} Omega_h``. O((N m)^3).

    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> len(lemma3_candidates(s)) == 2 * s.horizon * s.m
    True
    """
    pred = prediction(system) if pred is None else pred
    if np.any(pred.Omega_d <= 0):
        raise InputError("system", "Lemma 3 needs Omega_d > 0 (every input must reach a weighted state)")
    T, Psi = _lemma3_T(pred)
    Od = np.diag(pred.Omega_d)
    if variant == "lemma":
        M = T @ np.linalg.solve(pred.Omega_g + Psi, Od) @ np.diag(1.0 / pred.Psi)
    elif variant == "proof":
        M = T @ np.diag(pred.Omega_d / (pred.Psi * (pred.Omega_d + pred.Psi)))
    else:
        raise InputError("variant", f"expected 'lemma' or 'proof', found {variant!r}")
    lam = np.linalg.eigvals(M).astype(complex)
    root = np.sqrt(1 + lam)
    return np.concatenate([1 / (1 + root), 1 / (1 - root)])


def det_roots(system: System, pred: Prediction | None = None) -> np.ndarray:
    """The exact roots nu of det f(nu) = 0 (eq:det-0), independently of Lemma 3.

    det f = 0 iff det Q(nu) = 0 with the matrix polynomial
    ``Q(nu) = G_F^{-1} Omega_d^{-1} M(nu) Omega_d^{-1} G_G^{-1}`` (M the bracket of f), which is
    quadratic in nu (its cubic terms cancel); its roots are the eigenvalues of the companion
    linearisation. Returns all 2Nm roots (complex, inf where the leading term is singular).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> bool(np.allclose(sorted(det_roots(s).real), [-1 - 2**0.5, 2**0.5 - 1]))  # J_Delta' = 1/(1+nu)^2 - 1/2
    True
    """
    pred = prediction(system) if pred is None else pred
    Od_inv = np.diag(1.0 / pred.Omega_d)
    Psi = np.diag(pred.Psi)
    Od = np.diag(pred.Omega_d)

    def Q(nu: float) -> np.ndarray:
        F = nu * pred.Omega_g + Psi
        G = nu * pred.Omega_h + Od + Psi
        return (1 - 2 * nu) * F @ Od_inv @ G - nu * (1 - nu) * (F @ Od_inv @ pred.Omega_h
                                                                 + pred.Omega_g @ Od_inv @ G)

    Q0 = Q(0.0)
    Q1 = (Q(1.0) - Q(-1.0)) / 2
    Q2 = (Q(1.0) + Q(-1.0)) / 2 - Q0
    k = Q0.shape[0]
    # companion form: [0 I; -Q0 -Q1] z = nu [I 0; 0 Q2] z
    Aa = np.block([[np.zeros((k, k)), np.eye(k)], [-Q0, -Q1]])
    Bb = np.block([[np.eye(k), np.zeros((k, k))], [np.zeros((k, k)), Q2]])
    return sla.eigvals(Aa, Bb)


def theorem4_maximiser(system: System, variant: str = "lemma", tol: float = 1e-6,
                       pred: Prediction | None = None) -> Maximiser | None:
    """Theorem 4 (eq:maximising-nu): the best real Lemma 3 candidate in [0, 1] at which the largest eigenvalue of
    (the symmetric part of) f(nu) vanishes (|lambda_max| <= tol * ||G_G|| ||Omega_d|| ||G_F||, the scale of
    f's terms). None if no candidate qualifies: the theorem then names no maximiser. O(N m) candidates, each O((N m)^3).

    >>> from packetloss_cvx import load_example
    >>> print(theorem4_maximiser(load_example("two_actuator")))   # no candidate qualifies (docs/claims.md)
    None
    """
    pred = prediction(system) if pred is None else pred
    nus = [float(c.real) for c in lemma3_candidates(system, variant, pred)
           if abs(c.imag) <= 1e-12 and 0.0 < c.real < 1.0]
    best = None
    if not nus:
        return best
    # the candidates' G_F, G_G, f(nu) and eigenvalues stacked: per matrix the same operations
    # (the same LAPACK and BLAS calls) as lemma2_matrix and G_maps one nu at a time
    nu = np.array(nus)[:, None, None]
    Od, Psi = np.diag(pred.Omega_d), np.diag(pred.Psi)
    HF, HG = nu * pred.Omega_g + Psi, nu * pred.Omega_h + Od + Psi
    GF, GG = np.linalg.inv(HF), np.linalg.inv(HG)
    inner = (1 - 2 * nu) * Od - nu * (1 - nu) * (pred.Omega_h @ GG @ Od + Od @ GF @ pred.Omega_g)
    f = GG @ inner @ GF
    lam_maxes = np.linalg.eigvalsh(0.5 * (f + f.transpose(0, 2, 1))).max(axis=1)
    # the scale ||G_G|| ||Omega_d|| ||G_F|| = max Omega_d / (lambda_min(H_G) lambda_min(H_F)) (H = G^-1 symmetric
    # positive definite) is at most max Omega_d / min(Psi)^2, as H - Psi is PSD: a candidate whose lambda_max
    # exceeds twice tol times that bound fails without the eigenvalues of H (scale 0 below)
    top = float(pred.Omega_d.max())
    near = np.abs(lam_maxes) <= 2.0 * tol * top / float(pred.Psi.min()) ** 2
    scales = np.zeros(len(nus))
    if np.any(near):
        scales[near] = top / (np.linalg.eigvalsh(HG[near])[:, 0] * np.linalg.eigvalsh(HF[near])[:, 0])
    for value_nu, scale, lam_max in zip(nus, scales, lam_maxes, strict=True):
        if abs(float(lam_max)) > tol * float(scale):
            continue
        value = cost_difference(system, value_nu, pred)
        if best is None or value > best.value:
            best = Maximiser(np.array([value_nu]), value, f"theorem-4 ({variant})")
    return best


def maximise_cost_difference(system: System, grid: int = 400, pred: Prediction | None = None) -> Maximiser:
    """Robust maximiser of J_Delta(nu) over nu in (0, 1) for a shared channel (what eq:maximising-nu claims to give).

    A grid uniform in logit(nu) from 1e-9 to 1 - 1e-9 (so peaks near 1e-4 are bracketed), then a bounded
    Brent refinement in logit space between the best point's neighbours, both on the curve of
    `shared_channel_differences`; the better of the grid's and Brent's points, valued by
    [`cost_difference`][packetloss_cvx.lq.difference.cost_difference]. Time O((N m)^3 + (grid + Brent steps) (N m)^2).

    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> peak = maximise_cost_difference(s, grid=100)     # J_Delta = 1 - nu/2 - 1/(1 + nu)
    >>> bool(np.isclose(peak.value, 1.5 - 2**0.5) and np.isclose(peak.point[0], 2**0.5 - 1))
    True
    """
    pred = prediction(system) if pred is None else pred
    z = np.linspace(-np.log(1e9), np.log(1e9), grid)
    nus = 1 / (1 + np.exp(-z))
    curve = _shared_channel_curve(system, pred)
    i = int(np.argmax(curve(nus)))                      # the grid locates the peak's bracket
    lo, hi = z[max(i - 1, 0)], z[min(i + 1, grid - 1)]
    res = minimize_scalar(lambda s: -float(curve(np.array([1 / (1 + np.exp(-s))]))[0]),
                          bounds=(lo, hi), method="bounded", options={"xatol": 1e-10})
    # the two points' values by cost_difference (the LU solves every other J_Delta of this module uses)
    nu_brent = float(1 / (1 + np.exp(-res.x)))
    at_brent, at_grid = cost_difference(system, nu_brent, pred), cost_difference(system, float(nus[i]), pred)
    nu, value = (nu_brent, at_brent) if at_brent >= at_grid else (nus[i], at_grid)
    return Maximiser(np.array([float(nu)]), float(value), "logit-grid + bounded Brent")


def maximise_cost_difference_2d(system: System, grid: int = 41, pred: Prediction | None = None) -> Maximiser:
    """Maximiser of J_Delta(mu) over [0, 1]^2 for two stationary channels (the cross of Fig. 3):
    a grid, then L-BFGS-B from the best grid point. Time O(grid^2 (N m)^3).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1, 0]], horizon=1, state_weight=[1], input_weight=[1, 1], mu=[.5, .5], x0=[1])
    >>> b = maximise_cost_difference_2d(s, grid=11)   # u2 moves nothing: J_Delta's 1-D peak at nu = sqrt 2 - 1
    >>> bool(np.isclose(b.value, 1.5 - 2**0.5) and np.isclose(b.point[0], 2**0.5 - 1, atol=1e-4))
    True
    """
    if system.m != 2:
        raise InputError("system", f"expected m = 2 channels, found m = {system.m}")
    pred = prediction(system) if pred is None else pred
    axis = np.linspace(0.0, 1.0, grid)
    pairs = [(a, b) for a in axis for b in axis]
    V = np.tile(np.array(pairs), (1, system.horizon))                  # each pair as a stationary schedule
    best = max(zip(cost_differences(system, V, pred).tolist(), *zip(*pairs, strict=True), strict=True))
    res = minimize(lambda p: -cost_difference(system, np.clip(p, 0, 1), pred), x0=[best[1], best[2]],
                   bounds=[(0, 1), (0, 1)], method="L-BFGS-B")
    if -res.fun >= best[0]:
        return Maximiser(np.clip(res.x, 0, 1), float(-res.fun), "grid + L-BFGS-B")
    return Maximiser(np.array([best[1], best[2]]), float(best[0]), "grid")
