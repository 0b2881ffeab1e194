"""The Kalman filter with intermittent observations (Sinopoli et al., IEEE TAC 49(9), 2004), one group of
output rows per sensor channel, and its expected error covariance by enumeration of the arrival patterns.

With ``x+ = A x + B V u + w``, ``y = C x + r`` and the arrivals ``a_j`` of the g sensor channels
(``a_j ~ Bernoulli(gamma_j)``), the filter is

.. math:: \\hat x^-_{k+1} = A \\hat x_k + B\\,\\mathcal V_k u_k, \\qquad
   P^-_{k+1} = A P_k A' + \\Sigma_W + \\Sigma_{\\mathrm{act}}(u_k),

    TCP-like: V_k known (acks): the prediction uses V_k u_k and Sigma_act = 0;
    UDP-like: V_k unknown: the prediction uses E[V_k] u_k = M u_k and
              Sigma_act(u) = sum_i mu_i (1 - mu_i) u_i^2 b_i b_i' = B diag(mu (1 - mu) u^2) B'

(the error ``x+ - xhat-`` gains ``B (V - M) u``, zero-mean, independent of the past, of covariance
``B diag(mu (1 - mu) u^2) B'`` since ``E[(v_i - mu_i)(v_j - mu_j)] = mu_i (1 - mu_i) [i = j]``; the error is then
a Gaussian mixture, so this UDP filter is the best *linear* estimator, not the conditional mean), and the
update uses only the rows ``r(a)`` of the channels that arrived:

.. math:: L = P^- C_r' (C_r P^- C_r' + R_r)^+, \\qquad \\hat x = \\hat x^- + L (y_r - C_r \\hat x^-), \\qquad
   P = P^- - L C_r P^-

(a lost channel's rows are skipped: with no row, ``P = P^-``). The pseudo-inverse keeps ``R = 0`` with a
singular ``P^-`` exact (``C = I, R = 0``: ``P = 0``, the full-state limit).

The TCP-like ``P_k`` does not depend on the inputs, only on the arrivals: its expectation is exact by
enumerating the ``2^(g k)`` arrival paths (:func:`expected_covariance`), Bernoulli or Gilbert–Elliott (the
filter is the same on every path; only the paths' probabilities differ, :mod:`.arrivals`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model.sensor import Sensor
from .arrivals import sensor_arrivals

__all__ = ["ENUMERATION_MAX_PATHS", "ExpectedCovariance", "actuation_covariance", "expected_covariance",
           "RowUpdate", "UPDATE_PINV_RCOND", "hermitian_pinv", "measurement_update", "pattern_rows", "predict"]

#: The exact expected covariance enumerates at most this many arrival paths (2^(g steps)).
ENUMERATION_MAX_PATHS = 2**16


def pattern_rows(sensor: Sensor, arrived: np.ndarray) -> np.ndarray:
    """The output rows delivered by the channels ``arrived`` (bool, (g,)), ascending. O(p).

    >>> s = Sensor(C=np.eye(3), gamma=[0.5, 0.5], groups=[[0, 2], [1]])
    >>> pattern_rows(s, np.array([True, False])).tolist()
    [0, 2]
    """
    return np.array(sorted(r for j, rows in enumerate(sensor.groups) if arrived[j] for r in rows), dtype=int)


#: Singular values of S below this fraction of the largest are treated as zero in ``S^+``.
UPDATE_PINV_RCOND = 1e-13


def hermitian_pinv(S: np.ndarray, rcond: float = UPDATE_PINV_RCOND) -> np.ndarray:
    """The pseudo-inverse of one symmetric matrix, ``U diag(1/s) U'`` over its eigenvalues s of magnitude above
    ``rcond`` times the largest (the cut-off of ``np.linalg.pinv(S, rcond, hermitian=True)``, whose values it gives
    to rounding, without the stacked machinery's per-call overhead: the ~10^5 small updates of a certificate
    search). Time O(p^3).

    >>> hermitian_pinv(np.array([[2.0, 0.0], [0.0, 0.0]])).tolist()
    [[0.5, 0.0], [0.0, 0.0]]
    """
    s, u = np.linalg.eigh(S)
    large = np.abs(s) > rcond * np.abs(s).max()
    inverse = np.zeros_like(s)
    inverse[large] = 1.0 / s[large]
    return (u * inverse) @ u.T


class RowUpdate:
    """The measurement update with the output ``rows`` received, its rows of C and R selected once: the
    expected Riccati maps of :mod:`.bounds` and :mod:`.markov_bounds` apply the same ``2^g`` updates thousands of
    times, and :func:`measurement_update` is this class applied once. The algebra (module docstring):
    ``S = C_r P^- C_r' + R_r``, ``L_r = P^- C_r' S^+``, ``P = P^- - L_r C_r P^-``. O(p^2) to build."""

    __slots__ = ("rows", "Cr", "Rr")

    def __init__(self, C: np.ndarray, R: np.ndarray, rows: np.ndarray):
        self.rows = rows
        self.Cr = C[rows]
        self.Rr = R[np.ix_(rows, rows)]

    def update(self, Pm: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """``(P, L_r)`` for a stack Pm (..., n, n) of float predicted covariances: L_r (..., n, r) holds the
        columns of the received rows only (None when no row is received: then ``P = P^-``, a copy).
        Time O(n^2 r + r^3) per matrix."""
        if self.rows.size == 0:
            return Pm.copy(), None
        # P^- C_r' for a whole stack as one (... n) x n product: NumPy's stacked matmul with a 2-D operand makes one
        # small product per matrix (about 40x slower for 1000 runs at n = 4); the same products, summed in the order
        # the BLAS kernel picks (tests/sensing/test_sensing_estimation.py: to ROUNDING_ORDER_RTOL)
        PCt = (Pm.reshape(-1, Pm.shape[-1]) @ self.Cr.T).reshape(*Pm.shape[:-1], self.Cr.shape[0])
        S = self.Cr @ PCt + self.Rr
        S = 0.5 * (S + S.swapaxes(-1, -2))
        if S.shape[-1] == 1 and S.ndim == 2 and math.isfinite(s := float(S[0, 0])):
            # one row, one matrix: 1/s (0 where s = 0), as the stacked branch below without its arrays
            Lr = PCt * (1.0 / s if s != 0.0 else 0.0)
        elif S.shape[-1] == 1 and np.all(np.isfinite(S)):
            # one row received: the hermitian pinv of a 1 x 1 S is 1/s (0 where s = 0), and the product with it
            # multiplies each entry by 1/s: no eigh and its per-call overhead (the certificate search of
            # bounds.critical_gamma makes ~10^5 such updates)
            with np.errstate(divide="ignore"):
                Lr = PCt * np.where(S != 0.0, 1.0 / S, 0.0)
        elif S.ndim == 2:
            Lr = PCt @ hermitian_pinv(S)
        else:
            Lr = PCt @ np.linalg.pinv(S, rcond=UPDATE_PINV_RCOND, hermitian=True)
        P = Pm - Lr @ PCt.swapaxes(-1, -2)
        return 0.5 * (P + P.swapaxes(-1, -2)), Lr

    def covariance(self, Pm: np.ndarray) -> np.ndarray:
        """P alone (:meth:`update`)."""
        return self.update(Pm)[0]


def measurement_update(Pm: np.ndarray, C: np.ndarray, R: np.ndarray,
                       rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The update with the output ``rows`` received, for a stack of predicted covariances ``Pm`` (..., n, n):
    ``(P, L)``, P (..., n, n) and the gain L (..., n, p) with zero columns for the rows not received
    (:class:`RowUpdate` applied once). Time O(n^2 p + p^3) per matrix.

    >>> P, L = measurement_update(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0]))
    >>> float(P[0, 0]), float(L[0, 0])     # scalar: L = 2 / (2 + 2), P = 2 - L 2
    (1.0, 0.5)
    """
    Pm = np.asarray(Pm, dtype=float)
    L = np.zeros((*Pm.shape[:-1], C.shape[0]))
    P, Lr = RowUpdate(C, R, rows).update(Pm)
    if Lr is not None:
        L[..., rows] = Lr
    return P, L


