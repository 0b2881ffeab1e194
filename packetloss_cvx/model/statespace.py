"""python-control interop at the bottom layer: a discrete-time ``control.StateSpace`` to and from the plant
``x+ = A x + B u`` and its sampling time.

python-control is optional (the ``control`` extra) and imported only when a conversion runs. The sampling
time is metadata (nothing this package computes depends on it: the model is indexed by steps); python-control's
``dt = True`` (discrete, unspecified) is ``None`` here.
"""

from __future__ import annotations

import numbers
import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import InputError
from ..optional import load

__all__ = ["labels_field", "plant_matrices", "plant_statespace", "sampling_time", "user_labels"]

#: python-control's generated names (``u[0]``, ``x[1]``, ``sys[3]``): not a user's, so not kept
_GENERATED = re.compile(r"^(u|x|y|sys)\[\d+\]$")


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


def labels_field(value: Any, field: str, count: int) -> tuple[str, ...] | None:
    """Signal names: None, or ``count`` distinct non-empty strings, as a tuple. O(count).

    Raises
    ------
    InputError
        Named ``field``: not a list of strings, a wrong count, an empty or repeated name.

    Examples
    --------
    >>> labels_field(["F1", "F2"], "input_labels", 2), labels_field(None, "input_labels", 2)
    (('F1', 'F2'), None)
    >>> labels_field(["F1", "F1"], "input_labels", 2)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: input_labels: expected 2 distinct non-empty names, found ['F1', 'F1']
    """
    if value is None:
        return None
    if isinstance(value, str) or not isinstance(value, Sequence) or not all(isinstance(v, str) for v in value):
        raise InputError(field, f"expected a list of {count} names (strings), found {type(value).__name__}")
    names = tuple(value)
    if len(names) != count or len(set(names)) != count or not all(names):
        raise InputError(field, f"expected {count} distinct non-empty names, found {list(names)[:8]!r}")
    return names


def user_labels(names: Sequence[str]) -> list[str] | None:
    """``names`` unless every one is python-control's generated default (``u[0]``, ``x[1]``): None then. O(len).

    >>> user_labels(["u[0]", "u[1]"]), user_labels(["F1", "u[1]"])
    (None, ['F1', 'u[1]'])
    """
    names = list(names)
    return None if all(_GENERATED.match(str(v)) for v in names) else names


def plant_matrices(sys: Any) -> dict[str, Any]:
    """``{"A": sys.A, "B": sys.B, "dt": sys.dt}`` of a discrete-time ``control.StateSpace``, with ``dt`` None
    where python-control has True (discrete, unspecified), and the names a user gave: ``name`` (``sys.name``),
    ``input_labels`` and ``state_labels`` (python-control's generated ``sys[k]``, ``u[i]``, ``x[i]`` are not
    kept). C and D are not used: the model measures the full state. O(n (n + m)).

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
    out: dict[str, Any] = {"A": np.array(sys.A, dtype=float), "B": np.array(sys.B, dtype=float), "dt": dt}
    name = getattr(sys, "name", None)
    if isinstance(name, str) and name and not _GENERATED.match(name):
        out["name"] = name
    for key, attr in (("input_labels", "input_labels"), ("state_labels", "state_labels")):
        labels = user_labels(getattr(sys, attr, []) or [])
        if labels is not None:
            out[key] = labels
    return out


def plant_statespace(A: np.ndarray, B: np.ndarray, dt: float | None, name: str | None = None,
                     input_labels: Sequence[str] | None = None, state_labels: Sequence[str] | None = None) -> Any:
    """The plant ``x+ = A x + B u`` as a discrete-time ``control.StateSpace``: the m actuators' commands in,
    the full state out (C = I, D = 0; the outputs named as the states), sampling time ``dt`` (None: True, discrete
    and unspecified), named ``name`` with its signals' names where given (else python-control's). Every
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
    names: dict[str, Any] = {}
    if name:
        names["name"] = name
    if input_labels is not None:
        names["inputs"] = list(input_labels)
    if state_labels is not None:
        names["states"] = list(state_labels)
        names["outputs"] = list(state_labels)
    return control.StateSpace(A, B, np.eye(n), np.zeros((n, m)), True if dt is None else sampling_time(dt), **names)
