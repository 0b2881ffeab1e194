"""The verdict on a plan's law run in a loop: is u = -K x mean-square stable over the system's channel?

A `Solution` holds the receding-horizon gain K but not the channel, so its
mean-square stability is computed here, from the system it was solved for: with Bernoulli losses the radius
of the second-moment operator at mu ([`mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius]; the
first step's mu when the schedule varies), behind a Markov chain (Gilbert-Elliott or k-state) the Markov jump linear
system's (`packetloss_cvx.closedloop.mjls.mean_square_radius`). ``solve`` prints the same verdict.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from ..errors import InputError, NumericalError, ResourceError
from ..model.system import System, check_system
from ..results import LoopStability, Solution
from .mjls import mean_square_radius as markov_radius
from .stability import is_mean_square_stable, mean_square_radius

__all__ = ["loop_stability", "with_stability"]


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
        over = f"mu = {_numbers(mu)}"
        note = None if system.is_stationary else "first step's mu: the channel is non-stationary"
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
