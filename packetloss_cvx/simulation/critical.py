"""Critical delivery probabilities: where along a ray ``mu = t * direction`` a loop becomes mean-square stable."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ..costs import closed_form
from ..errors import InputError, NumericalError
from ..model import System
from ..tolerances import CRITICAL_MU_TOL
from .moments import stationary_channel
from .riccati import dp_riccati
from .stability import check_law, is_mean_square_stable, mean_square_radius

__all__ = ["critical_mu", "stable_at"]


def stable_at(system: System, law: str | npt.ArrayLike, mu: np.ndarray) -> bool:
    """Is the loop proved mean-square stable over channel ``mu``?

    ``law``: a fixed gain (m×n), or "tcp"/"udp" (the receding-horizon law re-designed for ``mu``:
    the first gain of Theorem 1's closed form) or "dp" (the DP optimum for ``mu``: stable iff the
    modified Riccati equation has a stabilising solution). Time: one design plus one radius.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> [stable_at(s, [[2.0]], np.array([mu])) for mu in (0.7, 0.8)]   # k = a: radius a^2 (1 - mu) = 1.2, 0.8
    [False, True]
    >>> [stable_at(s, "dp", np.array([mu])) for mu in (0.7, 0.8)]      # scalar critical mu: 1 - 1/a^2 = 0.75
    [False, True]
    """
    if isinstance(law, str):
        if law == "dp":
            try:
                dp_riccati(system, mu)
            except NumericalError:
                return False
            return True
        if law not in ("tcp", "udp"):
            raise InputError("law", f"expected tcp, udp, dp or a gain matrix, found {law!r}")
        K = closed_form(system.with_mu(mu), law).gain
    else:
        K = law
    A, B, K_, mu_ = check_law(system.A, system.B, K, mu)
    return is_mean_square_stable(mean_square_radius(A, B, K_, mu_))


def critical_mu(system: System, law: str | npt.ArrayLike, direction: npt.ArrayLike | None = None,
                tol: float = CRITICAL_MU_TOL, stable: Callable[[np.ndarray], bool] | None = None) -> float:
    """The least ``t`` with a mean-square stable loop over ``mu = t * direction``, by bisection.

    Parameters
    ----------
    system : System
    law : str or array_like
        As in :func:`stable_at`: a fixed gain, or "tcp" / "udp" / "dp" re-designed at each mu.
    direction : array_like, optional
        Nonnegative, not all zero (default: the system's channel); t runs over [0, 1 / max(direction)].
    tol : float
        Width of the final bracket in t (at best the spacing of doubles near the answer).
    stable : callable, optional
        Replaces :func:`stable_at` (mu -> bool), e.g. for another law.

    Returns
    -------
    float
        The upper end of the final bracket (a stable point); ``inf`` when the loop is not stable even
        at the ray's end, 0.0 when it is stable at mu = 0. If stability is not monotone along the
        ray, this is one crossing between an unstable and a stable point, not necessarily the only one.
        Time O(log2(1 / tol)) designs and radii.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> round(critical_mu(s, [[2.0]], tol=1e-4), 3)   # fixed k = a: a^2 (1 - mu) < 1 iff mu > 1 - 1/a^2
    0.75
    """
    d = np.asarray(stationary_channel(system) if direction is None else direction, dtype=float).reshape(-1)
    if d.shape != (system.m,) or np.any(d < 0) or not np.any(d > 0) or not np.all(np.isfinite(d)):
        raise InputError("direction", f"expected {system.m} nonnegative numbers, not all zero")
    if not tol > 0:
        raise InputError("tol", f"expected a positive width, found {tol!r}")
    test = stable if stable is not None else (lambda mu: stable_at(system, law, mu))
    lo, hi = 0.0, 1.0 / float(d.max())
    if not test(hi * d):
        return float("inf")
    if test(lo * d):
        return 0.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:   # adjacent doubles: a tol below the spacing of floats cannot be met
            break
        if test(mid * d):
            hi = mid
        else:
            lo = mid
    return hi
