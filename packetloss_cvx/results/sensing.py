"""Results of the lossy-sensor analyses (packetloss_cvx.sensing): covariance bounds, the critical arrival
rate, a law run for ever on an estimated state, and its Monte Carlo."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..display import fields_html, fields_repr, to_json
from .base import Frozen, finite_or_none

__all__ = ["CovarianceBounds", "CriticalGamma", "EstimatedLoop", "EstimatedRun", "FilterStability", "SampledCovariance"]


@dataclass(frozen=True)
class CovarianceBounds(Frozen):
    """Stationary bounds on ``lim E[P^-_k]`` (TCP-like filter, sensing.bounds): ``lower <= E[P^-] <= upper``
    (None: unbounded (lower) or no bound found (upper)); ``trace_lower``, ``trace_upper`` (inf when None)."""

    lower: np.ndarray | None
    upper: np.ndarray | None

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    @property
    def trace_lower(self) -> float:
        return float("inf") if self.lower is None else float(np.trace(self.lower))

    @property
    def trace_upper(self) -> float:
        return float("inf") if self.upper is None else float(np.trace(self.upper))

    def to_dict(self) -> dict[str, Any]:
        """The traces (null when infinite). O(n)."""
        return {"lower": finite_or_none(self.trace_lower), "upper": finite_or_none(self.trace_upper)}


@dataclass(frozen=True)
class CriticalGamma(Frozen):
    """The critical arrival rate along ``gamma = t d`` (sensing.bounds.critical_gamma): ``lower <= t_c <= upper``
    (upper inf: no certificate up to ``1 / max d``); ``exact`` when a theorem makes them equal (``reason``)."""

    direction: np.ndarray
    lower: float
    upper: float
    exact: bool
    reason: str

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (null for inf). O(g)."""
        return {"direction": self.direction.tolist(), "lower": finite_or_none(self.lower),
                "upper": finite_or_none(self.upper), "exact": self.exact, "reason": self.reason}


