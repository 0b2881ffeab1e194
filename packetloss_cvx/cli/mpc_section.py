"""``simulate FILE`` with a ``[constraints]`` table: the constrained receding-horizon loop (montecarlo/mpc.py), the
clipped unconstrained law, certainty-equivalent and expected-cost MPC on the same sample paths."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..closedloop.actuator import Actuator
from ..errors import InputError
from ..model.constraints import Constraints
from ..model.system import System
from ..montecarlo.mpc import CONTROLLERS, INFEASIBLE_ACTION, check_loop_budgets, loop_jobs, simulate_mpc
from ..results.mpc import ControllerRun, Frequency, MPCSimulation
from ..studies.engine import dask_client

__all__ = ["LABELS", "constrained_loop_section"]

#: How each controller is named in the text.
LABELS = {"clipped": "unconstrained law clipped to the bounds", "certainty-equivalent": "certainty-equivalent MPC "
          "(mu = 1)", "expected-cost": "expected-cost MPC"}


def constrained_loop_section(system: System, constraints: Constraints, protocols: tuple[str, ...], samples: int,
                             steps: int, seed: int, progress: bool | None, threads: int = 1, dask: Any = None,
                             workers: int | None = None,
                             strategies: tuple[Actuator, ...] = ()) -> tuple[dict[str, Any], list[str]]:
    """The ``"constrained_loop"`` JSON entry (`MPCSimulation.to_dict`) and its text lines; the runs on ``threads``
    threads, or as tasks on the Dask cluster ``dask`` ("local" with ``workers`` processes, or an address).
    With ``strategies`` (``--actuator``) the loop runs once per strategy on the same paths, the entry then the
    first run's ``samples``, ``steps``, ``seed``, ``channel`` and ``constraints`` with ``"strategies": {name:
    MPCSimulation.to_dict()}``; every strategy's budget is checked, summed, before the first runs.

    Raises
    ------
    InputError
        Named after the flag (``--mpc-samples``, ``--steps``, ``--seed``, ``--threads``, ``--dask``, ``--workers``).
    """
    flags = {"samples": "--mpc-samples", "steps": "--steps", "seed": "--seed", "threads": "--threads",
             "dask": "--dask", "workers": "--workers", "mu_schedule": "--mu-schedule",
             "state_weights": "cost.state_weights", "input_weights": "cost.input_weights"}
    try:
        if strategies:
            check_loop_budgets(system, constraints, samples, steps,
                               [loop_jobs(protocols, CONTROLLERS, strategy) for strategy in strategies])
        if dask is None:
            sims = [simulate_mpc(system, constraints, samples, steps, seed, protocols=protocols, progress=progress,
                                 threads=threads, actuator=strategy) for strategy in strategies or ("zero",)]
        else:
            with dask_client(dask, workers) as client:
                sims = [simulate_mpc(system, constraints, samples, steps, seed, protocols=protocols,
                                     progress=progress, threads=threads, dask=client, actuator=strategy)
                        for strategy in strategies or ("zero",)]
    except InputError as err:
        raise err.renamed(flags.get(err.field, err.field)) from None
    if not strategies:
        return sims[0].to_dict(), _text(sims[0])
    first = sims[0].to_dict()
    data = {key: first[key] for key in ("samples", "steps", "seed", "channel", "constraints")}
    data["strategies"] = {sim.actuator: sim.to_dict() for sim in sims}
    lines = _header(sims[0], "every controller and actuator strategy")
    lines.append(f"    (on a loss the actuator: {'; '.join(_strategy_text(s) for s in strategies)}. Input and rate "
                 "rows: zero's on the commands, the others' on the inputs applied; the rate bound links a TCP-like "
                 "controller's plan to the input applied last (acknowledged), a UDP-like one's to its last command, "
                 "assumed delivered)")
    for sim in sims:
        lines += _protocol_lines(sim, f"actuator {sim.actuator}, ")
    return data, lines


def _strategy_text(strategy: Actuator) -> str:
    """What the actuator does on a loss, in words."""
    if strategy.kind == "zero":
        return "zero applies nothing"
    if strategy.kind == "hold":
        return "hold applies its last input"
    then = "its last input" if strategy.exhausted == "hold" else "zero"
    return f"{strategy} plays the next entry of the last plan received ({strategy.length} entries), then {then}"


def _percent(value: float) -> str:
    return f"{100 * value:.3g}%"


def _interval(ci: tuple[float, float]) -> str:
    return f"[{_percent(ci[0])}, {_percent(ci[1])}]"


def _violation(v: Frequency) -> str:
    allowed = f", allowed {_percent(v.allowed)} per step" if v.allowed else ""
    return (f"{v.name}: {_percent(v.frequency)} of run-steps; worst step {v.worst_step + 1}: "
            f"{_percent(v.worst_frequency)} {_interval(v.worst_ci)}; runs {_percent(v.runs_with / v.runs)} "
            f"{_interval(v.runs_ci)}{allowed}")


def _run_lines(run: ControllerRun) -> list[str]:
    spread = f" +- {run.stderr:.3g}" if np.isfinite(run.stderr) else ""
    if run.diverged_runs:
        runs = run.violations[0].runs if run.violations else None
        of = f" of {runs}" if runs else ""
        lines = [f"    {LABELS[run.controller]}: mean stage cost inf [basis: loop]: the loop diverged (the state left "
                 f"the double-precision range) in {run.diverged_runs}{of} runs"]
    else:
        lines = [f"    {LABELS[run.controller]}: mean stage cost {run.mean_stage_cost:.6g}{spread} [basis: loop]"]
    if run.infeasible is not None:
        f = run.infeasible
        lines.append(f"      infeasible at {_percent(f.frequency)} of run-steps (runs {_percent(f.runs_with / f.runs)} "
                     f"{_interval(f.runs_ci)}); soft fallback {run.fallback_steps} steps, no trusted answer "
                     f"{run.failed_steps} steps")
    violated = [v for v in run.violations if v.count]
    lines += [f"      violated {_violation(v)}" for v in violated]
    if not violated:
        lines.append("      no constraint violated")
    return lines


def _text(sim: MPCSimulation) -> list[str]:
    return _header(sim, "every controller") + _protocol_lines(sim)


def _header(sim: MPCSimulation, shared: str) -> list[str]:
    confidence = next((v.confidence for runs in sim.runs.values() for run in runs.values() for v in run.violations),
                      None)
    level = f"; intervals Wilson {_percent(confidence)}" if confidence else ""
    lines = [f"  constrained loop ([constraints]): {sim.samples} runs of {sim.steps} steps, seed {sim.seed}, "
             f"the same paths for {shared}{level}",
             f"    (on infeasibility: {INFEASIBLE_ACTION})"]
    if sim.channel != "bernoulli":
        lines.append("    (behind the chain every program is the plug-in one, planned with the predicted mu_t of the "
                     "controller's belief: filtered by the acknowledgements TCP-like, the prior propagated UDP-like)")
    return lines


def _protocol_lines(sim: MPCSimulation, prefix: str = "") -> list[str]:
    lines = []
    for protocol, runs in sim.runs.items():
        lines.append(f"  {prefix}{protocol.upper()}-like information")
        for run in runs.values():
            lines += _run_lines(run)
    return lines
