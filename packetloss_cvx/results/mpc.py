"""The constrained receding-horizon loop sampled (montecarlo/mpc.py): each constraint's violation frequency with its
confidence intervals, the infeasibility frequency and what the controller did then, and the realised cost, per
controller and protocol."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .base import Frozen, finite_or_none

__all__ = ["ControllerRun", "Frequency", "MPCSimulation", "json_table"]


def json_table(value: Any) -> Any:
    """A ``[constraints]`` table (`Constraints.to_dict`) for JSON: every non-finite number (an infinite bound, which
    leaves the bound out) as None, lists and tables kept in shape. O(size).

    Examples
    --------
    >>> json_table({"u_max": [1.0, float("inf")], "du_max": [0.3], "soft": True})
    {'u_max': [1.0, None], 'du_max': [0.3], 'soft': True}
    """
    if isinstance(value, dict):
        return {key: json_table(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_table(item) for item in value]
    if isinstance(value, float | np.floating):
        return finite_or_none(value)
    return value


@dataclass(frozen=True)
class Frequency(Frozen):
    """How often an event (a constraint violated, the QP infeasible) happened over ``runs`` sampled runs of
    ``steps`` steps.

    Attributes
    ----------
    name : str
        The constraint ("x_max[0]", "chance[1]", "du_max[0]", ...) or "infeasible".
    allowed : float
        The frequency the controller's design allows: a chance row's eps, 0 for a hard limit.
    step_counts : ndarray (steps,)
        Runs with the event at each step.
    runs : int
        Sampled runs (independent).
    count : int
        Run-steps with the event; ``frequency = count / (runs steps)``, pooled over the steps (steps of one run are
        dependent: no interval is given for the pooled number).
    worst_step : int
        The step with the most events; ``worst_frequency`` its frequency over the runs, ``worst_ci`` its Wilson
        interval (independent runs). For a chance row P(a'x_k > b) <= eps at each k, compare eps with this (a
        maximum over the steps: it leans high).
    runs_with : int
        Runs with the event at some step; ``runs_ci`` the Wilson interval of ``runs_with / runs``.
    confidence : float
        The intervals' level.
    """

    name: str
    allowed: float
    step_counts: np.ndarray
    runs: int
    count: int
    frequency: float
    worst_step: int
    worst_frequency: float
    worst_ci: tuple[float, float]
    runs_with: int
    runs_ci: tuple[float, float]
    confidence: float

    def to_dict(self) -> dict[str, Any]:
        """Plain numbers and lists. O(steps)."""
        return {"name": self.name, "allowed": self.allowed, "count": self.count, "frequency": self.frequency,
                "worst_step": self.worst_step, "worst_frequency": self.worst_frequency,
                "worst_ci": list(self.worst_ci), "runs_with": self.runs_with,
                "runs_fraction": self.runs_with / self.runs, "runs_ci": list(self.runs_ci),
                "confidence": self.confidence, "step_counts": self.step_counts.tolist()}


@dataclass(frozen=True)
class ControllerRun(Frozen):
    """One controller in the sampled loop.

    Attributes
    ----------
    controller : {"clipped", "certainty-equivalent", "expected-cost"}
    protocol : {"tcp", "udp"}
        Whose information and cost it plans with ("certainty-equivalent": mu = 1, the same for both).
    mean_stage_cost, stderr : float
        The mean over runs of each run's mean stage cost ``x_t' Omega x_t + a_t' Psi a_t`` (a_t the applied input),
        t < steps, and its standard error.
    stage_cost_mean : ndarray (steps,)
    violations : tuple of Frequency
        One per constraint row (input and rate bounds on the commanded inputs, state limits and chance rows on the
        realised states x_1..x_steps).
    infeasible : Frequency or None
        Steps whose hard program was proven infeasible (None for the clipped law, which solves nothing).
    fallback_steps : int
        Steps that applied the soft program's first input (the action on infeasibility).
    failed_steps : int
        Steps where no program gave a trusted answer and the rest of the last plan was played (zero past its end).
    slack_steps : int
        Steps whose applied plan used slack on a soft row (the fallback's, or a soft program's own).
    action : str
        What the controller does when its program is infeasible.
    states : ndarray (keep, steps + 1, n) or None
        The realised states x_0..x_steps of the first ``keep`` runs (`simulate_mpc`'s ``keep``), None when none
        were kept.
    inputs : ndarray (keep, steps, m) or None
        The inputs those runs commanded (under zero, what the actuator applied is ``inputs *
        MPCSimulation.delivered``).
    diverged_runs : int
        Runs whose stage cost or state left the double range (the loop diverged: a result, as in `simulate`); with
        any, ``mean_stage_cost`` is inf (null in JSON).
    applied : ndarray (keep, steps, m) or None
        Under hold or buffer (`MPCSimulation.actuator`): the inputs the actuator applied in the kept runs (None
        under zero, or when none were kept).
    """

    controller: str
    protocol: str
    mean_stage_cost: float
    stderr: float
    stage_cost_mean: np.ndarray
    violations: tuple[Frequency, ...]
    infeasible: Frequency | None
    fallback_steps: int
    failed_steps: int
    slack_steps: int
    action: str
    states: np.ndarray | None = None
    inputs: np.ndarray | None = None
    diverged_runs: int = 0
    applied: np.ndarray | None = None

    def violation(self, name: str) -> Frequency:
        """The `Frequency` of the constraint row ``name``."""
        return next(v for v in self.violations if v.name == name)

    def to_dict(self) -> dict[str, Any]:
        """Plain numbers and lists; ``"basis": "loop"`` (the costs of a law run in closed loop). O(rows steps)."""
        return {"controller": self.controller, "protocol": self.protocol, "basis": "loop",
                "mean_stage_cost": finite_or_none(self.mean_stage_cost), "stderr": finite_or_none(self.stderr),
                "stage_cost_mean": [finite_or_none(v) for v in self.stage_cost_mean],
                "violations": {v.name: v.to_dict() for v in self.violations},
                "infeasible": None if self.infeasible is None else self.infeasible.to_dict(),
                "fallback_steps": self.fallback_steps, "failed_steps": self.failed_steps,
                "slack_steps": self.slack_steps, "diverged_runs": self.diverged_runs, "action": self.action}


@dataclass(frozen=True)
class MPCSimulation(Frozen):
    """The constrained loop sampled: every controller on the same sample paths (deliveries, chain states, noise).

    ``runs[protocol][controller]`` is a `ControllerRun`; ``channel`` "bernoulli", "gilbert-elliott" or "markov";
    ``constraints`` the ``[constraints]`` table run; ``delivered`` (keep, steps, m) the kept runs' deliveries
    (True: the packet arrived), the same for every controller, or None when no trajectory was kept; ``actuator``
    what the actuator did on a loss ("zero", "hold", "buffer:L", "buffer:L:hold").
    """

    samples: int
    steps: int
    seed: int
    channel: str
    constraints: dict
    runs: dict
    delivered: np.ndarray | None = None
    actuator: str = "zero"

    def to_dict(self) -> dict[str, Any]:
        """``{"samples", "steps", "seed", "channel", "constraints", "actuator", "tcp": {controller: ...}, "udp":
        {...}}``;
        ``constraints`` is the table with every infinite entry (a bound left out) as None (JSON null: strict JSON
        has no inf), each row keeping its place."""
        out: dict[str, Any] = {"samples": self.samples, "steps": self.steps, "seed": self.seed,
                               "channel": self.channel, "constraints": json_table(self.constraints),
                               "actuator": self.actuator}
        for protocol, controllers in self.runs.items():
            out[protocol] = {name: run.to_dict() for name, run in controllers.items()}
        return out

    def plot(self, protocol: str | None = None, **kwargs: Any) -> Any:
        """The kept trajectories (each controller's realised states and commanded inputs, the lost packets
        marked) and every state-side constraint's violation frequency with its confidence interval, drawn by
        [`plot_mpc`][packetloss_cvx.plots.figures.plot_mpc] for ``protocol`` (default: the first run; keywords
        passed on); returns the matplotlib Figure.

        Raises
        ------
        InputError
            Field ``protocol``: not one that was run.
        """
        from ..plots import plot_mpc  # lazy: matplotlib, only when asked to draw
        return plot_mpc(self, protocol=protocol, **kwargs)
