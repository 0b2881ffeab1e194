"""The QP twin's cross-check: a plan and its cost against a reference solution (the closed form).

Split out of :mod:`.qp` (which re-exports :func:`compare`); :mod:`.markov.qp` uses it too. O(N m).
"""

from __future__ import annotations

import numpy as np

from .errors import CrossCheckError, InputError
from .model import System
from .results import CrossCheck, Solution
from .tolerances import CROSS_CHECK_COST_RTOL, CROSS_CHECK_FLOOR, CROSS_CHECK_INPUT_ATOL

__all__ = ["compare"]


def compare(inputs: np.ndarray, cost: float, reference: Solution, system: System,
            scale: tuple[float, float] = (0.0, 0.0)) -> CrossCheck:
    """Compare a plan and its cost with ``reference``; raise :class:`CrossCheckError` naming both
    numbers unless the mean applied inputs agree, ``max|Vbar (U - U*)| <= CROSS_CHECK_INPUT_ATOL
    max(max|Vbar U*|, CROSS_CHECK_FLOOR s_x)``, and the costs agree relatively, ``|J - J*| <=
    CROSS_CHECK_COST_RTOL max(|J*|, CROSS_CHECK_FLOOR s_J)``. ``scale = (s_J, s_x)`` is the
    problem's own size (largest weight times max|x0|^2, and max|x0|): below a billionth of it
    a difference is rounding, and an exact zero on one side can only be matched that way.

    The mean applied input ``Vbar U`` is what the cost sees: an input over a channel that
    (almost) never delivers is (almost) free, so it is compared through its delivery probability.

    Examples
    --------
    >>> from packetloss_cvx.costs import closed_form
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ref = closed_form(s, "tcp")                     # min (1 + u/2)^2 + u^2/2: u = -2/3, J = 2/3
    >>> compare(np.array([[-2 / 3]]), 2 / 3, ref, s).cost_rel_diff < 1e-12
    True
    >>> compare(np.array([[-0.5]]), 0.75, ref, s)      # the UDP-like optimum is not the TCP-like one
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.CrossCheckError: the QP twin and the closed form disagree: J_qp = 0.75, ...
    """
    if not isinstance(reference, Solution):
        raise InputError("reference", f"expected a Solution (e.g. from closed_form), found {type(reference).__name__}")
    expected = np.asarray(reference.inputs)
    if expected.shape != inputs.shape:
        raise InputError("reference", f"expected a Solution of this system (inputs of shape {inputs.shape}), "
                                      f"found inputs of shape {expected.shape}")
    mu = system.mu_schedule
    diff = float(np.abs(mu * (inputs - expected)).max(initial=0.0))
    input_scale = max(float(np.abs(mu * expected).max(initial=0.0)), CROSS_CHECK_FLOOR * scale[1])
    delta = abs(cost - reference.cost)
    cost_scale = max(abs(reference.cost), CROSS_CHECK_FLOOR * scale[0])
    rel = delta / cost_scale if cost_scale > 0 else (0.0 if delta == 0 else float("inf"))
    if not (diff <= CROSS_CHECK_INPUT_ATOL * input_scale and rel <= CROSS_CHECK_COST_RTOL):
        raise CrossCheckError(
            f"the QP twin and the closed form disagree: J_qp = {cost:.10g}, J* = {reference.cost:.10g} "
            f"({reference.method}), rel dJ = {rel:.1e} (tolerance {CROSS_CHECK_COST_RTOL:.0e}), max|Vbar dU| = "
            f"{diff:.1e} (tolerance {CROSS_CHECK_INPUT_ATOL * input_scale:.1e})",
            {"qp": cost, reference.method: reference.cost})
    return CrossCheck(reference_method=reference.method, max_input_diff=diff, cost_rel_diff=rel)
