"""expectation-mpc-feasibility: Trodden & Li's phenomenon ("When expectation fails: stochastic MPC of linear systems
with random input losses", arXiv 2606.13421, 2026) on a scalar plant of our own, in the package's constrained loop.

*The plant.* ``x' = a x + v u``, ``v ~ Bernoulli(mu)``, a = 1.2, mu = 0.3, no noise, Q = 1, R = 0.01, N = 1,
``|u| <= 3``, the expected state ``|E[x_k]| <= 1``, x0 = 1/2.

*Certified on the expectation.* The expected dynamics ``z' = a z + mu u`` keep the box: from any ``|z| <= x_max``
the input ``u = -sign(z) min(u_max, a |z| / mu)`` gives ``|a z + mu u| <= max(0, a x_max - mu u_max) <= x_max``
whenever ``mu u_max >= (a - 1) x_max`` (0.9 >= 0.2): the box is controlled invariant, so the program on the expected
dynamics, feasible at x0, stays feasible along the expected trajectory (the usual recursive-feasibility argument).

*Realised.* The TCP-like program (the expected dynamics and ``mu R u^2``) commands ``u = -a x / (mu + R)`` while its
bounds do not bind: a delivered packet gives ``x' = a x (1 - 1/(mu + R)) = -2.67 x``, a lost one ``x' = 1.2 x``, so
``|x|`` grows whatever the link does and the state leaves the box; from ``|x| > (x_max + mu u_max) / a = 1.583`` no
plan keeps the expected state inside: the program is infeasible. Certainty-equivalent MPC (mu = 1 in the model)
commands ``u = -a x / (1 + R)``: a delivery lands near zero, only a run of losses (1.2 per step) can leave the box,
and infeasibility needs ``|x| > (1 + 3) / 1.2``: more than ten losses in a row from 1/2.

The check runs `simulate_mpc` (RUNS runs of STEPS steps, seed 0) and compares the runs that stay feasible throughout:
margin = (the Wilson lower bound of certainty-equivalent MPC's share) - (the Wilson upper bound of expected-cost MPC's
share), positive where the phenomenon is reproduced; a case whose certificate fails does not apply.
"""

from __future__ import annotations

from ..model.constraints import Constraints
from ..model.system import System
from ..results import ClaimResult
from .context import Context
from .evaluate import Tally

__all__ = ["RUNS", "STATEMENT", "STEPS", "expectation_mpc", "feasibility_case"]

STATEMENT = ("(Not the paper's: Trodden & Li, arXiv 2606.13421.) Under Bernoulli input losses, MPC on the expected "
             "dynamics whose state limits are certified recursively feasible on the expectation loses feasibility in "
             "the realised loop, where certainty-equivalent MPC (mu = 1 in the model) keeps it with positive "
             "probability.")

#: sampled runs and steps of the loop: every run re-solves two programs per step (about 5 ms each)
RUNS, STEPS = 20, 8


def feasibility_case() -> tuple[System, Constraints]:
    """The scalar plant and its limits (module docstring). O(1).

    Examples
    --------
    >>> s, c = feasibility_case()
    >>> a, mu, u_max, x_max = s.A[0, 0], s.mu[0], c.u_max[0], c.x_max[0]
    >>> bool(mu * u_max >= (a - 1) * x_max), round(float((x_max + mu * u_max) / a), 3)   # certified; infeasible beyond
    (True, 1.583)
    """
    system = System(A=[[1.2]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[0.01], mu=[0.3], x0=[0.5],
                    name="expected-dynamics MPC example")
    return system, Constraints(u_min=[-3.0], u_max=[3.0], x_min=[-1.0], x_max=[1.0])


def expectation_mpc(ctx: Context) -> ClaimResult:
    """The check on `feasibility_case` (independent of the audit's random cases; RUNS x STEPS x 2 programs, about
    2 s; tests/claims/test_claims_expectation_mpc.py runs it)."""
    from ..montecarlo.mpc import simulate_mpc  # cvxpy: only when this claim runs

    system, constraints = feasibility_case()
    a, mu = float(system.A[0, 0]), float(system.mu[0])
    u_max, x_max = float(constraints.u_max[0]), float(constraints.x_max[0])
    found: dict[str, object] = {}

    def margin(case: tuple[System, Constraints]) -> float | None:
        if mu * u_max < (a - 1.0) * x_max:            # the box is not invariant under the expected dynamics
            return None
        sim = simulate_mpc(*case, RUNS, STEPS, seed=0, protocols=["tcp"],
                           controllers=["certainty-equivalent", "expected-cost"], progress=False)
        found["sim"] = sim
        runs = sim.runs["tcp"]
        kept = {name: (1.0 - runs[name].infeasible.runs_ci[1], 1.0 - runs[name].infeasible.runs_ci[0])
                for name in runs}                       # share of runs feasible throughout: [low, high]
        return kept["certainty-equivalent"][0] - kept["expected-cost"][1]

    tally = Tally()
    tally.run(margin, (system, constraints), system.name)
    note = ("Plant x' = 1.2 x + v u, mu = 0.3, Q = 1, R = 0.01, N = 1, |u| <= 3, |E[x_k]| <= 1, x0 = 0.5, no noise. "
            "Certificate on the expectation: mu u_max = 0.9 >= (a - 1) x_max = 0.2, so the box is controlled invariant "
            "for z' = a z + mu u and the program is recursively feasible along the expected trajectory. Realised: "
            "the TCP-like program commands u = -a x / (mu + R) inside its bounds, so x' = -2.67 x (delivered) or "
            "1.2 x (lost): |x| grows on every outcome and the program is infeasible once |x| > (1 + 0.9) / 1.2 = "
            "1.583; certainty-equivalent MPC (u = -a x / (1 + R)) lands near 0 on a delivery. Sampled "
            f"(simulate_mpc, {RUNS} runs of {STEPS} steps, seed 0, the same paths for both): ")
    sim = found.get("sim")
    if sim is not None:
        parts = []
        for name in ("expected-cost", "certainty-equivalent"):
            run = sim.runs["tcp"][name]
            f = run.infeasible
            box = max(run.violation("x_max[0]").runs_with, run.violation("x_min[0]").runs_with)
            parts.append(f"{name} MPC infeasible in {f.runs_with} of {f.runs} runs (Wilson 95 % "
                         f"[{f.runs_ci[0]:.3f}, {f.runs_ci[1]:.3f}]), at {100 * f.frequency:.3g} % of run-steps, "
                         f"realised |x| > 1 in at least {box} runs, mean stage cost {run.mean_stage_cost:.4g}")
        note += "; ".join(parts) + (". On infeasibility the controller applied the soft program's first input. "
                                    "Margin = the Wilson lower bound of the certainty-equivalent runs that stay "
                                    "feasible minus the upper bound of the expected-cost runs that do.")
    return tally.result("expectation-mpc-feasibility", STATEMENT, note)
