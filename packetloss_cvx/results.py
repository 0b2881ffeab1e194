"""Every result type the package returns: frozen dataclasses with read-only arrays and
``to_dict()`` for JSON (plain lists and floats)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "Allocation", "BurstinessSweep", "ClaimResult", "CrossCheck", "MarkovSolution", "Maximiser", "MinCost",
    "MjlsResult", "Solution", "Sweep", "eigenvalue_pairs",
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


@dataclass(frozen=True)
class MarkovSolution:
    """One protocol under a Gilbert–Elliott channel (:func:`packetloss_cvx.markov.markov_solution`).

    ``exact``: the minimiser of the protocol's exact expected cost (closed form); ``qp``: its
    cvxpy + Clarabel twin (cross-checked) or None; ``plugin_cost``: the protocol's exact cost of the
    plug-in plan (the paper's law with the chain's mu_t); ``relative_loss``: plugin_cost / exact.cost - 1;
    ``plan_expected_cost``: E[realised cost] of the plug-in plan under the chain (what sampling measures,
    the UDP-like form for both protocols). O(N m + n m) to build.
    """

    protocol: str
    exact: Solution
    qp: Solution | None
    plugin_cost: float
    relative_loss: float
    plan_expected_cost: float

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"exact": self.exact.to_dict(), "plugin_cost": self.plugin_cost,
                               "relative_loss": self.relative_loss, "plan_expected_cost": self.plan_expected_cost}
        if self.qp is not None:
            out["qp"] = {"status": self.qp.status, "cost": self.qp.cost, "solve_time": self.qp.solve_time,
                         **(self.qp.cross_check.to_dict() if self.qp.cross_check is not None else {})}
        return out


@dataclass(frozen=True)
class BurstinessSweep:
    """Costs over the burstiness lambda = 1 - p - r at fixed average delivery rates ``rate``
    (:func:`packetloss_cvx.markov.burstiness_sweep`). ``plugin``: protocol -> the protocol's exact cost
    of its plug-in plan; ``exact``: protocol -> the exact minimum; each an array over ``correlation``."""

    correlation: np.ndarray
    rate: np.ndarray
    plugin: dict[str, np.ndarray]
    exact: dict[str, np.ndarray]

    def __post_init__(self) -> None:
        _freeze(self)
        object.__setattr__(self, "plugin", {k: _read_only(v) for k, v in self.plugin.items()})
        object.__setattr__(self, "exact", {k: _read_only(v) for k, v in self.exact.items()})

    def to_dict(self) -> dict[str, Any]:
        return {"correlation": self.correlation.tolist(), "rate": self.rate.tolist(),
                "plugin": {k: v.tolist() for k, v in self.plugin.items()},
                "exact": {k: v.tolist() for k, v in self.exact.items()}}


@dataclass(frozen=True)
class MjlsResult:
    """Mode-dependent optimal control of a Markov jump linear system (:mod:`packetloss_cvx.markov.mjls`).

    ``gains[k]``: u = -gains[k] x in mode k; ``cost_matrices[k]``: the coupled Riccati solutions P_k;
    ``modes``: the delivery pattern of each mode (0/1 per actuator); ``transition``: the mode chain;
    ``spectral_radius``: of the closed loop's second-moment operator (< 1: mean-square stable);
    ``iterations``, ``residual``: of the coupled Riccati iteration.
    """

    gains: np.ndarray
    cost_matrices: np.ndarray
    modes: np.ndarray
    transition: np.ndarray
    spectral_radius: float
    iterations: int
    residual: float

    def __post_init__(self) -> None:
        _freeze(self)

    def to_dict(self) -> dict[str, Any]:
        return {"gains": self.gains.tolist(), "cost_matrices": self.cost_matrices.tolist(),
                "modes": self.modes.tolist(), "transition": self.transition.tolist(),
                "spectral_radius": self.spectral_radius, "mean_square_stable": bool(self.spectral_radius < 1),
                "iterations": self.iterations, "residual": self.residual}
