"""python-control interop at the bottom layer: a discrete-time ``control.StateSpace`` to and from the plant
``x+ = A x + B u`` and its sampling time.

python-control is optional (the ``control`` extra) and imported only when a conversion runs. The sampling
time is metadata (nothing this package computes depends on it: the model is indexed by steps); python-control's
``dt = True`` (discrete, unspecified) is ``None`` here.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np

from ..errors import InputError
from ..optional import load

__all__ = ["plant_matrices", "plant_statespace", "sampling_time"]


def sampling_time(value: Any, field: str = "dt") -> float | None:
    """``value`` as a sampling time in seconds: a finite number > 0, or None (unspecified). O(1).

    Raises
    ------
    InputError
        Named ``field``: a bool, a string, 0, a negative or a non-finite number.

    Examples
    --------
    >>> sampling_time(0.05), sampling_time(1), sampling_time(None)
    (0.05, 1.0, None)
    >>> sampling_time(0)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: dt: expected a sampling time > 0 in seconds (or none), found 0
    """
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (np.isfinite(value) and value > 0):
        raise InputError(field, f"expected a sampling time > 0 in seconds (or none), found {value!r}")
    return float(value)


def plant_matrices(sys: Any) -> dict[str, Any]:
    """``{"A": sys.A, "B": sys.B, "dt": sys.dt}`` of a discrete-time ``control.StateSpace``, with ``dt`` None
    where python-control has True (discrete, unspecified). C and D are not used: the model measures the full
    state. O(n (n + m)).

    Raises
    ------
    InputError
        Field ``sys``: not a StateSpace, or not discrete time (``dt`` 0 is continuous, None unspecified):
        discretise first, e.g. ``control.c2d(sys, Ts)``.

    Examples
    --------
    >>> import control
    >>> plant = plant_matrices(control.ss([[1.0]], [[0.5]], [[1.0]], [[0.0]], dt=0.1))
    >>> plant["B"].tolist(), plant["dt"], plant_matrices(control.ss([[1.0]], [[0.5]], [[1.0]], [[0.0]], True))["dt"]
    ([[0.5]], 0.1, None)
    """
    control = load("control", "sys")

    if not isinstance(sys, control.StateSpace):
        raise InputError("sys", f"expected a control.StateSpace, found {type(sys).__name__}")
    if not control.isdtime(sys, strict=True):
        raise InputError("sys", f"expected a discrete-time system (dt > 0 or True), found dt = {sys.dt!r}; "
                                "discretise it first, e.g. control.c2d(sys, Ts)")
    dt = None if sys.dt is True else sampling_time(sys.dt, "sys.dt")
    return {"A": np.array(sys.A, dtype=float), "B": np.array(sys.B, dtype=float), "dt": dt}


def plant_statespace(A: np.ndarray, B: np.ndarray, dt: float | None) -> Any:
    """The plant ``x+ = A x + B u`` as a discrete-time ``control.StateSpace``: the m actuators' commands in,
    the full state out (C = I, D = 0), sampling time ``dt`` (None: True, discrete and unspecified). Every
    packet delivered: the loss model is not a linear system
    ([`closed_loop_statespace`][packetloss_cvx.closedloop.interop.closed_loop_statespace]
    gives a law's mean closed loop). O(n (n + m)).

    Examples
    --------
    >>> ss = plant_statespace(np.array([[1.0]]), np.array([[0.5]]), 0.1)
    >>> ss.B.tolist(), ss.C.tolist(), ss.dt, plant_statespace(np.eye(1), np.eye(1), None).dt
    ([[0.5]], [[1.0]], 0.1, True)
    """
    import control  # lazy: an optional dependency

    n, m = B.shape
    return control.StateSpace(A, B, np.eye(n), np.zeros((n, m)), True if dt is None else sampling_time(dt))
