"""python-control interop at the bottom layer: the plant of a discrete-time ``control.StateSpace``.

python-control is optional (the ``control`` extra) and imported only when a conversion runs.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError
from .optional import load

__all__ = ["plant_matrices"]


def plant_matrices(sys: Any) -> dict[str, np.ndarray]:
    """``{"A": sys.A, "B": sys.B}`` of a discrete-time ``control.StateSpace`` (C and D are not used:
    the model measures the full state).

    Raises
    ------
    InputError
        Field ``sys``: not a StateSpace, or not discrete time (``dt`` 0 is continuous, None unspecified):
        discretise first, e.g. ``control.c2d(sys, Ts)``.

    Examples
    --------
    >>> import control
    >>> plant_matrices(control.ss([[1.0]], [[0.5]], [[1.0]], [[0.0]], dt=0.1))["B"].tolist()
    [[0.5]]
    """
    control = load("control", "sys")

    if not isinstance(sys, control.StateSpace):
        raise InputError("sys", f"expected a control.StateSpace, found {type(sys).__name__}")
    if not control.isdtime(sys, strict=True):
        raise InputError("sys", f"expected a discrete-time system (dt > 0 or True), found dt = {sys.dt!r}; "
                                "discretise it first, e.g. control.c2d(sys, Ts)")
    return {"A": np.array(sys.A, dtype=float), "B": np.array(sys.B, dtype=float)}