@dataclass(frozen=True)
class EstimatedLoop(Frozen):
    """A law ``u = -K xhat`` run for ever on the estimate of a stationary-gain filter (sensing.loop).

    ``protocol`` "tcp" (acks: the prediction uses V u) or "udp" (M u); ``spectral_radius`` of the second-moment
    operator of ``z = (xhat, e)``; ``stable`` when below 1 by the margin (None, no verdict, where the radius is
    not computed: nan with the ``reason``); ``average_stage_cost`` =
    lim E[x'Omega x + (V u)'Psi(V u)] (inf when not stable, or None-like with ``reason`` when not computed);
    ``control_part`` = tr(P Sigma_W) (P the DP's cost-to-go) and ``estimation_part`` = E[(u + K_dp x)' H
    (u + K_dp x)], whose sum is the cost (sensing.loop docstring); ``second_moment`` E[z z'] (2n×2n)."""

    law: str
    protocol: str
    gain: np.ndarray
    spectral_radius: float
    stable: bool | None
    average_stage_cost: float
    control_part: float
    estimation_part: float
    second_moment: np.ndarray | None
    reason: str = ""

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (null for inf or nan). O(n^2)."""
        return {"law": self.law, "protocol": self.protocol, "gain": self.gain.tolist(),
                "spectral_radius": finite_or_none(self.spectral_radius), "stable": self.stable,
                "average_stage_cost": finite_or_none(self.average_stage_cost),
                "control_part": finite_or_none(self.control_part),
                "estimation_part": finite_or_none(self.estimation_part), "reason": self.reason}


@dataclass(frozen=True)
class EstimatedRun(Frozen):
    """Monte Carlo of a law on an estimated state (sensing.montecarlo): ``filter`` "kalman" (time-varying,
    intermittent observations) or "stationary" (the fixed gains of sensing.loop); ``mean_stage_cost`` over the
    second half of ``steps`` and ``samples`` runs, ``stderr`` from the runs' means; ``exact_stage_cost`` (nan
    with ``reason`` when there is none); ``mean_filtered_covariance`` the mean of the filter's own P_k over the
    kept steps (Kalman; nan otherwise), ``mean_filtered_covariance_stderr`` its standard error per entry and
    ``mean_filtered_trace_stderr`` that of its trace (from the runs' own means over the kept steps: the runs are
    independent, the steps of one run are not); ``stderr_reason`` why the sample has no error bar (``stderr`` then
    nan), "" when it has one. The sample averages steps ``averaged_steps`` (the second half, step 0 the first from
    x0); ``exact_window_cost`` is the exact expectation of that same average (the stationary filter; nan otherwise),
    ``z`` the sample's distance from it in standard errors (nan without an error bar or that value), and
    ``exact_stage_cost`` the stationary loop's (the law run for ever: another window, which the sample need not
    approach)."""

    law: str
    protocol: str
    filter: str
    mean_stage_cost: float
    stderr: float
    exact_stage_cost: float
    stable: bool | None
    mean_filtered_covariance: np.ndarray
    samples: int
    steps: int
    reason: str = ""
    mean_filtered_covariance_stderr: np.ndarray | None = None
    mean_filtered_trace_stderr: float = float("nan")
    stderr_reason: str = ""
    exact_window_cost: float = float("nan")
    z: float = float("nan")

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    def to_dict(self) -> dict[str, Any]:
        """Plain floats (null for inf or nan; ``stderr_reason`` when the sample has no error bar). O(1)."""
        return {"law": self.law, "protocol": self.protocol, "filter": self.filter,
                "mean_stage_cost": finite_or_none(self.mean_stage_cost), "stderr": finite_or_none(self.stderr),
                "exact_stage_cost": finite_or_none(self.exact_stage_cost), "stable": self.stable,
                "mean_filtered_trace": finite_or_none(float(np.trace(self.mean_filtered_covariance))),
                "mean_filtered_trace_stderr": finite_or_none(self.mean_filtered_trace_stderr),
                "samples": self.samples,
                "steps": self.steps, "reason": self.reason,
                **({"stderr_reason": self.stderr_reason} if self.stderr_reason else {}),
                "averaged_steps": list(self.averaged_steps),
                "exact_window_cost": finite_or_none(self.exact_window_cost),
                "z": finite_or_none(self.z), "exact_stage_cost_window": "stationary"}

    @property
    def averaged_steps(self) -> tuple[int, int]:
        """The first and last step the sample averages (the second half; step 0 is the first, from x0). O(1)."""
        return self.steps - self.steps // 2, self.steps - 1


@dataclass(frozen=True)
class SampledCovariance(Frozen):
    """Monte Carlo of the TCP-like filter's expected error covariances (sensing.montecarlo.sampled_covariance):
    ``predicted[k]`` the mean of ``P^-_k`` (k = 0..steps), ``filtered[k]`` of ``P_k`` (k = 0..steps-1), each with
    its per-entry standard error over ``samples`` independent arrival paths."""

    predicted: np.ndarray
    predicted_stderr: np.ndarray
    filtered: np.ndarray
    filtered_stderr: np.ndarray
    samples: int

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    def to_dict(self) -> dict[str, Any]:
        """The traces per step and their standard errors (the trace's own: the paths' traces). O(steps n)."""
        return {"predicted_trace": np.trace(self.predicted, axis1=1, axis2=2).tolist(),
                "filtered_trace": np.trace(self.filtered, axis1=1, axis2=2).tolist(), "samples": self.samples}


@dataclass(frozen=True)
class FilterStability(Frozen):
    """Whether the TCP-like filter's expected error covariance stays bounded behind Markov (Gilbert–Elliott)
    sensor links (sensing.markov_bounds.filter_stability): ``bounded`` True (proved: ``by`` says how), False
    (proved unbounded), None (undecided, ``reason``); ``loss_radius`` = rho(Lambda) rho(A)^2 (Lambda the chain's
    all-lost matrix on the states it can visit from its initial distribution; < 1 is necessary, and sufficient
    when every channel alone observes the state: ``exact``)."""

    bounded: bool | None
    loss_radius: float
    exact: bool
    by: str
    reason: str

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    def to_dict(self) -> dict[str, Any]:
        """Plain floats (null for inf or nan). O(1)."""
        return {"bounded": self.bounded, "loss_radius": finite_or_none(self.loss_radius), "exact": self.exact,
                "by": self.by, "reason": self.reason}
