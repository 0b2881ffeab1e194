"""The verdict on a plan's law run in a loop: is u = -K x mean-square stable over the system's channel?

A `Solution` holds the receding-horizon gain K but not the channel, so its
mean-square stability is computed here, from the system it was solved for: with Bernoulli losses the radius
of the second-moment operator at mu ([`mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius]; the
first step's mu when the schedule varies: step 0's law run for ever over the first step's channel, said in the
note), behind a Markov chain (Gilbert-Elliott or k-state) the Markov jump linear system's
(`packetloss_cvx.closedloop.mjls.mean_square_radius`). ``solve`` prints the same verdict.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from ..errors import InputError, NumericalError, ResourceError
from ..lq import costs
from ..model.system import System, check_system
from ..results import LoopStability, Solution
from .mjls import mean_square_radius as markov_radius
from .stability import is_mean_square_stable, mean_square_radius

__all__ = ["STABILITY_MAX_N", "closed_form", "loop_stability", "with_stability"]

#: The verdict is computed by default up to this state dimension (``solve`` and :func:`closed_form`; asked for
#: beyond, skipped on request). Measured (one BLAS thread, per law; ARPACK's hardest cases, an orthogonal A and a
#: chain of integrators, where it does not converge): n = 60 0.5 s, n = 100 4 s, n = 200 33 s (a random n = 200
#: plant: 2 s).
STABILITY_MAX_N = 60


def _numbers(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]" if values.size > 1 else f"{values[0]:.6g}"


def loop_stability(system: System, gain: npt.ArrayLike) -> LoopStability:
    """Mean-square stability of u = -K x run for ever over ``system``'s channel.

    A radius that cannot be computed (an eigenvalue solver that fails, a chain whose 2^m modes exceed the
    budget) is reported with ``radius = None`` and the reason in ``note``: it is not a verdict. Time
    O(n^6) dense for n <= KRONECKER_MAX_N, else ARPACK on the n^2-dimensional operator (minutes at n ~ 100);
    behind a chain, 2^m modes of that.

    Examples
    --------
    x' = x - v K x with P(v = 1) = mu: E[x'^2] = (mu (1 - K)^2 + 1 - mu) x^2, so K = 2/3 at mu = 0.5 gives 5/9,
    and K = 0 (no control of x' = x) gives 1, not stable.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> st = loop_stability(s, [[2 / 3]])
    >>> st.stable, round(st.radius, 12), st.over
    (True, 0.555555555556, 'mu = 0.5')
    >>> loop_stability(s, [[0.0]]).stable
    False
    """
    check_system(system)
    K = np.asarray(gain, dtype=float)
    if K.shape != (system.m, system.n):
        raise InputError("gain", f"expected shape ({system.m}, {system.n}) (m × n) but found {K.shape}")
    mu = system.mu_schedule[0]
    if system.channel is not None:   # the losses are correlated: the loop is a Markov jump linear system
        over, note = "the Markov chain (a Markov jump linear system)", None
    else:
        over = f"mu = {_numbers(mu)}" if system.is_stationary else f"the first step's mu = {_numbers(mu)}"
        note = None if system.is_stationary else (
            f"the channel is non-stationary (the schedule's least mu per channel: "
            f"{_numbers(system.mu_schedule.min(axis=0))}): "
            "this is the verdict on step 0's receding-horizon law run for ever over the first step's channel; a loop "
            "run for ever over a schedule that changes has no such verdict")
    try:
        if system.channel is not None:
            radius = markov_radius(system.A, system.B, system.channel, K)
        else:
            radius = mean_square_radius(system.A, system.B, K, mu)
    except (NumericalError, ResourceError, InputError) as err:   # InputError: a chain of more channels than
        # the MJLS operator takes (2^m modes): the system is valid, only this verdict is out of reach
        return LoopStability(None, False, over, str(err))
    return LoopStability(float(radius), is_mean_square_stable(radius), over, note)


def with_stability(system: System, solution: Solution) -> Solution:
    """``solution`` with its law's [`loop_stability`][packetloss_cvx.closedloop.law_stability.loop_stability] over
    ``system``'s channel attached (shown in its notebook view and ``to_dict()``). ``system`` is the one the plan was
    solved for.

    Examples
    --------
    >>> from packetloss_cvx import closed_form
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> sol = with_stability(s, closed_form(s, "udp"))       # u = -x/2: E[x'^2] = (0.5/4 + 0.5) x^2
    >>> sol.stability.radius, sol.to_dict()["stable"]
    (0.625, True)
    """
    if solution.gain is None:
        raise InputError("solution", "this solution carries no gain K (a QP solved with with_gain=False): "
                                     "solve it with closed_form(system, protocol) or with_gain=True")
    return dataclasses.replace(solution, stability=loop_stability(system, solution.gain))


def closed_form(system: System, protocol: str, method: str = "auto", stability: bool | None = None) -> Solution:
    """Theorem 1's optimal plan ([`packetloss_cvx.lq.costs.closed_form`][packetloss_cvx.lq.costs.closed_form], the same
    numbers) with the mean-square
    verdict of its receding-horizon law u = -K x run for ever over ``system``'s channel attached
    ([`with_stability`][packetloss_cvx.closedloop.law_stability.with_stability]), shown in its repr, notebook view and
    ``to_dict()``.

    Parameters
    ----------
    system, protocol, method
        As [`packetloss_cvx.lq.costs.closed_form`][packetloss_cvx.lq.costs.closed_form].
    stability : bool or None
        None (default): the verdict where it is cheap, n <= `STABILITY_MAX_N` (as ``solve``); True: at any n
        (minutes at n ~ 200); False: the plan alone.

    Returns
    -------
    Solution
        ``stability`` set (a radius that cannot be computed is reported with the reason, not as a verdict), or
        None where skipped.

    Raises
    ------
    As [`packetloss_cvx.lq.costs.closed_form`][packetloss_cvx.lq.costs.closed_form].

    Examples
    --------
    x' = 2 x + v u, N = 1, weights 1 and 2, UDP-like: E[(2x + v u)^2 + 2 v u^2] is least at u = -2x/3, so
    A - B K = 4/3: the law is unstable even with every packet delivered, and at mu = 1/2 its second moment grows by
    (4/3)^2 / 2 + 4 / 2 = 26/9 a step.

    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[2.0], mu=[0.5], x0=[1.0])
    >>> sol = closed_form(s, "udp")
    >>> round(sol.stability.radius, 12), sol.stability.stable, closed_form(s, "udp", stability=False).stability
    (2.888888888889, False, None)
    """
    solution = costs.closed_form(system, protocol, method)
    if stability is False or (stability is None and system.n > STABILITY_MAX_N):
        return solution
    return with_stability(system, solution)
