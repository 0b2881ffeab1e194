"""Results of design questions: allocations, claim verdicts, maximisers, sweeps (and design-study sweeps)
and minimum costs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..display import (
    allocation_html,
    allocation_repr,
    claim_html,
    claim_repr,
    design_sweep_html,
    design_sweep_repr,
    fields_html,
    fields_repr,
    maximiser_repr,
    to_json,
)
from ..errors import InputError
from ..optional import load
from ..tolerances import ALLOCATION_COST_RTOL
from .base import Frozen, freeze, numbered, read_only

__all__ = ["Allocation", "ClaimResult", "DesignSweep", "Maximiser", "MinCost", "PowerAllocation", "ProtocolChoice",
           "Sweep", "attained", "loop_warning"]


def loop_warning(alpha: float | None, attainable_cost: float | None, stabilisable: bool | None) -> str | None:
    """One line saying what misleads at an allocation's mu*: no linear law holds the loop, or the attainable cost
    exceeds alpha (beyond ALLOCATION_COST_RTOL); None when neither. O(1).

    >>> loop_warning(8.0, 38.08, False)
    'warning: at mu* no linear law holds the loop mean-square stable, and the attainable cost 38.08 exceeds alpha = 8'
    >>> loop_warning(8.0, 8.0, True) is None, loop_warning(8.0, None, None) is None
    (True, True)
    """
    parts = []
    if stabilisable is False:
        parts.append("no linear law holds the loop mean-square stable")
    if alpha is not None and attainable_cost is not None and attainable_cost > alpha * (1.0 + ALLOCATION_COST_RTOL):
        parts.append(f"the attainable cost {attainable_cost:.6g} exceeds alpha = {alpha:.6g}")
    return "warning: at mu* " + ", and ".join(parts) if parts else None


def attained(result: Any) -> dict[str, Any]:
    """The JSON keys of what a loop attains at an allocation's mu: ``basis`` (of its ``cost``),
    ``attainable_cost``, ``attainable_note``, ``stabilisable``, ``stability_note``; ``actuator`` where the
    allocation was asked for the actuator strategies' verdicts (per strategy ``verdict``, ``radius``, ``reason``,
    as ``allocate --actuator``). O(1)."""
    out = {"basis": result.basis, "attainable_cost": result.attainable_cost,
           "attainable_note": result.attainable_note, "stabilisable": result.stabilisable,
           "stability_note": result.stability_note}
    verdicts = getattr(result, "actuator", ())
    if verdicts:
        out["actuator"] = {name: {"verdict": verdict, "radius": radius, "reason": reason}
                           for name, verdict, radius, reason in verdicts}
    return out


@dataclass(frozen=True)
class Allocation(Frozen):
    """The cheapest channel qualities found, with a certificate.

    ``mu``: delivery probabilities; ``communication_cost``: beta'mu; ``cost``: `J*(mu)` by the
    closed form (<= alpha); ``lower_bound``: a proven lower bound on the optimal beta'mu;
    ``gap``: (communication_cost - lower_bound) / max(communication_cost, 1e-12);
    ``status``: "optimal" (the gap is certified) or "gap_not_certified" (a cap on boxes or time
    was hit; ``gap`` is the gap reached); ``method``: how it was solved; ``boxes``: boxes the
    UDP-like branch and bound explored (0 for the TCP-like SOCP). ``lower_bound`` is proved:
    tangent cuts of the convex `J*_tcp` with an exactly evaluated LP dual (TCP-like), the branch
    and bound's remaining boxes (UDP-like).

    What a loop attains at mu (allocation.attainable): ``attainable_cost``, the least expected cost a causal
    law of the protocol reaches over the horizon (TCP-like: the finite-horizon DP with acknowledgements, which
    may exceed alpha; UDP-like: ``cost`` itself), None when not computed (``attainable_note`` says why);
    ``stabilisable``: does some linear law hold the loop mean-square stable at mu (True / False, each certified;
    None when undecided or not computed, ``stability_note`` says why). ``basis``: what ``cost`` is ("paper":
    the paper's J*(mu); "attainable": the exact expected cost under a chain). ``actuator``: with
    ``allocate(..., actuator=...)``, per strategy on a loss ``(name, verdict, radius, reason)``: is mu
    stabilisable by a TCP-like law of that strategy ("stable" / "unstable", each proved, or "undecided";
    closedloop.actuator_region.actuator_membership; radius None unless stable).
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
    basis: str = "paper"
    attainable_cost: float | None = None
    attainable_note: str = ""
    stabilisable: bool | None = None
    stability_note: str = ""
    actuator: tuple[tuple[str, str, float | None, str], ...] = ()

    __repr__ = allocation_repr
    _repr_html_ = allocation_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    @property
    def warning(self) -> str | None:
        """One line when mu* misleads (no linear law holds the loop, or the attainable cost exceeds alpha)."""
        return loop_warning(self.alpha, self.attainable_cost, self.stabilisable)

    def to_dict(self) -> dict[str, Any]:
        return {"protocol": self.protocol, "alpha": self.alpha, "beta": self.beta.tolist(),
                "mu": self.mu.tolist(), "communication_cost": self.communication_cost, "cost": self.cost,
                "lower_bound": self.lower_bound, "gap": self.gap, "status": self.status, "method": self.method,
                "boxes": self.boxes, **attained(self)}


@dataclass(frozen=True)
class PowerAllocation(Frozen):
    """Transmit power per channel with a certificate (allocation/power.py).

    ``problem``: "least-power" (min sum P with `J*` <= ``limit`` = alpha; ``lower_bound`` proven on the total
    power) or "least-cost" (min `J*` with sum P <= ``limit`` = the budget; ``lower_bound`` proven on `J*`);
    ``model``: the delivery-versus-power model as a dict; ``power`` (m,), ``total_power``, ``mu`` = mu(power),
    ``cost`` = `J*(mu)` by the closed form; ``gap``: (objective - lower_bound) / objective; ``status``
    "optimal" or "gap_not_certified"; ``method``; ``boxes`` the branch and bound explored. Construction O(m).
    """

    protocol: str
    problem: str
    model: dict
    power: np.ndarray
    total_power: float
    mu: np.ndarray
    cost: float
    limit: float
    lower_bound: float
    gap: float
    status: str
    method: str
    boxes: int = 0
    basis: str = "paper"
    attainable_cost: float | None = None
    attainable_note: str = ""
    stabilisable: bool | None = None
    stability_note: str = ""

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    @property
    def warning(self) -> str | None:
        """One line when mu* misleads (no linear law holds the loop, or, least-power, the attainable cost exceeds
        alpha)."""
        return loop_warning(self.limit if self.problem == "least-power" else None, self.attainable_cost,
                            self.stabilisable)

    def to_dict(self) -> dict[str, Any]:
        """Plain floats and lists for JSON. O(m)."""
        limit = "alpha" if self.problem == "least-power" else "budget"
        return {"protocol": self.protocol, "problem": self.problem, "model": self.model,
                "power": self.power.tolist(), "total_power": self.total_power, "mu": self.mu.tolist(),
                "cost": self.cost, limit: self.limit, "lower_bound": self.lower_bound, "gap": self.gap,
                "status": self.status, "method": self.method, "boxes": self.boxes, **attained(self)}


@dataclass(frozen=True)
class ProtocolChoice(Frozen):
    """TCP-like (plus its acknowledgement link) or UDP-like, for one alpha (allocation/ack.py).

    ``currency``: "beta'mu" or "power"; ``tcp``, ``udp``: the two designs (Allocation or PowerAllocation;
    ``udp`` None when no UDP-like design meets alpha); ``tcp_total``: the TCP-like design's total plus
    ``ack_price``; ``udp_total`` (inf when none); ``choice``: "tcp" or "udp" (UDP-like on a tie);
    ``certified``: the chosen total is at most the other's proven lower bound; ``break_even``: the
    acknowledgement price above which the UDP-like design wins. Those are on the paper's basis (the TCP-like design
    on J*_tcp, which no controller attains); on the attainable basis (the TCP-like design on the finite-horizon
    DP's cost, ``allocate(..., target="attainable")``; the UDP-like design is the same): ``tcp_attainable`` (None
    with ``attainable_note``), ``tcp_total_attainable``, ``choice_attainable``, ``break_even_attainable`` (nan
    where not computed). ``break_even_by_basis``: the two prices by basis. Construction O(1).
    """

    alpha: float
    currency: str
    ack_price: float
    tcp: Any
    udp: Any
    tcp_total: float
    udp_total: float
    choice: str
    certified: bool
    break_even: float
    tcp_attainable: Any = None
    tcp_total_attainable: float = np.nan
    choice_attainable: str | None = None
    break_even_attainable: float = np.nan
    attainable_note: str = ""

    __repr__ = fields_repr   # the headline numbers, not the designs (display.py)
    _repr_html_ = fields_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    @property
    def break_even_by_basis(self) -> dict[str, float]:
        """``{"paper": break_even, "attainable": break_even_attainable}``. O(1)."""
        return {"paper": self.break_even, "attainable": self.break_even_attainable}

    def to_dict(self) -> dict[str, Any]:
        """Plain floats and dicts for JSON (inf and nan as None); ``"break_even_by_basis"``: one entry per basis
        (``"basis"``, ``"tcp_design"`` the TCP-like design's total without the link, ``"tcp_total"``,
        ``"choice"``, ``"break_even_ack_price"``), the paper's first. O(m)."""
        def finite(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None
        a = self.tcp_attainable
        design = self.tcp.total_power if self.currency == "power" else self.tcp.communication_cost
        bases = [{"basis": "paper", "tcp_design": finite(design),
                  "tcp_total": finite(self.tcp_total), "choice": self.choice,
                  "break_even_ack_price": finite(self.break_even), "note": "TCP-like design on J*_tcp (the paper's "
                                                                           "first-moment cost, not attained)"},
                 {"basis": "attainable", "tcp_design": None if a is None else a.communication_cost,
                  "tcp_total": finite(self.tcp_total_attainable), "choice": self.choice_attainable,
                  "break_even_ack_price": finite(self.break_even_attainable),
                  "note": self.attainable_note or "TCP-like design on the finite-horizon DP's cost"}]
        return {"protocol": "best", "alpha": self.alpha, "currency": self.currency, "ack_price": self.ack_price,
                "choice": self.choice, "certified": self.certified, "tcp_total": finite(self.tcp_total),
                "udp_total": finite(self.udp_total), "break_even_ack_price": finite(self.break_even),
                "break_even_by_basis": bases,
                "tcp": self.tcp.to_dict(), "udp": None if self.udp is None else self.udp.to_dict(),
                "tcp_attainable": None if a is None else a.to_dict()}


@dataclass(frozen=True)
class ClaimResult(Frozen):
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

    __repr__ = claim_repr
    _repr_html_ = claim_html

    def __post_init__(self) -> None:
        if self.verdict not in ("holds", "fails", "not-reproduced", "inconclusive"):
            raise ValueError(f"verdict: expected holds, fails, not-reproduced or inconclusive, found {self.verdict!r}")
        if self.verdict == "holds" and (self.checked <= 0 or self.errors or self.violations):
            raise ValueError(f"verdict: 'holds' needs checked > 0 with no violation and no error, found "
                             f"checked={self.checked}, violations={self.violations}, errors={self.errors}")
        freeze(self)

    to_json = to_json   # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id, "statement": self.statement, "verdict": self.verdict, "checked": self.checked,
            "violations": self.violations, "errors": self.errors,
            "worst": self.worst if self.worst is None or np.isfinite(self.worst) else None,   # JSON has no inf
            "counterexample": self.counterexample, "note": self.note, "outcomes": self.outcomes,
        }


@dataclass(frozen=True)
class Maximiser(Frozen):
    """Where J_Delta peaks: ``nu`` (or ``mu`` for per-channel), the value, and how found."""

    point: np.ndarray
    value: float
    method: str

    __repr__ = maximiser_repr
    _repr_html_ = fields_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        return {"point": self.point.tolist(), "value": self.value, "method": self.method}


@dataclass(frozen=True)
class Sweep(Frozen):
    """Optimal costs over a grid of delivery probabilities
        ([`packetloss_cvx.studies.sweeps`][packetloss_cvx.studies.sweeps]).

    ``axes``: one array per swept dimension; ``costs``: protocol -> array over the grid;
    ``difference``: `J*_udp` - `J*_tcp` over the grid (None unless both protocols were swept);
    ``difference_method``: how the difference was computed.
    """

    axes: tuple[np.ndarray, ...]
    costs: dict[str, np.ndarray]
    difference: np.ndarray | None
    difference_method: str | None

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html

    def __post_init__(self) -> None:
        freeze(self)
        object.__setattr__(self, "axes", tuple(read_only(a) for a in self.axes))
        object.__setattr__(self, "costs", {k: read_only(v) for k, v in self.costs.items()})

    to_json = to_json   # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        return {"axes": [a.tolist() for a in self.axes], "costs": {k: v.tolist() for k, v in self.costs.items()},
                "difference": None if self.difference is None else self.difference.tolist(),
                "difference_method": self.difference_method}

    def _names(self) -> tuple[str, ...]:
        """The axes' names: ("nu",) for a shared channel, ("mu2", "mu1") for two channels (rows follow mu2)."""
        return ("nu",) if len(self.axes) == 1 else ("mu2", "mu1")

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per grid point: nu (one shared channel) or mu2, mu1 (mu2 slowest, as the cost arrays' rows),
        cost_<protocol> and cost_diff (J*_udp - J*_tcp); the difference's method as attrs."""
        names = self._names()
        grids = np.meshgrid(*self.axes, indexing="ij")
        columns: dict[str, Any] = {name: np.ravel(g) for name, g in zip(names, grids, strict=True)}
        columns.update({f"cost_{p}": np.ravel(v) for p, v in self.costs.items()})
        if self.difference is not None:
            columns["cost_diff"] = np.ravel(self.difference)
        return columns, {"difference_method": self.difference_method or ""}

    def plot(self, quantity: str | None = None, **kwargs: Any) -> Any:
        """Draw the sweep; returns the matplotlib Figure. One shared channel: every cost (and J_Delta) against
        nu by [`plot_cost_lines`][packetloss_cvx.plots.figures.plot_cost_lines]; two channels: ``quantity`` ("cost_tcp",
        "cost_udp" or "cost_diff", the default where swept, else the first cost) on a logarithmic colour map by
        [`plot_log_contour`][packetloss_cvx.plots.figures.plot_log_contour]. Keywords go to the plot function.

        Raises
        ------
        InputError
            Field ``quantity``: not one of the sweep's quantities.
        """
        from ..plots import plot_cost_lines, plot_log_contour  # lazy: matplotlib, only when asked to draw
        values = {f"cost_{p}": v for p, v in self.costs.items()}
        if self.difference is not None:
            values["cost_diff"] = self.difference
        if len(self.axes) == 1:
            curves = {("diff" if k == "cost_diff" else k[5:]): v for k, v in values.items()}
            if quantity is not None:
                curves = {k: v for k, v in curves.items() if f"cost_{k}" == quantity or k == quantity}
            return plot_cost_lines(self.axes[0], curves, **{"xlabel": r"$\nu$", **kwargs})
        quantity = quantity or ("cost_diff" if "cost_diff" in values else next(iter(values)))
        if quantity not in values:
            raise InputError("quantity", f"expected one of {', '.join(values)}, found {quantity!r}")
        return plot_log_contour(self.axes[1], self.axes[0], values[quantity], **kwargs)


@dataclass(frozen=True)
class MinCost(Frozen):
    """The least optimal cost J*(mu) reachable within bounds and constraints.

    ``cost``: J*(mu) at ``mu`` (reachable, by the closed form); ``lower_bound``: proven, no
    admissible mu does better; ``gap``: (cost - lower_bound) / cost; ``status``: "optimal"
    (gap <= ``tolerances.MIN_COST_RTOL``) or "gap_not_certified"; ``method``: how found; ``basis``: what ``cost``
    is ("paper": the paper's `J*(mu)`; "attainable": the exact expected cost under a chain). Construction O(m).
    """

    protocol: str
    cost: float
    lower_bound: float
    gap: float
    status: str
    mu: np.ndarray
    method: str
    basis: str = "paper"

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        """Plain floats and lists for JSON. O(m)."""
        return {"protocol": self.protocol, "cost": self.cost, "lower_bound": self.lower_bound, "gap": self.gap,
                "status": self.status, "mu": self.mu.tolist(), "method": self.method, "basis": self.basis}


@dataclass(frozen=True)
class DesignSweep(Frozen):
    """Optimal costs over a design study ([`packetloss_cvx.studies.sweep`][packetloss_cvx.studies.design.sweep]), over
        its points.

    ``kind``: "mu-grid", "mu-list", "x0-scale" or "horizon"; ``dims``/``axes``: the swept dimensions,
    slowest first (``("mu2", "mu1")`` for a 2-D grid: rows follow mu2), the points being the axes'
    Cartesian product in C order; ``mu`` (points, m), ``x0`` (points, n), ``horizon`` (points,): each point;
    ``costs``: protocol -> `J*` (points,); ``difference``: `J*_udp` - `J*_tcp` (points,) or None, the difference of
    the two checked costs, exactly 0 where every mu_i is 0 or 1, else accurate to about 1e-15 `J*_udp`
    absolute (so not relatively where the costs nearly agree); ``name``: the system's;
    ``chunk_size``: points per batched evaluation (in process or per Dask task); ``radii``: protocol ->
    the mean-square spectral radius of its receding-horizon law's closed loop at each point (points,), when
    asked for (stable iff < 1), else empty.
    """

    kind: str
    dims: tuple[str, ...]
    axes: tuple[np.ndarray, ...]
    mu: np.ndarray
    x0: np.ndarray
    horizon: np.ndarray
    costs: dict[str, np.ndarray]
    difference: np.ndarray | None
    name: str | None
    chunk_size: int
    radii: dict[str, np.ndarray] = field(default_factory=dict)

    __repr__ = design_sweep_repr   # one line: the grid and each quantity's range (display.py)
    _repr_html_ = design_sweep_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def __post_init__(self) -> None:
        freeze(self)
        object.__setattr__(self, "axes", tuple(read_only(a) for a in self.axes))
        object.__setattr__(self, "costs", {k: read_only(v) for k, v in self.costs.items()})
        object.__setattr__(self, "radii", {k: read_only(v) for k, v in self.radii.items()})

    @property
    def shape(self) -> tuple[int, ...]:
        """The grid's shape: one length per dimension."""
        return tuple(a.size for a in self.axes)

    def arrays(self) -> dict[str, np.ndarray]:
        """Flat arrays as ``sweep.npz`` stores them: mu, x0, horizon, cost_<protocol>, cost_diff,
        radius_<protocol>, axis_<dim>. O(points)."""
        out = {"mu": self.mu, "x0": self.x0, "horizon": self.horizon, **{f"cost_{p}": v for p, v in self.costs.items()}}
        if self.difference is not None:
            out["cost_diff"] = self.difference
        out.update({f"radius_{p}": v for p, v in self.radii.items()})
        return {**out, **{f"axis_{d}": a for d, a in zip(self.dims, self.axes, strict=True)}}

    def grid(self, name: str) -> np.ndarray:
        """The flat array ``name`` (as `arrays` names it: cost_tcp, cost_udp, cost_diff, radius_<protocol>,
        mu, x0, horizon) on the sweep's axes: shape `shape` (mu: ``shape + (m,)``, x0: ``shape + (n,)``), so
        ``grid("cost_udp")[j, i]`` is at ``axes[0][j], axes[1][i]`` (a 2-D grid: mu2 = axes[0], mu1 = axes[1]).
        A read-only view, O(1).

        Raises
        ------
        InputError
            Field ``name``: not one of this sweep's arrays (the message lists them).
        """
        flat = {k: v for k, v in self.arrays().items() if not k.startswith("axis_")}
        if name not in flat:
            raise InputError("name", f"expected one of {', '.join(flat)}, found {name!r}")
        value = flat[name]
        return value.reshape(*self.shape, -1) if value.ndim == 2 else value.reshape(self.shape)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists for JSON. O(points (m + n))."""
        return {"kind": self.kind, "name": self.name, "dims": list(self.dims), "shape": list(self.shape),
                "chunk_size": self.chunk_size, **{k: v.tolist() for k, v in self.arrays().items()}}

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per point, the columns of ``sweep.csv``: mu1..mum, x0_1..x0_n, horizon, cost_<protocol>,
        cost_diff, radius_<protocol>; kind, name, dims and chunk size as attrs."""
        columns: dict[str, Any] = dict(zip(numbered("mu", self.mu.shape[1]), self.mu.T, strict=True))
        columns.update(zip(numbered("x0", self.x0.shape[1]), self.x0.T, strict=True))
        columns["horizon"] = self.horizon
        flat = self.arrays()
        columns.update({k: v for k, v in flat.items() if k.startswith(("cost_", "radius_"))})
        return columns, {"kind": self.kind, "name": self.name or "", "dims": list(self.dims),
                         "chunk_size": self.chunk_size}

    def plot(self, quantity: str | None = None, **kwargs: Any) -> Any:
        """Draw the sweep; returns the matplotlib Figure. One dimension: every cost (and J_Delta) against it by
        [`plot_cost_lines`][packetloss_cvx.plots.figures.plot_cost_lines], or only ``quantity``; a 2-D mu grid:
        ``quantity``
        ("cost_tcp", "cost_udp", "cost_diff" or "radius_<protocol>"; default cost_diff where swept, else the
        first cost) over (mu1, mu2) on a logarithmic colour map by
        [`plot_log_contour`][packetloss_cvx.plots.figures.plot_log_contour].
        Keywords go to the plot function.

        Raises
        ------
        InputError
            Field ``quantity``: not one of the sweep's quantities.
        """
        from ..plots import plot_cost_lines, plot_log_contour  # lazy: matplotlib, only when asked to draw
        values = {k: v for k, v in self.arrays().items() if k.startswith(("cost_", "radius_"))}
        if quantity is not None and quantity not in values:
            raise InputError("quantity", f"expected one of {', '.join(values)}, found {quantity!r}")
        if len(self.dims) == 1:
            labels = {"x0": "scale of x0", "horizon": "horizon N", "point": "point (row of the mu list)",
                      "nu": r"$\nu$ (every channel)"}
            label = labels.get(self.dims[0].partition("_")[0], _mu_label(self.dims[0]))
            chosen = {quantity: values[quantity]} if quantity else {k: v for k, v in values.items()
                                                                    if k.startswith("cost_")}
            curves = {("diff" if k == "cost_diff" else k[5:]): v for k, v in chosen.items()}
            return plot_cost_lines(self.axes[0], curves, **{"xlabel": label, **kwargs})
        costs = [k for k in values if k.startswith("cost_")]
        quantity = quantity or ("cost_diff" if "cost_diff" in values else costs[0])
        names = tuple(_mu_label(d) for d in self.dims)
        return plot_log_contour(self.axes[1], self.axes[0], self.grid(quantity),
                                **{"xlabel": names[1], "ylabel": names[0], **kwargs})

    def to_xarray(self) -> Any:
        """An `xarray.Dataset` over ``dims`` only (the ``xarray`` extra), so that ``to_dataframe()`` has
        one row per point: cost_<protocol>, cost_diff, radius_<protocol>, and each point's mu1..mum, x0_1..x0_n
        and horizon, one variable per channel and per state (those that are a dimension are its coordinate);
        the axes as coordinates. Every variable carries ``long_name`` and ``units`` attrs. O(points (m + n)).

        Raises
        ------
        InputError
            Field ``to_xarray`` when xarray is not installed (the message says how to install it).
        """
        xr = load("xarray", "to_xarray")
        dims = self.dims
        columns, _ = self._table()
        data = {}
        for key, values in columns.items():
            if key in dims:          # a swept variable that is also a dimension is its coordinate
                continue
            data[key] = (dims, np.asarray(values).reshape(self.shape), _variable_attrs(key))
        coords = {d: (d, a, _variable_attrs(d)) for d, a in zip(dims, self.axes, strict=True)}
        attrs = {"kind": self.kind, "name": self.name or "", "chunk_size": self.chunk_size,
                 "cost_diff": "J*_udp - J*_tcp, the difference of the two checked costs"}
        return xr.Dataset(data, coords=coords, attrs=attrs)


def _mu_label(dim: str) -> str:
    """Mathtext of a swept channel's axis: ``mu2`` -> ``$\\mu_2$`` (braces from channel 10 on)."""
    k = dim[2:]
    return rf"$\mu_{k}$" if len(k) == 1 else rf"$\mu_{{{k}}}$"


def _variable_attrs(name: str) -> dict[str, str]:
    """``long_name`` and ``units`` of a design sweep's variable or coordinate (CF conventions: "1" is
    dimensionless; a cost is in the units of the stage cost x'Qx + u'Ru, which the package does not know).

    Examples
    --------
    >>> _variable_attrs("mu2")["long_name"], _variable_attrs("cost_udp")["long_name"]
    ('delivery probability of channel 2 (1-based)', 'optimal expected cost J* (UDP-like)')
    """
    kind, _, rest = name.partition("_")
    cost_units = "stage-cost units (x'Qx + u'Ru)"
    if name.startswith("mu") and name[2:].isdigit():
        return {"long_name": f"delivery probability of channel {name[2:]} (1-based)", "units": "1"}
    if name.startswith("x0_"):
        return {"long_name": f"initial state x0, component {rest} (1-based)", "units": "state units"}
    if name == "cost_diff":
        return {"long_name": "J*_udp - J*_tcp", "units": cost_units}
    if kind == "cost":
        return {"long_name": f"optimal expected cost J* ({rest.upper()}-like)", "units": cost_units}
    if kind == "radius":
        return {"long_name": f"mean-square spectral radius of the {rest.upper()}-like receding-horizon law",
                "units": "1", "description": "< 1: mean-square stable"}
    return {"horizon": {"long_name": "horizon N", "units": "steps"},
            "nu": {"long_name": "delivery probability of every channel", "units": "1"},
            "x0_scale": {"long_name": "scale of the initial state x0", "units": "1"},
            "point": {"long_name": "row of the mu list (0-based)", "units": "1"}}.get(name, {"long_name": name})
