"""Critical delivery probabilities: where along a ray ``mu = t * direction`` a loop becomes mean-square stable."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ..errors import InputError, NumericalError
from ..lq.costs import closed_form
from ..model.system import System
from ..results.region import CriticalPoint, Membership
from ..tolerances import CRITICAL_MU_TOL
from .certificates import law_proved_stable
from .moments import stationary_channel
from .region import LazyLmi, membership
from .stability import check_law, is_mean_square_stable, mean_square_radius

__all__ = ["critical_mu", "critical_point", "law_membership", "stable_at"]

#: the fractions of an undecided bracket tried after its midpoint (a point within about 1e-9 of the
#: boundary of S has no checkable certificate either way)
_RETRY_FRACTIONS = (0.25, 0.75, 0.125, 0.875)


def law_membership(system: System, law: str | npt.ArrayLike, mu: np.ndarray, lmi: LazyLmi | None = None,
                   riccati: tuple[float, np.ndarray, np.ndarray] | None = None) -> Membership:
    """The loop of ``law`` over channel ``mu``: decided with its evidence.

    ``law``: a fixed gain (m×n), or "tcp"/"udp" (the receding-horizon law re-designed for ``mu``: the first
    gain of Theorem 1's closed form), verdict "stable" iff its radius is below 1 by the margin and an exact witness
    proves it (certificates.law_proved_stable), else "unstable" (not proved stable); or "dp" (the DP optimum for
    ``mu``: stable iff mu is in the stabilisable set, [`membership`][packetloss_cvx.closedloop.region.membership],
    "undecided" where no certificate can be checked; ``riccati``: the homogeneous Riccati eigenpair at mu when the
    caller has it, as there). Time: one design, one radius and its witness (O(n^6)); "dp" as
    [`membership`][packetloss_cvx.closedloop.region.membership] without the cross-check.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> found = law_membership(s, [[2.0]], np.array([0.9]))   # k = a: radius a^2 (1 - mu) = 0.4
    >>> found.verdict, round(found.radius, 12)
    ('stable', 0.4)
    """
    if isinstance(law, str):
        if law == "dp":
            return membership(system, mu, cross_check=False, lmi=lmi, riccati=riccati)
        if law not in ("tcp", "udp"):
            raise InputError("law", f"expected tcp, udp, dp or a gain matrix, found {law!r}")
        K = closed_form(system.with_mu(mu), law).gain
    else:
        K = law
    A, B, K_, mu_ = check_law(system.A, system.B, K, mu)
    radius = mean_square_radius(A, B, K_, mu_)
    verdict = "stable" if is_mean_square_stable(radius) and law_proved_stable(A, B, K_, mu_, radius) else "unstable"
    return Membership(mu_, verdict, K_, radius, None, float("nan"), (("radius", verdict),))


def stable_at(system: System, law: str | npt.ArrayLike, mu: np.ndarray) -> bool:
    """Is the loop proved mean-square stable over channel ``mu``?
        ([`law_membership`][packetloss_cvx.closedloop.critical.law_membership].)

    Raises
    ------
    NumericalError
        For "dp", when no certificate can be checked either way (a numerical failure is not a verdict).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> [stable_at(s, [[2.0]], np.array([mu])) for mu in (0.7, 0.8)]   # k = a: radius a^2 (1 - mu) = 1.2, 0.8
    [False, True]
    >>> [stable_at(s, "dp", np.array([mu])) for mu in (0.7, 0.8)]      # scalar critical mu: 1 - 1/a^2 = 0.75
    [False, True]
    """
    found = law_membership(system, law, mu)
    if found.stable is None:
        raise NumericalError(found.reason)
    return found.stable


def critical_point(system: System, law: str | npt.ArrayLike, direction: npt.ArrayLike | None = None,
                   tol: float = CRITICAL_MU_TOL,
                   stable: Callable[[np.ndarray], bool] | None = None,
                   decide: Callable[[np.ndarray], Membership] | None = None,
                   end: float | None = None) -> CriticalPoint:
    """The boundary of a law's region along ``mu = t * direction``, bracketed by two decided points.

    Bisection in t that moves an end only to a decided point (an undecided midpoint is replaced by
    another point of the bracket, `_RETRY_FRACTIONS`): the upper end keeps a stabilising gain,
    the lower end (for "dp") an infeasibility certificate. For "dp" the region is monotone in mu
    (docs/mathematics.md §2), so the ray meets its boundary once and the bracket holds the exact critical
    point; for another law, stability need not be monotone along the ray and this is one crossing.
    ``decide`` (mu -> Membership) replaces the law's membership with another region's, monotone along the ray
    by its own proof (e.g. markov_region's mean rates behind a chain), and ``end`` the ray's end in t (default
    ``1 / max(direction)``). ``direction`` defaults to all ones, as on the command line. Time O(log2(1 / tol))
    memberships.

    Raises
    ------
    NumericalError
        For "dp": the ray's end, or mu = 0, is undecided. (A bracket that cannot be narrowed to ``tol``, no
        point inside it decided, is returned with its proved ends and a ``note`` saying so.)

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[0.1], mu=[1.0], x0=[1.0])
    >>> p = critical_point(s, "dp")              # exact: 1 - 1/a^2 = 0.75, bracketed by two certificates
    >>> bool(p.lower <= 0.75 <= p.t <= p.lower + 1e-6), p.inside.verdict, p.outside.verdict
    (True, 'stable', 'unstable')
    """
    if direction is None:          # the default ray, all ones (as the command line's); a chain or a schedule is
        stationary_channel(system)  # refused as before: its region is not the Bernoulli one
    d = np.asarray(np.ones(system.m) if direction is None else direction, dtype=float).reshape(-1)
    if d.shape != (system.m,) or np.any(d < 0) or not np.any(d > 0) or not np.all(np.isfinite(d)):
        raise InputError("direction", f"expected {system.m} nonnegative numbers, not all zero")
    if not tol > 0:
        raise InputError("tol", f"expected a positive width, found {tol!r}")
    name = law if isinstance(law, str) else "gain"
    lmi = LazyLmi(system.A, system.B)   # built on first use, once for the whole bisection
    given = decide

    def decide(t: float) -> Membership:
        mu = t * d
        if given is not None:
            return given(mu)
        if stable is not None:
            verdict = "stable" if stable(mu) else "unstable"
            return Membership(mu, verdict, None, float("nan"), None, float("nan"), (("stable", verdict),))
        return law_membership(system, law, mu, lmi=lmi)

    lo, hi = 0.0, (1.0 / float(d.max()) if end is None else float(end))
    top = decide(hi)
    if top.verdict != "stable":
        if top.verdict == "undecided":
            raise NumericalError(f"critical mu: the ray's end is undecided ({top.reason})")
        return CriticalPoint(name, d, float("inf"), hi, None, top)
    bottom = decide(lo)
    if bottom.verdict == "stable":
        return CriticalPoint(name, d, 0.0, 0.0, bottom, None)
    if bottom.verdict == "undecided":
        raise NumericalError(f"critical mu: mu = 0 is undecided ({bottom.reason})")
    inside, outside = top, bottom
    note = ""
    while hi - lo > tol:
        for fraction in (0.5, *_RETRY_FRACTIONS):
            mid = lo + fraction * (hi - lo)
            if not lo < mid < hi:
                break
            found = decide(mid)
            if found.verdict != "undecided":
                break
        else:   # both ends stay proved: a wider bracket is an answer, not a failure
            note = (f"the bracket is {hi - lo:.3g} wide, wider than tol = {tol:g}: no point inside it could be "
                    "decided (near the boundary every certificate's margin vanishes); both ends are proved")
            break
        if not lo < mid < hi:   # adjacent doubles: a tol below the spacing of floats cannot be met
            break
        if found.verdict == "stable":
            hi, inside = mid, found
        else:
            lo, outside = mid, found
    return CriticalPoint(name, d, hi, lo, inside, outside, note)


def critical_mu(system: System, law: str | npt.ArrayLike, direction: npt.ArrayLike | None = None,
                tol: float = CRITICAL_MU_TOL, stable: Callable[[np.ndarray], bool] | None = None) -> CriticalPoint:
    """The critical delivery probabilities of a law: where its region meets the ray ``mu = t * direction``, by
    bisection in t ([`critical_point`][packetloss_cvx.closedloop.critical.critical_point]).

    Parameters
    ----------
    system : System
    law : str or array_like
        As in [`law_membership`][packetloss_cvx.closedloop.critical.law_membership]: a fixed gain, or "tcp" / "udp" /
        "dp" re-designed at each mu.
    direction : array_like, optional
        Nonnegative, not all zero; default all ones (every channel alike, as ``region --direction`` on the
        command line); t runs over [0, 1 / max(direction)].
    tol : float
        Width of the final bracket in t (at best the spacing of doubles near the answer).
    stable : callable, optional
        Replaces [`stable_at`][packetloss_cvx.closedloop.critical.stable_at] (mu -> bool), e.g. for another law.

    Returns
    -------
    CriticalPoint
        ``mu``: the critical mu ``t * direction`` (the upper end of the final bracket, a stable point; inf
        entries when the loop is not stable even at the ray's end, zeros when it is stable at mu = 0); ``t``
        beside it, the bracket ``[lower, t]`` and both ends' evidence. For "dp" the exact critical point lies
        in the bracket (a numerical failure is never read as "unstable"). Time O(log2(1 / tol)) designs and
        radii.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> point = critical_mu(s, [[2.0]], tol=1e-4)     # fixed k = a: a^2 (1 - mu) < 1 iff mu > 1 - 1/a^2
    >>> np.round(point.mu, 3).tolist(), round(point.t, 3)
    ([0.75], 0.75)
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[0.1], mu=[1.0], x0=[1.0])
    >>> bool(abs(critical_mu(s, "dp").mu[0] - 0.75) <= 1e-6)    # the DP law's region: mu > 1 - 1/a^2, to the tol
    True
    """
    return critical_point(system, law, direction, tol, stable)
