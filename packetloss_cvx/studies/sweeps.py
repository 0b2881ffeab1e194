"""Optimal costs over grids of delivery probabilities: the data behind the paper's cost figures.

* [`shared_channel_sweep`][packetloss_cvx.studies.sweeps.shared_channel_sweep]: every actuator behind one channel of
probability nu
  (Fig. log-cost-pendulum: log `J*_tcp(nu)`, log `J*_udp(nu)`; and J_Delta(nu));
* [`two_channel_sweep`][packetloss_cvx.studies.sweeps.two_channel_sweep]: two channels over a grid of [0, 1]^2 (Figs.
TCP-log-cost-mixed,
  UDP-log-cost-mixed and cost-diff-mixed).

Each cost is a closed form that passed its own checks, evaluated for all points at once by
[`packetloss_cvx.lq.evaluator.CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator] (equal to
[`packetloss_cvx.closed_form`][packetloss_cvx.lq.costs.closed_form] to rounding). The difference J_Delta = `J*_udp` -
`J*_tcp` is computed without cancellation
([`packetloss_cvx.lq.difference.cost_differences`][packetloss_cvx.lq.difference.cost_differences], all points in stacked
solves) where the dense form is well conditioned, and as the difference of the two checked costs otherwise
(``difference_method`` says which).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..lq.difference import cost_differences
from ..lq.evaluator import CostEvaluator
from ..lq.prediction import prediction
from ..lq.recursion import condition_estimate
from ..model.protocols import PROTOCOLS, check_protocol
from ..model.system import System, numeric_array
from ..results import Sweep
from ..threads import blas_limited
from ..tolerances import DENSE_MAX_CONDITION

__all__ = ["MAX_POINTS", "shared_channel_sweep", "two_channel_sweep"]

#: The most grid points a sweep evaluates (each is one closed form per protocol).
MAX_POINTS = 250_000


def _axis(values: Sequence[float] | np.ndarray, field: str) -> np.ndarray:
    axis = numeric_array(values, field)
    if axis.ndim != 1 or axis.size < 1:
        raise InputError(field, f"expected a non-empty list of probabilities, found shape {axis.shape}")
    if np.any(axis < 0) or np.any(axis > 1):
        raise InputError(field, "expected probabilities in [0, 1]")
    return axis


def _protocols(protocols: Sequence[str]) -> tuple[str, ...]:
    out = tuple(check_protocol(p, "protocols") for p in protocols)
    if not out:
        raise InputError("protocols", "expected at least one of 'tcp', 'udp'")
    return out


def _sweep(system: System, points: list[np.ndarray], shape: tuple[int, ...], protocols: tuple[str, ...],
           axes: tuple[np.ndarray, ...]) -> Sweep:
    if len(points) > MAX_POINTS:
        raise InputError("grid", f"expected at most {MAX_POINTS} points, found {len(points)}")
    costs = {p: CostEvaluator(system, p).costs(np.reshape(points, (-1, system.m))).reshape(shape) for p in protocols}
    difference, how = None, None
    if set(protocols) == set(PROTOCOLS):
        if condition_estimate(system) <= DENSE_MAX_CONDITION:
            pred = prediction(system)   # Phi, Gamma and the Omega products do not depend on mu
            V = np.repeat(np.reshape(points, (-1, 1, system.m)), system.horizon, axis=1).reshape(len(points), -1)
            difference = cost_differences(system, V, pred).reshape(shape)
            how = "cancellation-free (difference.cost_difference)"
        else:
            difference = costs["udp"] - costs["tcp"]
            how = "difference of the two closed forms (the dense form is ill-conditioned here)"
    if difference is not None:
        # exactly 0 where every channel is deterministic (both problems are the same there; the two
        # evaluations differ by rounding, ~1e-17 J*, which made J_Delta negative at (0, 1) or (1, 0))
        flat = np.reshape(points, (-1, system.m))
        difference = np.where(np.all((flat == 0) | (flat == 1), axis=1).reshape(shape), 0.0, difference)
    return Sweep(axes=axes, costs=costs, difference=difference, difference_method=how)


@blas_limited
def shared_channel_sweep(system: System, nus: Sequence[float] | np.ndarray,
                         protocols: Sequence[str] = PROTOCOLS) -> Sweep:
    """J*(nu) with every actuator behind one channel of delivery probability nu.

    Returns a `Sweep` with ``axes = (nus,)``, ``costs[p]`` of
    shape (len(nus),), and, when both protocols are swept, ``difference`` = `J*_udp` - `J*_tcp`.
    Time O(len(nus) · N (n^3 + m^3)), plus O(len(nus) (N m)^3) for the difference.

    Examples
    --------
    >>> from packetloss_cvx.model.files import load_example
    >>> sweep = shared_channel_sweep(load_example("two_actuator"), [0.5, 0.9])
    >>> bool(np.all(np.diff(sweep.costs["tcp"]) < 0))   # Theorem 3: more delivery, less cost
    True
    """
    axis = _axis(nus, "nus")
    points = [np.full(system.m, nu) for nu in axis]
    return _sweep(system, points, (axis.size,), _protocols(protocols), (axis,))


@blas_limited
def two_channel_sweep(system: System, axis: Sequence[float] | np.ndarray,
                      protocols: Sequence[str] = PROTOCOLS) -> Sweep:
    """J*(mu1, mu2) for a two-channel system over ``axis`` × ``axis``.

    ``costs[p][j, i]`` is the cost at ``mu1 = axis[i]``, ``mu2 = axis[j]`` (rows follow mu2, as
    matplotlib's ``contour`` expects). Time O(len(axis)^2 · N (n^3 + m^3)), plus
    O(len(axis)^2 (N m)^3) for the difference.

    Examples
    --------
    Two decoupled copies of x' = x + v u, N = 1: `J*_tcp` = sum 1/(1 + mu_i), `J*_udp` = sum (1 - mu_i/2).

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> sweep = two_channel_sweep(t, [0.0, 0.5])
    >>> bool(np.allclose(sweep.costs["tcp"], [[2, 5 / 3], [5 / 3, 4 / 3]]))
    True
    >>> bool(np.allclose(sweep.difference, sweep.costs["udp"] - sweep.costs["tcp"])), float(sweep.difference[0, 0])
    (True, 0.0)
    """
    if system.m != 2:
        raise InputError("system", f"expected m = 2 channels, found m = {system.m}")
    axis = _axis(axis, "axis")
    points = [np.array([a, b]) for b in axis for a in axis]
    return _sweep(system, points, (axis.size, axis.size), _protocols(protocols), (axis, axis))
