"""cost-split-sensor (not the paper's): over a lossy sensor link, the DP law on the TCP-like Kalman
estimate costs the full-state optimum plus an estimation part. Each case measures its first state over one
link (gamma = 0.9, R = 0.01; Sigma_W = 0.01 I where the case has no noise); the split is checked exactly on the
loop with stationary filter gains (sensing.loop), and on the paper's systems also by simulating the
time-varying filter (sensing.montecarlo: cost against ``tr(P Sigma_W) + tr(K'HK mean P_k)``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from ..closedloop.riccati import NO_SOLUTION, dp_input_hessian, dp_riccati
from ..errors import NumericalError
from ..model.files import system_from_dict
from ..model.system import System
from ..results import ClaimResult, Riccati
from ..sensing.loop import estimated_loop
from ..sensing.montecarlo import simulate_estimated
from ..tolerances import RESOLVED_MIN
from .context import Context, loop_case
from .evaluate import Tally, resolved

__all__ = ["STATEMENT", "cost_split_sensor", "sensed"]

STATEMENT = ("(Not the paper's.) With the first state measured over a lossy link (gamma = 0.9), the DP "
             "law on the TCP-like Kalman estimate costs tr(P Sigma_W) (the full-state optimum) plus the "
             "estimation part tr(K'HK E[e e']): the cost splits into a control and an estimation part.")
#: |cost - (control + estimation)| / cost allowed on the exact loop (rounding of two moment solves)
SPLIT_RTOL = 1e-9
#: the simulated split on the paper's systems: runs, the longest window, and the |z| that counts as a violation
RUNS, MAX_STEPS, Z_MAX = 1000, 2000, 4.0
#: the window is long enough for the transient to be gone by its kept half: radius^(steps/2) at most this
MIXED = 1e-3


def sensed(system: System) -> System | None:
    """``system`` measuring its first state over one link (gamma 0.9, R 0.01), with Sigma_W = 0.01 I if it has no
    noise; None for a non-stationary or Gilbert-Elliott actuator channel. O(n^2).

    >>> s = sensed(System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1]))
    >>> s.sensor.gamma.tolist(), s.noise_cov.tolist()
    ([0.9], [[0.01]])
    """
    if not system.is_stationary or system.channel is not None:
        return None
    data = loop_case(system).to_dict()        # the loop's one weight: the case's first stage's
    if not np.any(system.noise_cov):
        data["plant"]["noise_cov"] = (0.01 * np.eye(system.n)).tolist()
    data["sensor"] = {"C": np.eye(system.n)[:1].tolist(), "gamma": [0.9], "noise_cov": [[0.01]]}
    return system_from_dict(data)


def _split(system: System, solve: Callable[[System], Riccati] | None = None
           ) -> tuple[float, float, float, System, Any, float] | None:
    """The exact loop's cost and parts on ``sensed(system)``, the twin, its DP and the loop's radius (None where the
    claim does not apply). ``solve``: the DP of ``system`` itself when the caller keeps it (the audit's
    `Context.dp`, solved for mpc-vs-dp already): the DP depends on A, B, mu and the weights only, so the
    twin's is the case's with the twin's noise in its average stage cost (the same floats as solving it again)."""
    s = sensed(system)
    if s is None:
        return None
    try:
        if solve is None:
            dp = dp_riccati(s)
        else:
            own = solve(system)
            dp = replace(own, average_stage_cost=float(np.sum(own.cost_to_go * s.noise_cov)))
    except NumericalError as err:
        if str(err).startswith(NO_SOLUTION):
            return None
        raise
    loop = estimated_loop(s, dp.gain, "tcp", "dp", dp=dp)        # the DP solved once (it was solved twice a case)
    if not loop.stable or not loop.average_stage_cost > 0:
        return None
    return loop.average_stage_cost, loop.control_part, loop.estimation_part, s, dp, loop.spectral_radius


def _exact_margin(found: tuple[float, float, float, System, Any, float]) -> float:
    cost, control, estimation = found[:3]
    resolved(cost, "the loop's average stage cost")
    return SPLIT_RTOL - abs(cost - control - estimation) / cost


