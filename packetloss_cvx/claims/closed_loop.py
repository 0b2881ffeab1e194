"""The paper's ranking of the protocols, put to the test the way a designer pays for it: both
receding-horizon laws run in closed loop, their expected costs computed exactly from second moments."""

from __future__ import annotations

import numpy as np

from ..closedloop.moments import finite_horizon_costs
from ..lq.costs import closed_form
from ..model.system import System
from ..results import ClaimResult
from ..threads import blas_limited
from .context import Context, loop_case
from .evaluate import evaluate
from .ordering import case_ids, optimal_plan

__all__ = ["STEPS", "protocol_ranking"]

#: Closed-loop steps of the compared costs (the sampled check this replaces ran 40).
STEPS = 40
#: Relative rounding of the exact costs: a difference within it is a tie (the claim holds).
TIE_RTOL = 1e-9


def exact_cost(system: System, protocol: str, steps: int = STEPS, gain: np.ndarray | None = None) -> float:
    """E[sum_{t<steps} x_t'Omega_1 x_t + (V u_t)'Psi_0 (V u_t) + x_steps'Omega_1 x_steps] from x0, with noise, for the
    protocol's receding-horizon law u = -K x (``gain``: K when the caller has it, else closed_form's);
    ``inf`` when it overflows. Time O(steps n^3)."""
    K = closed_form(system, protocol).gain if gain is None else gain
    stage, terminal = finite_horizon_costs(loop_case(system), K, steps)
    with np.errstate(over="ignore", invalid="ignore"):
        return float(stage.sum() + terminal)


@blas_limited
def protocol_ranking(ctx: Context) -> ClaimResult:
    """The TCP-like law costs less than the UDP-like one in closed loop (stationary cases, exact costs).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ctx = Context(paper={}, random=[s], seed=0)
    >>> r = protocol_ranking(ctx)     # x0' P_K x0 = (1 + K^2/2) / (K - K^2/2): 2.75 (K = 2/3), 3 (K = 1/2)
    >>> r.verdict, bool(np.isclose(r.worst, (3 - 2.75) / 3, atol=1e-7))
    ('holds', True)
    """
    cases = case_ids(ctx)

    def margin(s: System) -> float | None:
        if not s.is_stationary:
            return None
        tcp, udp = (exact_cost(s, p, gain=optimal_plan(ctx, s, p, id(s) in cases).gain) for p in ("tcp", "udp"))
        if not (np.isfinite(tcp) and np.isfinite(udp)):
            return None if tcp == udp else (1.0 if udp > tcp else -1.0)
        return (udp - tcp) / max(tcp, udp, np.finfo(float).tiny) + TIE_RTOL   # < 0: the UDP-like law is cheaper
    return evaluate("protocol-ranking-closed-loop", ctx, ctx.cases, margin,
                    f"Receding-horizon laws u = -K x run in closed loop for {STEPS} steps from x0 (stationary cases, "
                    "noise included, stage weights Omega_1 and Psi_0, terminal x_T'Omega_1 x_T); expected costs exact "
                    "from second moments (no sampling). Margin = (cost_udp - cost_tcp) / max + 1e-9 (a tie holds); "
                    "an overflowing cost counts as infinite. With full state feedback both laws see the same state; "
                    "the UDP-like law is the one that accounts for the loss variance, so it can be the cheaper one.")
