"""Solutions of one system: the closed forms' and QPs' plans, their cross-check, and batches of channels."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..display import batch_repr, fields_html, fields_repr, solution_html, solution_repr, to_json
from .base import Frozen, Tabular, eigenvalue_pairs, numbered, scalar_row

__all__ = ["BatchSolution", "CrossCheck", "LoopStability", "Solution"]


@dataclass(frozen=True)
class CrossCheck(Tabular):
    """Agreement of a solver answer with the closed form.

    ``max_input_diff`` is max |Vbar (U_qp - `U*`)|, the largest difference of the mean applied
    inputs (an input sent over a channel that never delivers does not enter the cost, so any
    value is optimal; one that rarely delivers is weakly determined); ``cost_rel_diff`` is
    |J_qp - `J*`| / |`J*`|. Both are relative to the problem's own scale: the QP binds at
    ``max_input_diff <= 1e-6 max|Vbar U*|`` and ``cost_rel_diff <= 1e-7`` (tolerances.py).
    """

    reference_method: str
    max_input_diff: float
    cost_rel_diff: float

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        return {"max_input_diff": self.max_input_diff, "cost_rel_diff": self.cost_rel_diff}


@dataclass(frozen=True)
class LoopStability(Tabular):
    """Mean-square stability of a plan's receding-horizon law u = -K x run for ever over the system's channel
    ([`loop_stability`][packetloss_cvx.closedloop.law_stability.loop_stability]).

    Attributes
    ----------
    radius : float or None
        Spectral radius of the second-moment map E[x x'] -> E[x' x'']; None when it was not computed.
    stable : bool
        True only when the radius is proved below 1 (``is_mean_square_stable``); False when it is not, or
        when the radius was not computed (then ``note`` says why: not a verdict).
    over : str
        The loop it speaks of: "mu = [...]", "the first step's mu = [...]" (a schedule) or the Markov chain.
    note : str or None
        Why it is not computed, or that the first step's mu stands for a non-stationary channel.
    """

    radius: float | None
    stable: bool
    over: str
    note: str | None = None

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    @property
    def computed(self) -> bool:
        return self.radius is not None

    @property
    def verdict(self) -> str:
        """One sentence: the loop, the verdict and the radius (or why there is none), and the note where there is one
        (a non-stationary channel: which loop the verdict is on)."""
        if self.radius is None:
            return f"stability not computed: {self.note}"
        if self.stable:
            verdict = "mean-square stable"
        elif self.radius >= 1:
            verdict = ("NOT mean-square stable: E[x x'] grows without bound when u = -K x runs in a loop over these "
                       "losses")
        else:
            verdict = "not proved mean-square stable (the radius is within 1e-9 of 1)"
        said = f"u = -K x over {self.over}: {verdict} (second-moment spectral radius {self.radius:.6g})"
        return said if self.note is None else f"{said}; {self.note}"

    def to_dict(self) -> dict[str, Any]:
        """The keys ``solve --json`` gives each protocol's block."""
        out: dict[str, Any] = {"mean_square_spectral_radius": self.radius, "stable": self.stable}
        if self.note is not None:
            out["stability_note"] = self.note
        return out


@dataclass(frozen=True)
class Solution(Frozen):
    """The optimal open-loop plan for one protocol.

    Attributes
    ----------
    protocol : {"tcp", "udp"}
    cost : float
        Optimal expected cost `J*`, constant and noise terms included.
    inputs : ndarray, shape (N, m)
        Commanded inputs `U*` (row t is U_{k+t}).
    gain : ndarray, shape (m, n), or None
        Receding-horizon gain K: U_k = -K X_k (None when a QP was solved without it).
    closed_loop_eigenvalues : ndarray, complex, shape (n,)
        Eigenvalues of A - B K (the paper's Tables I–II convention).
    method : str
        "dense", "recursion", "qp-condensed" or "qp-sparse".
    status, solve_time : solver status and seconds (QPs only).
    cross_check : CrossCheck or None
        For QPs, the comparison with the closed form.
    stability : LoopStability or None
        Mean-square stability of u = -K x over the channel, once
        [`with_stability`][packetloss_cvx.closedloop.law_stability.with_stability] attached it (a Solution alone does
        not know the channel).
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
    stability: LoopStability | None = None

    __repr__ = solution_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = solution_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "protocol": self.protocol,
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
        if self.stability is not None:
            out.update(self.stability.to_dict())
        return out

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per step t = 0..N-1: the commanded inputs u1..um; the cost, protocol and method as attrs."""
        data = self.to_dict()
        del data["inputs"]
        row, attrs = scalar_row(data)
        inputs = np.asarray(self.inputs, dtype=float)
        columns: dict[str, Any] = {"t": np.arange(inputs.shape[0])}
        columns.update(dict(zip(numbered("u", inputs.shape[1]), inputs.T, strict=True)))
        return columns, {**{k: v[0] for k, v in row.items()}, **attrs}



@dataclass(frozen=True)
class BatchSolution(Frozen):
    """Optimal plans for a batch of channels (``points`` of them) of one system
    ([`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator]).

    Construction O(points N m n) (read-only copies).

    Attributes
    ----------
    protocol : {"tcp", "udp"}
    costs : ndarray, shape (points,)
        Optimal expected costs `J*`, each checked against the forward cost of its own plan.
    inputs : ndarray, shape (points, N, m)
        Commanded inputs `U*` per point.
    gains : ndarray, shape (points, m, n)
        Receding-horizon gains K of the first step per point.
    method : str
        "dense", "recursion", or "mixed" (dense, with the recursion for points whose dense
        solve failed its checks).
    """

    protocol: str
    costs: np.ndarray
    inputs: np.ndarray
    gains: np.ndarray
    method: str

    __repr__ = batch_repr
    _repr_html_ = fields_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists for JSON. O(points N m n)."""
        return {"protocol": self.protocol, "costs": self.costs.tolist(), "inputs": self.inputs.tolist(),
                "gains": self.gains.tolist(), "method": self.method}

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per point: its cost J*; the protocol and method as attrs (inputs and gains stay arrays on
        the result: ``inputs[point]`` is an N x m plan)."""
        return ({"point": np.arange(self.costs.size), "cost": self.costs},
                {"protocol": self.protocol, "method": self.method})
