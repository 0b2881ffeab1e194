"""Whether a backward iterate has settled: the tests the Theorem-1 kernels share (the Lyapunov sum of
`structure`, the Riccati passes of [`recursion`][packetloss_cvx.lq.recursion], the augmented Markov
recursion). A map contracting by q per step whose last change was c can still move by at most ``c q / (1 - q)``:
below ``tolerances.STATIONARY_RTOL`` of the iterate's size, the iterate is its fixed point to rounding and the
steps before it take its value. Also how far a pass's data are one map (`leading_run`), and the spectral
radius that gives q.
"""

from __future__ import annotations

import numpy as np

from ..tolerances import STATIONARY_RTOL

__all__ = ["STATIONARY_RUN", "all_steps_equal", "drift", "leading_run", "settled", "small_change",
           "spectral_radius", "stationary_close"]

#: Horizons of at least twice this many steps try to close a stationary tail (tolerances.STATIONARY_RTOL), and a
#: run of at least this many steps with one gain and one channel is rolled out by powers of its closed loop.
STATIONARY_RUN = 64


def small_change(new: np.ndarray, old: np.ndarray) -> bool:
    """A cheap necessary test for `stationary_close` with a contraction q >= 0.01. O(points n^2)."""
    return bool(np.abs(new - old).max() <= 100.0 * STATIONARY_RTOL * np.abs(new).max())


def spectral_radius(loop: np.ndarray) -> np.ndarray:
    """The spectral radius of each matrix of a stack (or of one matrix). O(points n^3)."""
    return np.max(np.abs(np.linalg.eigvals(loop)), axis=-1)


def stationary_close(new: np.ndarray, old: np.ndarray, q: np.ndarray | float) -> bool:
    """Whether a backward iterate has settled: its last change, times the remaining geometric sum
    ``q / (1 - q)`` of a map contracting by ``q`` per step, is below ``STATIONARY_RTOL`` relative to its
    size (every point of a batch: new, old (..., n, n), q (...,) or a float). Never with q >= 1. O(points n^2).

    Examples
    --------
    >>> stationary_close(np.eye(2), np.eye(2) * (1 + 1e-16), 0.25), stationary_close(np.eye(2), 2 * np.eye(2), 0.25)
    (True, False)
    """
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return settled(*drift(new, old), q)


def drift(new: np.ndarray, old: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``max |new - old|`` and ``max |new|`` per matrix of a stack: what `stationary_close` weighs (the
    caller ignores overflow in np.errstate, as the backward passes do). O(points n^2)."""
    lead, k = new.shape[:-2], new.shape[-1] * new.shape[-2]
    return _row_max(np.abs(new - old).reshape(-1, k), lead), _row_max(np.abs(new).reshape(-1, k), lead)


def _row_max(values: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """The largest entry of each row of ``values`` (p, k), shaped ``shape``: by a reduction over the first axis of
    the transposed copy (NumPy reduces a short last axis row by row: 175 against 12 us for 1,600 rows of 16).
    O(p k)."""
    if values.shape[0] < 64:
        return values.max(axis=1).reshape(shape)
    return np.ascontiguousarray(values.T).max(axis=0).reshape(shape)


def settled(change: np.ndarray, size: np.ndarray, q: np.ndarray | float) -> bool:
    """`stationary_close` of a change and size (`drift`), in the caller's np.errstate. O(points)."""
    q = np.asarray(q, dtype=float)
    return bool(((q < 1.0) & (change * (q / (1.0 - q)) <= STATIONARY_RTOL * size) & np.isfinite(size)).all())


def all_steps_equal(values: np.ndarray) -> bool:
    """Whether ``values[:, k]`` is the same for every k (values (points, L, ...)): each step against the next, as two
    same-shaped views (no broadcasting over a short last axis). O(points L k)."""
    return bool(np.array_equal(values[:, 1:], values[:, :-1]))


def leading_run(values: np.ndarray) -> int:
    """The last index h with ``values[:, 0..h]`` all equal to ``values[:, 0]`` (values (points, L, ...)), to the bit:
    how far a backward pass's data are one map. O(points L k).

    Examples
    --------
    >>> leading_run(np.array([[1.0, 1.0, 2.0, 1.0]])), leading_run(np.ones((2, 3, 1)))
    (1, 2)
    """
    points, L = values.shape[:2]
    if all_steps_equal(values):                  # the usual case, one comparison of two views
        return L - 1
    same = np.all((values[:, 1:] == values[:, :-1]).reshape(points, L - 1, -1), axis=2).all(axis=0)
    return int(np.argmin(same)) if not same.all() else L - 1
