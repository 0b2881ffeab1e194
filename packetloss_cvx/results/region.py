"""The stabilisable set: a channel's membership with its certificate, and each law's critical point."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..display import fields_html, fields_repr, to_json
from ..optional import load
from .base import Frozen, finite_or_none, numbered
from .studies import attained

__all__ = ["RADIUS_MEANING", "CriticalPoint", "Membership", "RegionMap", "StabilityAllocation"]


@dataclass(frozen=True)
class Membership(Frozen):
    """Is ``mu`` in the stabilisable set S (simulation.region)? ``verdict`` "stable", "unstable" or
    "undecided". "stable" comes with ``gain`` (a K whose second-moment operator has ``radius`` < 1 by
    the margin, proved in exact arithmetic); "unstable" with ``certificate`` (P symmetric and not negative
    semidefinite, usually P >= 0 with tr P = 1, and ``T_c(P) >= 0`` exactly: no linear law is mean-square
    stabilising; ``certificate_margin`` = c - 1, c the bound P proves on every law's radius).
    ``forms`` pairs each form that was run ("dp", "riccati", "lmi") with its own verdict; the forms that
    decided agree (else CrossCheckError was raised). ``reason``: why undecided."""

    mu: np.ndarray
    verdict: str
    gain: np.ndarray | None
    radius: float
    certificate: np.ndarray | None
    certificate_margin: float
    forms: tuple[tuple[str, str], ...]
    reason: str = ""

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    @property
    def stable(self) -> bool | None:
        """True / False when decided, None when undecided."""
        return None if self.verdict == "undecided" else self.verdict == "stable"

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (None for a missing certificate). O(n^2)."""
        return {"mu": self.mu.tolist(), "verdict": self.verdict,
                "gain": None if self.gain is None else self.gain.tolist(), "radius": finite_or_none(self.radius),
                "certificate": None if self.certificate is None else self.certificate.tolist(),
                "certificate_margin": finite_or_none(self.certificate_margin), "forms": dict(self.forms),
                "reason": self.reason}


@dataclass(frozen=True)
class CriticalPoint(Frozen):
    """Where a law's region meets the ray ``mu = t * direction`` (simulation.region.critical_point).

    ``t`` the upper end of the final bracket ``[lower, t]`` (``t - lower <= tol``), ``inside`` and
    ``outside`` the decided memberships at ``t`` and ``lower`` (for the DP law: a stabilising gain and an
    infeasibility certificate; None at the ray's ends). ``t`` is ``inf`` when the law is not stable even at
    the ray's end, 0.0 when it is stable at mu = 0. ``note``: empty, or why the bracket is wider than the ``tol``
    asked for (no point inside it could be decided: near the boundary every certificate's margin vanishes); its
    two ends are proved all the same."""

    law: str
    direction: np.ndarray
    t: float
    lower: float
    inside: Membership | None
    outside: Membership | None
    note: str = ""

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    @property
    def mu(self) -> np.ndarray:
        """The boundary point ``t * direction`` (inf entries when t is inf)."""
        return self.t * self.direction

    def to_dict(self) -> dict[str, Any]:
        """``critical_mu`` (a list of m numbers, None when t is inf), ``t``, the bracket and both certificates."""
        finite = bool(np.isfinite(self.t))
        return {"law": self.law, "direction": self.direction.tolist(), "t": finite_or_none(self.t),
                "lower": float(self.lower), "critical_mu": self.mu.tolist() if finite else None,
                "inside": None if self.inside is None else self.inside.to_dict(),
                "outside": None if self.outside is None else self.outside.to_dict(), "note": self.note}


#: what a region map's ``radius`` grid holds, written into its JSON: the "dp" law's and every other law's
RADIUS_MEANING = {
    "dp": "the least mean-square radius over linear laws u = -Kx, min_K rho(L_K) (the homogeneous modified "
          "Riccati eigenvalue; 0 where a deadbeat law exists, never negative; < 1 iff some law stabilises)",
    "law": "the mean-square radius rho(L_K) of this law's own gain at each mu (< 1 - 1e-9: proved stable)"}


@dataclass(frozen=True)
class RegionMap(Frozen):
    """Every law's region (simulation.region_map): ``critical`` one CriticalPoint per law along ``direction``;
    with a grid, ``axis`` (K values on [0, 1]) for ``channels`` (I, J; 0-based), the other channels at
    ``base``, and per law (first axis, in ``laws`` order) ``stable`` (1.0, 0.0, nan where undecided) and
    ``radius``, rows mu_J, columns mu_I. The "dp" radius is the least mean-square radius over linear laws,
    min_K rho(L_K) (the homogeneous Riccati eigenvalue: 0 where a deadbeat law exists, never negative; < 1 iff mu
    is in S), the others the radius of their law's own gain (`RADIUS_MEANING`)."""

    laws: tuple[str, ...]
    direction: np.ndarray
    critical: tuple[CriticalPoint, ...]
    axis: np.ndarray | None
    channels: tuple[int, ...]
    base: np.ndarray | None
    stable: np.ndarray | None
    radius: np.ndarray | None

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    def area(self, law: str) -> float:
        """The fraction of the grid's points where ``law`` is proved stable (nan without a grid). O(K^2)."""
        if self.stable is None:
            return float("nan")
        return float(np.mean(self.stable[self.laws.index(law)] == 1.0))

    def to_dict(self) -> dict[str, Any]:
        """Per law: ``critical_mu`` (m numbers, None when t is inf), ``t`` and, with a grid, ``grid``:
        ``axis``, ``stable`` (true / false / null where undecided), ``radius`` (null where not finite) and
        ``radius_meaning`` (`RADIUS_MEANING`). O(L K^2)."""
        out: dict[str, Any] = {}
        for k, (law, point) in enumerate(zip(self.laws, self.critical, strict=True)):
            entry = point.to_dict()
            entry = {"critical_mu": entry["critical_mu"], "t": entry["t"], "lower": entry["lower"]}
            if self.stable is not None:
                entry["grid"] = {
                    "axis": self.axis.tolist(), "channels": [c + 1 for c in self.channels],
                    "stable": [[None if np.isnan(v) else bool(v) for v in row] for row in self.stable[k]],
                    "radius": [[finite_or_none(v) for v in row] for row in self.radius[k]],
                    "radius_meaning": RADIUS_MEANING["dp" if law == "dp" else "law"]}
            out[law] = entry
        return out

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """With a grid: one row per (law, mu_J, mu_I), law slowest, then rows mu_J, columns mu_I, as
        ``to_xarray().to_dataframe()`` orders them: ``stable`` (1.0, 0.0, nan undecided) and ``radius``; each
        law's critical point as attrs. Without: one row per law, its critical point (t, lower, critical mu)."""
        critical = {law: {"t": p.t, "lower": p.lower, "critical_mu": p.mu.tolist()}
                    for law, p in zip(self.laws, self.critical, strict=True)}
        attrs: dict[str, Any] = {"direction": self.direction.tolist()}
        if self.stable is None:
            mus = np.array([p.mu for p in self.critical], dtype=float).reshape(len(self.laws), -1)
            columns: dict[str, Any] = {"law": list(self.laws), "t": [p.t for p in self.critical],
                                       "lower": [p.lower for p in self.critical]}
            columns.update(dict(zip(numbered("critical_mu", mus.shape[1]), mus.T, strict=True)))
            return columns, attrs
        i, j = self.channels
        K, L = self.axis.size, len(self.laws)
        columns = {"law": np.repeat(np.array(self.laws, dtype=object), K * K),
                   f"mu{j + 1}": np.tile(np.repeat(self.axis, K), L), f"mu{i + 1}": np.tile(self.axis, K * L),
                   "stable": np.ravel(self.stable), "radius": np.ravel(self.radius)}
        return columns, {**attrs, "critical": critical, "base": None if self.base is None else self.base.tolist(),
                         "radius_meaning": dict(RADIUS_MEANING)}

    def plot(self, **kwargs: Any) -> Any:
        """The map drawn by [`plot_region`][packetloss_cvx.plots.figures.plot_region] (the "dp" law's least radius as
        colours,
        each law's boundary as a line; keywords passed on); returns the matplotlib Figure.

        Raises
        ------
        InputError
            Field ``region`` without a grid or without the "dp" law.
        """
        from ..plots import plot_region  # lazy: matplotlib, only when asked to draw
        return plot_region(self, **kwargs)

    def to_xarray(self) -> Any:
        """An xarray Dataset: ``stable`` and ``radius`` over (law, mu_J, mu_I), ``t`` over law (the 'xarray'
        extra); each variable with ``long_name``, ``units`` and ``description`` attrs. O(L K^2)."""
        xr = load("xarray", "to_xarray")
        data = {"t": (("law",), np.array([p.t for p in self.critical]),
                      {"long_name": "critical scale t: the region's boundary at mu = t * direction",
                       "units": "1"})}
        coords: dict[str, Any] = {"law": list(self.laws)}
        if self.stable is not None:
            i, j = self.channels
            dims = ("law", f"mu{j + 1}", f"mu{i + 1}")
            data["stable"] = (dims, self.stable, {"long_name": "proved mean-square stable", "units": "1",
                                                  "description": "1.0 stable, 0.0 not stable, nan undecided"})
            data["radius"] = (dims, self.radius, {"long_name": "mean-square spectral radius", "units": "1",
                                                  "description": f"dp: {RADIUS_MEANING['dp']}; other laws: "
                                                                 f"{RADIUS_MEANING['law']}"})
            for c in (i, j):
                coords[f"mu{c + 1}"] = (f"mu{c + 1}", self.axis,
                                        {"long_name": f"delivery probability of channel {c + 1} (1-based)",
                                         "units": "1"})
        return xr.Dataset(data, coords=coords, attrs={"direction": self.direction.tolist()})


@dataclass(frozen=True)
class StabilityAllocation(Frozen):
    """The cheapest channel for a stability target (allocation.stability): ``mu`` certified inside, ``cost``
    beta'mu, ``lower_bound`` on the optimal beta'mu (proved: LP bounds of the boxes no certificate discarded),
    ``gap`` (cost - lower_bound) / max(cost, 1e-12), ``status`` "optimal" or "gap_not_certified".
    ``radius``: the mean-square radius of ``gain`` at mu (the operator's, < ``radius_bound``): for target
    "stable" the least-radius gain (homogeneous Riccati), for "dp-cost" the DP law. ``dp_cost`` the DP law's
    stationary cost at mu (``dp_cost_kind`` "average" or "total from x0"; nan when the DP solution failed),
    ``alpha`` its bound (None for "stable"), ``boxes`` explored, ``method`` how it ended. ``basis`` "loop":
    ``dp_cost`` is the law run for ever; ``attainable_cost`` the least expected cost over the system's horizon of a
    law with acknowledgements (the finite-horizon DP, allocation.attainable; None with ``attainable_note`` when not
    computed); ``stabilisable`` True, on ``gain``'s certificate; ``actuator`` as `Allocation`'s; ``dp_cost_note`` why
    ``dp_cost`` is nan ("" where it is reported)."""

    target: str
    mu: np.ndarray
    cost: float
    lower_bound: float
    gap: float
    status: str
    radius: float
    radius_bound: float
    gain: np.ndarray
    dp_cost: float
    dp_cost_kind: str
    alpha: float | None
    beta: np.ndarray
    boxes: int
    method: str
    basis: str = "loop"
    attainable_cost: float | None = None
    attainable_note: str = ""
    stabilisable: bool | None = None
    stability_note: str = ""
    actuator: tuple[tuple[str, str, float | None, str], ...] = ()
    dp_cost_note: str = ""

    __repr__ = fields_repr
    _repr_html_ = fields_html
    to_json = to_json

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (None for nan). O(m n)."""
        return {"target": self.target, "mu": self.mu.tolist(), "cost": self.cost, "lower_bound": self.lower_bound,
                "gap": self.gap, "status": self.status, "radius": self.radius, "radius_bound": self.radius_bound,
                "gain": self.gain.tolist(), "dp_cost": finite_or_none(self.dp_cost),
                "dp_cost_kind": self.dp_cost_kind or None, "dp_cost_note": self.dp_cost_note or None,
                "alpha": self.alpha, "beta": self.beta.tolist(),
                "boxes": self.boxes, "method": self.method, **attained(self)}
