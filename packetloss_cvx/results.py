"""Every result type the package returns: frozen dataclasses with read-only arrays and
``to_dict()`` for JSON (plain lists and floats)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "Allocation", "ClaimResult", "ClosedLoop", "ClosedLoopRun", "CrossCheck", "Maximiser", "MinCost", "OpenLoopCheck",
    "Riccati", "Simulation", "Solution", "Sweep", "eigenvalue_pairs",
]


def _read_only(value: Any) -> np.ndarray:
    arr = np.array(value)
    arr.setflags(write=False)
    return arr


def _freeze(obj: Any) -> None:
    """Make every ndarray field of a frozen dataclass a read-only copy."""
    for name, value in vars(obj).items():
        if isinstance(value, np.ndarray):
            object.__setattr__(obj, name, _read_only(value))


def eigenvalue_pairs(eigs: np.ndarray) -> list[list[float]]:
    """Complex eigenvalues as ``[[re, im], ...]`` sorted by descending modulus, then real part."""
    order = sorted(range(len(eigs)), key=lambda i: (-abs(eigs[i]), -eigs[i].real, -eigs[i].imag))
    return [[float(eigs[i].real), float(eigs[i].imag)] for i in order]


@dataclass(frozen=True)
class CrossCheck:
    """Agreement of a solver answer with the closed form.

    ``max_input_diff`` is max |Vbar (U_qp - U*)|, the largest difference of the mean applied
    inputs (an input sent over a channel that never delivers does not enter the cost, so any
    value is optimal; one that rarely delivers is weakly determined); ``cost_rel_diff`` is
    |J_qp - J*| / |J*|. Both are relative to the problem's own scale: the QP binds at
    ``max_input_diff <= 1e-6 max|Vbar U*|`` and ``cost_rel_diff <= 1e-7`` (tolerances.py).
    """

    reference_method: str
    max_input_diff: float
    cost_rel_diff: float

    def to_dict(self) -> dict[str, Any]:
        return {"max_input_diff": self.max_input_diff, "cost_rel_diff": self.cost_rel_diff}


@dataclass(frozen=True)
class Solution:
    """The optimal open-loop plan for one protocol.

    Attributes
    ----------
    protocol : {"tcp", "udp"}
    cost : float
        Optimal expected cost J*, constant and noise terms included.
    inputs : ndarray, shape (N, m)
        Commanded inputs U* (row t is U_{k+t}).
    gain : ndarray, shape (m, n), or None
        Receding-horizon gain K: U_k = -K X_k (None when a QP was solved without it).
    closed_loop_eigenvalues : ndarray, complex, shape (n,)
        Eigenvalues of A - B K (the paper's Tables I–II convention).
    method : str
        "dense", "recursion", "qp-condensed" or "qp-sparse".
    status, solve_time : solver status and seconds (QPs only).
    cross_check : CrossCheck or None
        For QPs, the comparison with the closed form.
    """

    protocol: str
    cost: float
    inputs: np.ndarray
    gain: np.ndarray | None
    closed_loop_eigenvalues: np.ndarray | None
    method: str
    status: str | None = None
    solve_time: float | None = None
    cross_check: CrossCheck | None = None

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "cost": self.cost,
            "inputs": self.inputs.tolist(),
            "gain": None if self.gain is None else self.gain.tolist(),
            "closed_loop_eigenvalues": (
                None if self.closed_loop_eigenvalues is None
                else eigenvalue_pairs(self.closed_loop_eigenvalues)
            ),
            "method": self.method,
        }
        if self.status is not None:
            out["status"] = self.status
            out["solve_time"] = self.solve_time
        if self.cross_check is not None:
            out.update(self.cross_check.to_dict())
        return out


@dataclass(frozen=True)
class Allocation:
    """The cheapest channel qualities found, with a certificate.

    ``mu``: delivery probabilities; ``communication_cost``: beta'mu; ``cost``: J*(mu) by the
    closed form (<= alpha); ``lower_bound``: a proven lower bound on the optimal beta'mu;
    ``gap``: (communication_cost - lower_bound) / max(communication_cost, 1e-12);
    ``status``: "optimal" (the gap is certified) or "gap_not_certified" (a cap on boxes or time
    was hit; ``gap`` is the gap reached); ``method``: how it was solved; ``boxes``: boxes the
    UDP-like branch and bound explored (0 for the TCP-like SOCP). ``lower_bound`` is proved:
    tangent cuts of the convex J*_tcp with an exactly evaluated LP dual (TCP-like), the branch
    and bound's remaining boxes (UDP-like).
    """

    mu: np.ndarray
    communication_cost: float
    cost: float
    lower_bound: float
    gap: float
    status: str
    method: str
    protocol: str
    alpha: float
    beta: np.ndarray
    boxes: int = 0

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        return {"protocol": self.protocol, "alpha": self.alpha, "beta": self.beta.tolist(),
                "mu": self.mu.tolist(), "communication_cost": self.communication_cost, "cost": self.cost,
                "lower_bound": self.lower_bound, "gap": self.gap, "status": self.status, "method": self.method,
                "boxes": self.boxes}


@dataclass(frozen=True)
class ClaimResult:
    """The verdict on one claim, with the numbers behind it.

    Attributes
    ----------
    id, statement : str
        The claim's id and what the paper states.
    verdict : {"holds", "fails", "not-reproduced", "inconclusive"}
        "holds": ``checked > 0`` cases, none violated, none errored. "fails": some case violated the
        claim (a proven violation fails the claim whatever else errored). "not-reproduced": the
        paper's printed numbers could not be recovered. "inconclusive": no violation, but a case
        errored or none was checked: nothing proved the claim.
    checked : int
        Cases whose check ran to a margin (errored and not-applicable cases excluded).
    violations : int
        Checked cases that violate the claim.
    worst : float or None
        The least margin over the checked cases (< 0 where a case violates).
    counterexample : dict or None
        A (shrunk) violating System in the TOML schema's structure.
    note : str
        How the margin is defined, what was found, and which cases errored.
    errors : int
        Cases whose check raised (a numerical or solver failure, or bad input).
    outcomes : str
        One character per case, in the audit's case order: ``+`` holds, ``-`` violated,
        ``.`` not applicable, ``E`` errored; empty for claims not checked case by case.
    """

    id: str
    statement: str
    verdict: str
    checked: int
    violations: int
    worst: float | None
    counterexample: dict | None
    note: str
    errors: int = 0
    outcomes: str = ""

    def __post_init__(self) -> None:
        if self.verdict not in ("holds", "fails", "not-reproduced", "inconclusive"):
            raise ValueError(f"verdict: expected holds, fails, not-reproduced or inconclusive, found {self.verdict!r}")
        if self.verdict == "holds" and (self.checked <= 0 or self.errors or self.violations):
            raise ValueError(f"verdict: 'holds' needs checked > 0 with no violation and no error, found "
                             f"checked={self.checked}, violations={self.violations}, errors={self.errors}")
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id, "statement": self.statement, "verdict": self.verdict, "checked": self.checked,
            "violations": self.violations, "errors": self.errors,
            "worst": self.worst if self.worst is None or np.isfinite(self.worst) else None,   # JSON has no inf
            "counterexample": self.counterexample, "note": self.note, "outcomes": self.outcomes,
        }


@dataclass(frozen=True)
class Maximiser:
    """Where J_Delta peaks: ``nu`` (or ``mu`` for per-channel), the value, and how found."""

    point: np.ndarray
    value: float
    method: str

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        return {"point": self.point.tolist(), "value": self.value, "method": self.method}


@dataclass(frozen=True)
class Sweep:
    """Optimal costs over a grid of delivery probabilities (:mod:`packetloss_cvx.studies.sweeps`).

    ``axes``: one array per swept dimension; ``costs``: protocol -> array over the grid;
    ``difference``: J*_udp - J*_tcp over the grid (None unless both protocols were swept);
    ``difference_method``: how the difference was computed.
    """

    axes: tuple[np.ndarray, ...]
    costs: dict[str, np.ndarray]
    difference: np.ndarray | None
    difference_method: str | None

    def __post_init__(self) -> None:
        _freeze(self)
        object.__setattr__(self, "axes", tuple(_read_only(a) for a in self.axes))
        object.__setattr__(self, "costs", {k: _read_only(v) for k, v in self.costs.items()})

    def to_dict(self) -> dict[str, Any]:
        return {"axes": [a.tolist() for a in self.axes], "costs": {k: v.tolist() for k, v in self.costs.items()},
                "difference": None if self.difference is None else self.difference.tolist(),
                "difference_method": self.difference_method}


@dataclass(frozen=True)
class MinCost:
    """The least optimal cost J*(mu) reachable within bounds and constraints.

    ``cost``: J*(mu) at ``mu`` (reachable, by the closed form); ``lower_bound``: proven, no
    admissible mu does better; ``gap``: (cost - lower_bound) / cost; ``status``: "optimal"
    (gap <= ``tolerances.MIN_COST_RTOL``) or "gap_not_certified"; ``method``: how found.
    Construction O(m).
    """

    protocol: str
    cost: float
    lower_bound: float
    gap: float
    status: str
    mu: np.ndarray
    method: str

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        """Plain floats and lists for JSON. O(m)."""
        return {"protocol": self.protocol, "cost": self.cost, "lower_bound": self.lower_bound, "gap": self.gap,
                "status": self.status, "mu": self.mu.tolist(), "method": self.method}



def _finite_or_none(value: float | None) -> float | None:
    return float(value) if value is not None and np.isfinite(value) else None


@dataclass(frozen=True)
class ClosedLoop:
    """A stationary law ``u = -K x`` (``law``: its label) run for ever over the channel ``mu`` (simulation.moments).

    ``spectral_radius`` of the second-moment operator (mean-square stable iff < 1); ``stable`` only when
    it is below 1 by ``tolerances.MEAN_SQUARE_MARGIN``; ``average_stage_cost`` = lim E[x'Omega x + (Vu)'Psi(Vu)]
    = tr(P_K Sigma_W), ``inf`` when not stable; ``cost_to_go`` P_K (x0'P_K x0: total cost from x0 without
    noise) and ``second_moment`` (stationary E[xx']), None when not stable; ``reason`` why the cost is inf.
    """

    law: str
    gain: np.ndarray
    mu: np.ndarray
    spectral_radius: float
    stable: bool
    average_stage_cost: float
    cost_to_go: np.ndarray | None
    second_moment: np.ndarray | None
    reason: str = ""

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats; an infinite cost is None (JSON has no inf). O(n^2)."""
        return {"law": self.law, "gain": self.gain.tolist(), "mu": self.mu.tolist(),
                "mean_square_spectral_radius": self.spectral_radius, "stable": self.stable,
                "average_stage_cost": _finite_or_none(self.average_stage_cost),
                "cost_to_go": None if self.cost_to_go is None else self.cost_to_go.tolist(), "reason": self.reason}


@dataclass(frozen=True)
class Riccati:
    """The DP optimum (simulation.riccati): ``cost_to_go`` P solves the modified Riccati equation, ``gain``
    K its law u = -K x, ``average_stage_cost`` = tr(P Sigma_W), ``spectral_radius`` of the law's
    second-moment operator, ``iterations`` (value and policy), ``residual`` ||R(P) - P|| / ||P||."""

    gain: np.ndarray
    cost_to_go: np.ndarray
    average_stage_cost: float
    spectral_radius: float
    iterations: int
    residual: float

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats. O(n^2)."""
        return {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in vars(self).items()}


@dataclass(frozen=True)
class OpenLoopCheck:
    """A protocol's plan U* applied open loop and sampled (simulation.montecarlo): ``formula`` J* (Theorem 1),
    ``exact`` E[realised cost] under the stated model (J_udp(U*)), ``mean`` and ``stderr`` of the samples,
    ``z = (mean - exact) / stderr``."""

    formula: float
    exact: float
    mean: float
    stderr: float
    z: float

    def to_dict(self) -> dict[str, Any]:
        """The issue's schema; a non-finite number is None (JSON). O(1)."""
        return {k: _finite_or_none(getattr(self, k)) for k in ("formula", "exact", "mean", "stderr", "z")}


@dataclass(frozen=True)
class ClosedLoopRun:
    """A law run in closed loop for ``steps`` steps over sampled losses (simulation.montecarlo): ``mean_stage_cost``
    and ``stderr`` of each run's mean stage cost over t < steps, ``exact_stage_cost`` its expectation,
    ``spectral_radius`` and ``stable`` as in ClosedLoop, ``reason`` why there is no law ("" if there is); per
    step: ``state_norm_mean``, ``state_norm_std`` of ||x_t|| (t <= steps) and ``stage_cost_mean``."""

    law: str
    mean_stage_cost: float
    stderr: float
    exact_stage_cost: float
    spectral_radius: float
    stable: bool
    state_norm_mean: np.ndarray
    state_norm_std: np.ndarray
    stage_cost_mean: np.ndarray
    reason: str = ""

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        """The issue's schema (plus ``reason`` when there is no law); non-finite numbers are None. O(1)."""
        out: dict[str, Any] = {"mean_stage_cost": _finite_or_none(self.mean_stage_cost),
                               "stderr": _finite_or_none(self.stderr),
                               "exact_stage_cost": _finite_or_none(self.exact_stage_cost),
                               "mean_square_spectral_radius": _finite_or_none(self.spectral_radius),
                               "stable": self.stable}
        return {**out, "reason": self.reason} if self.reason else out


@dataclass(frozen=True)
class Simulation:
    """Monte Carlo checks (simulation.montecarlo): ``open_loop`` protocol -> OpenLoopCheck, ``closed_loop`` law ->
    ClosedLoopRun, ``trajectories`` (laws, runs, steps + 1, n) of the first runs or None."""

    samples: int
    steps: int
    seed: int
    open_loop: dict[str, OpenLoopCheck]
    closed_loop: dict[str, ClosedLoopRun]
    trajectories: np.ndarray | None = None

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        """``{law: {"open_loop": {...}, "closed_loop": {...}}}``, each part where it was run. O(laws)."""
        out: dict[str, Any] = {}
        for law, check in self.open_loop.items():
            out.setdefault(law, {})["open_loop"] = check.to_dict()
        for law, run in self.closed_loop.items():
            out.setdefault(law, {})["closed_loop"] = run.to_dict()
        return out
