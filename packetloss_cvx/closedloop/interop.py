"""python-control interop for closed loops: the mean dynamics of a law as a ``control.StateSpace``.

python-control is optional (the ``control`` extra) and imported only here, when a conversion runs.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..model.system import System
from ..optional import load
from .moments import stationary_channel
from .stability import check_law

__all__ = ["closed_loop_statespace"]


def closed_loop_statespace(system: System, gain: npt.ArrayLike, mu: npt.ArrayLike | None = None,
                           dt: float | bool | str = "auto", name: str | None = None) -> Any:
    """The closed loop of ``u = -K x`` over the channel as a discrete-time ``control.StateSpace``.

    Its dynamics are the mean's: ``E[x+] = (A - B M K) E[x] + w`` with ``M = diag(mu)``; input ``w``
    (the process noise, n inputs named ``w[i]``, or ``w_<state>`` after the system's ``state_labels``), output
    the state (C = I, D = 0; named ``x[i]`` or as the states), the system named ``name`` (default: the system's
    name and "closed loop", or "closed loop"). Its poles are the eigenvalues of
    ``A - B M K``: the mean converges iff they lie inside the unit circle, which is necessary for, but
    weaker than, mean-square stability ([`mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius]).
    Time O(n^2 m).

    Parameters
    ----------
    system : System
    gain : array_like, shape (m, n)
    mu : array_like, optional
        Default: the system's stationary channel.
    dt : float, True or "auto"
        The sampling time (True: discrete, unspecified); "auto" (default): the system's ``dt``, True when it
        has none. 0, None or a negative time is an InputError (the loop's matrix is a discrete-time one).

    Examples
    --------
    >>> from packetloss_cvx import load_example
    >>> s = load_example("two_actuator")
    >>> cl = closed_loop_statespace(s, [[1.0, 0.0], [0.0, 1.0]], dt=0.1)
    >>> bool(np.allclose(cl.A, s.A - s.B @ np.diag(s.mu) @ np.eye(2))), cl.dt
    (True, 0.1)
    >>> cl.name, cl.input_labels, cl.output_labels
    ('two-actuator closed loop', ['w[0]', 'w[1]'], ['x[0]', 'x[1]'])
    """
    control = load("control", "closed_loop_statespace")

    if isinstance(dt, str) and dt == "auto":
        dt = True if system.dt is None else system.dt
    if dt is not True and (isinstance(dt, bool) or not isinstance(dt, int | float | np.integer | np.floating)
                           or not (np.isfinite(dt) and dt > 0)):
        # dt = 0 would declare A - B M K a continuous-time matrix, None an unspecified timebase
        raise InputError("dt", f"expected a sampling time > 0 or True (discrete time), found {dt!r}")
    A, B, K, mu_ = check_law(system.A, system.B, gain, stationary_channel(system) if mu is None else mu)
    n = A.shape[0]
    states = list(system.state_labels) if system.state_labels is not None else [f"x[{i}]" for i in range(n)]
    noise = [f"w_{x}" for x in states] if system.state_labels is not None else [f"w[{i}]" for i in range(n)]
    if name is None:
        name = f"{system.name} closed loop" if system.name else "closed loop"
    return control.StateSpace(A - (B * mu_) @ K, np.eye(n), np.eye(n), np.zeros((n, n)), dt, inputs=noise,
                              outputs=states, states=states, name=name)