def simulated_z(system: System, seed: int,
                found: tuple[float, float, float, System, Any, float] | None = None) -> float | None:
    """(sampled cost - tr(P Sigma_W) - tr(K'HK mean P_k)) / stderr for the time-varying filter on ``sensed(system)``;
    None where the claim does not apply, where the sample has no error bar (its ``stderr_reason``), or where the
    loop mixes too slowly for MAX_STEPS (the window is the
    steps whose second half starts where radius^(steps/2) start <= MIXED: the start's transient is gone, relative to
    the stationary cost; ``start = max(1, (1 - radius) x0'P x0 / cost)``, x0's cost over the transient spread over
    its length, so a larger x0 needs a longer window and the test means the same at every scale of x0). ``found``:
    the case's exact split when the caller has it (not solved again). O(RUNS steps n^3)."""
    found = _split(system) if found is None else found
    if found is None:
        return None
    s, dp = found[3], found[4]
    start = max(1.0, (1.0 - found[5]) * float(s.x0 @ dp.cost_to_go @ s.x0) / found[0])
    if not np.isfinite(start):
        return None
    steps = 2 * int(np.ceil(np.log(MIXED / start) / np.log(found[5]))) if found[5] > 0 else 2
    if steps > MAX_STEPS:
        return None
    run = simulate_estimated(s, dp.gain, "tcp", "kalman", samples=RUNS, steps=max(steps, 2), seed=seed)
    if run.stderr_reason:        # the law's fourth moments grow: the sample has no error bar to measure a z with
        return None
    mu, P, K, B, psi = s.mu, dp.cost_to_go, dp.gain, s.B, s.input_weights[0]
    H = dp_input_hessian(B, P, mu, psi)
    split = float(np.sum(P * s.noise_cov) + np.sum((K.T @ H @ K) * run.mean_filtered_covariance))
    with np.errstate(over="ignore", under="ignore"):
        variance = run.stderr ** 2 * RUNS         # of one run's mean cost, from the squares of its deviations
    if not RESOLVED_MIN <= variance < np.inf:
        raise NumericalError(f"the simulated costs (about {run.mean_stage_cost:.3g}) have a variance of {variance:.3g} "
                             f"across runs, outside [{RESOLVED_MIN:.1e}, inf): its squares under- or overflowed, so "
                             "no z")
    return (run.mean_stage_cost - split) / run.stderr


def cost_split_sensor(ctx: Context) -> ClaimResult:
    """The check: on every case, margin = 1e-9 - |cost - (control + estimation)| / cost on the exact loop; on the
    paper's systems also 1 - |z| / 4 for the simulated time-varying filter (the smaller counts).

    Examples
    --------
    >>> s = System(A=[[1.2]], B=[[1.0]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.8], x0=[1])
    >>> cost_split_sensor(Context(paper={}, random=[s], seed=0)).verdict
    'holds'
    """
    tally = Tally()
    paper = {id(s): name for name, s in ctx.paper.items()}
    zs: dict[str, float | None] = {}

    def margin(s: System) -> float | None:
        found = _split(s, ctx.dp)    # once a case: the exact margin and the simulation share it
        if found is None:
            return None
        exact = _exact_margin(found)
        if id(s) not in paper:
            return exact
        z = simulated_z(s, ctx.seed, found)
        zs[paper[id(s)]] = z
        return exact if z is None else min(exact, 1.0 - abs(z) / Z_MAX)

    for s in ctx.cases:
        tally.run(margin, s, ctx.label(s))
    shown = "; ".join(f"{name}: z = {z:.2f}" if z is not None else f"{name}: not simulated (not stable, or more than "
                      f"{MAX_STEPS} steps to mix)" for name, z in zs.items())
    note = ("Each stationary case measures its first state over one link (gamma = 0.9, R = 0.01; Sigma_W = 0.01 I "
            "where the case has none); a case without a stabilising DP law or whose loop on the estimate is not "
            "mean-square stable does not apply. Exact: the loop (xhat, e) with stationary filter gains, margin = "
            "1e-9 - |cost - tr(P Sigma_W) - E[(u + K x)'H(u + K x)]| / cost. Simulated on the paper's systems ("
            f"{RUNS} runs, the time-varying filter, 2 k steps with radius^k max(1, (1 - radius) x0'P x0 / cost) <= "
            f"{MIXED:g}, the second half averaged): z of the sampled cost against tr(P Sigma_W) + tr(K'HK mean "
            "P_k), margin 1 - |z| / 4"
            + (f" ({shown})" if shown else "") + ".")
    return tally.result("cost-split-sensor", STATEMENT, note)