def actuation_covariance(B: np.ndarray, mu: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The UDP-like prediction's extra covariance ``B diag(mu (1 - mu) u^2) B'`` for inputs u (..., m): the
    error the unacknowledged deliveries add (module docstring). Time O(n^2 m) per input.

    >>> float(actuation_covariance(np.array([[2.0]]), np.array([0.5]), np.array([3.0]))[0, 0])   # 4 * 0.25 * 9
    9.0
    """
    c = mu * (1.0 - mu) * np.asarray(u, dtype=float) ** 2
    return np.einsum("ij,...j,kj->...ik", B, c, B)


def predict(P: np.ndarray, A: np.ndarray, Sigma_W: np.ndarray) -> np.ndarray:
    """``A P A' + Sigma_W`` for a stack P (..., n, n) (the UDP-like caller adds :func:`actuation_covariance`).
    Time O(n^3) per matrix."""
    out = A @ P @ A.T + Sigma_W
    return 0.5 * (out + out.swapaxes(-1, -2))


@dataclass(frozen=True)
class ExpectedCovariance:
    """The exact expected TCP-like error covariances over ``steps`` steps, from ``P^-_0 = P0``.

    ``predicted[k] = E[P^-_k]`` (k = 0..steps) and ``filtered[k] = E[P_k]`` (after the update at step k,
    k = 0..steps-1); ``paths``: the number of arrival paths enumerated."""

    predicted: np.ndarray
    filtered: np.ndarray
    paths: int


def expected_covariance(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor, steps: int,
                        P0: np.ndarray | None = None) -> ExpectedCovariance:
    """E[P^-_k] and E[P_k] exactly, by enumerating all ``2^(g steps)`` arrival paths (TCP-like: the
    covariances do not depend on the inputs), each path weighted by its probability under the sensor's arrival
    chain (:func:`.arrivals.sensor_arrivals`: the product of the pattern probabilities for Bernoulli channels; for
    Gilbert–Elliott channels the forward recursion ``w <- (w * emission[:, a]) T`` over the hidden states, so the
    path probability is exact). Time O(2^(g steps) (n^3 + n^2 p + p^3 + S^2)), S the chain's states.

    Raises
    ------
    InputError
        Field ``steps``: more than :data:`ENUMERATION_MAX_PATHS` paths (use Monte Carlo or the bounds).

    Examples
    --------
    >>> s = Sensor(C=[[1.0]], gamma=[0.5], noise_cov=[[1.0]], P0=[[1.0]])
    >>> out = expected_covariance(np.array([[1.0]]), np.array([[1.0]]), s, 1)
    >>> float(out.filtered[0, 0, 0])     # arrived: 1/(1+1) = 0.5; lost: 1; mean 0.75
    0.75
    """
    g = sensor.g
    if isinstance(steps, bool) or not isinstance(steps, int | np.integer) or steps < 1:
        raise InputError("steps", f"expected an integer >= 1, found {steps!r}")
    if g * steps > np.log2(ENUMERATION_MAX_PATHS):
        raise InputError("steps", f"{steps} steps of {g} sensor channels are 2^{g * steps} arrival paths, over the "
                                  f"{ENUMERATION_MAX_PATHS} enumerated exactly: use Monte Carlo or the bounds")
    arrivals = sensor_arrivals(sensor)
    updates = [pattern_rows(sensor, a) for a in arrivals.patterns]
    Pm = np.array(sensor.P0 if P0 is None else P0, dtype=float)[None]
    weight = arrivals.initial[None, :]                  # (paths, S): P(the path so far, S_k = s)
    predicted, filtered = [Pm[0].copy()], []
    for _ in range(steps):
        P = np.concatenate([measurement_update(Pm, sensor.C, sensor.noise_cov, rows)[0] for rows in updates])
        joint = np.concatenate([weight * e for e in arrivals.emission.T])      # the path extended by each pattern
        prob = joint.sum(axis=1)
        filtered.append(np.einsum("k,kij->ij", prob, P))
        Pm = predict(P, A, Sigma_W)
        predicted.append(np.einsum("k,kij->ij", prob, Pm))
        weight = joint @ arrivals.transition
    return ExpectedCovariance(np.array(predicted), np.array(filtered), int(prob.size))
