"""Delivery probability as a function of transmit power, per channel: the model of a power-limited
link, apart from the problems that buy power ([`.power`][packetloss_cvx.allocation.power]).

`PowerModel` (validated by `power_model`, read from a system file's ``[power]`` table by
`load_power`):

* ``exponential``: ``mu = 1 - exp(-P / c)``, concave;
* ``rayleigh`` (block Rayleigh fading at a fixed rate): ``mu = exp(-c / P)``, concave only for
  ``P >= c / 2`` (``mu >= e^-2``);
* ``table``: piecewise linear through measured points (power, mu), non-decreasing, flat after the last.

Each gives mu(P), its inverse (the least power reaching mu), its slope (a supergradient where concave), the
power beyond which mu no longer grows, where it is concave, and its own unit of power.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..model.files import load_table, read_csv_rows
from ..model.validation import numeric_array

__all__ = ["EXPONENTIAL_TOP", "MODELS", "RAYLEIGH_TOP_SLACK", "PowerModel", "load_power", "power_model",
           "rayleigh_majorant"]

#: the delivery-versus-power models
MODELS = ("exponential", "rayleigh", "table")

#: mu reaches 1 - RAYLEIGH_TOP_SLACK at the Rayleigh model's cap P = c / RAYLEIGH_TOP_SLACK (where no optimum
#: is sought without --power-max: 1e-12 of delivery probability is below every tolerance of J*)
RAYLEIGH_TOP_SLACK = 1e-12
#: the exponential model's mu is 1.0 in double precision from P = 40 c on (1 - e^-40 = 1 - 4e-18)
EXPONENTIAL_TOP = 40.0


@dataclass(frozen=True, eq=False)
class PowerModel:
    """Delivery probability as a function of transmit power, per channel; validated, immutable.

    ``kind`` one of `MODELS`; ``scale`` (m,) the constants c > 0 (exponential, rayleigh);
    ``powers`` (K,) increasing from 0 and ``table`` (K, m) non-decreasing in [0, 1] (table). Build with
    `power_model`. Every method is O(m) per point.

    Examples
    --------
    >>> model = power_model("exponential", 2, scale=[1.0, 2.0])
    >>> model.mu(np.array([np.log(2.0), 0.0])).tolist(), model.power(np.array([0.5, 0.0])).tolist()
    ([0.5, 0.0], [0.6931471805599453, 0.0])
    """

    kind: str
    m: int
    scale: np.ndarray | None = None
    powers: np.ndarray | None = None
    table: np.ndarray | None = None

    def mu(self, P: np.ndarray) -> np.ndarray:
        """Delivery probabilities at powers ``P`` (..., m) >= 0."""
        P = np.maximum(np.asarray(P, dtype=float), 0.0)
        if self.kind == "exponential":
            return -np.expm1(-P / self.scale)
        if self.kind == "rayleigh":
            with np.errstate(divide="ignore"):
                return np.where(P > 0, np.exp(-self.scale / np.where(P > 0, P, 1.0)), 0.0)
        out = np.empty(np.broadcast_shapes(P.shape, (self.m,)))
        for i in range(self.m):
            out[..., i] = np.interp(P[..., i], self.powers, self.table[:, i])
        return out

    def channel(self, i: int, p: float) -> float:
        """mu_i at the power p (one channel)."""
        P = np.zeros(self.m)
        P[i] = p
        return float(self.mu(P)[i])

    def slope(self, P: np.ndarray) -> np.ndarray:
        """d mu_i / d P_i at P (m,) (the right derivative for a table; 0 after its last point): a
        supergradient of mu_i where mu_i is concave."""
        P = np.maximum(np.asarray(P, dtype=float), 0.0)
        if self.kind == "exponential":
            return np.exp(-P / self.scale) / self.scale
        if self.kind == "rayleigh":
            safe = np.where(P > 0, P, 1.0)
            return np.where(P > 0, self.scale / safe ** 2 * np.exp(-self.scale / safe), 0.0)
        out = np.zeros(self.m)
        slopes = np.diff(self.table, axis=0) / np.diff(self.powers)[:, None]
        for i in range(self.m):
            k = int(np.searchsorted(self.powers, P[i], side="right")) - 1
            out[i] = slopes[k, i] if k < len(self.powers) - 1 else 0.0
        return out

    def power(self, mu: np.ndarray) -> np.ndarray:
        """The least power per channel whose delivery reaches ``mu`` (m,): inf where none does."""
        mu = np.asarray(mu, dtype=float)
        with np.errstate(divide="ignore"):
            if self.kind == "exponential":
                return np.where(mu >= 1.0, np.inf, -self.scale * np.log1p(-np.minimum(mu, 1.0)))
            if self.kind == "rayleigh":
                return np.where(mu <= 0.0, 0.0, np.where(mu >= 1.0, np.inf, -self.scale / np.log(np.clip(mu, 1e-300,
                                                                                                        1.0))))
        out = np.empty(self.m)
        for i in range(self.m):
            column = self.table[:, i]
            if mu[i] <= column[0]:
                out[i] = 0.0
            elif mu[i] > column[-1]:
                out[i] = np.inf
            else:
                k = int(np.searchsorted(column, mu[i], side="left"))      # column[k-1] < mu <= column[k]
                lo, hi = column[k - 1], column[k]
                out[i] = self.powers[k - 1] + (mu[i] - lo) / (hi - lo) * (self.powers[k] - self.powers[k - 1])
        return out

    def saturation(self) -> np.ndarray:
        """Per channel a power beyond which mu does not grow (to double precision or to 1e-12): the
        search box's cap when the caller gives none."""
        if self.kind == "exponential":
            return EXPONENTIAL_TOP * self.scale
        if self.kind == "rayleigh":
            return self.scale / RAYLEIGH_TOP_SLACK
        return np.full(self.m, float(self.powers[-1]))

    def unit(self) -> np.ndarray:
        """Per channel the model's own unit of power: c (exponential, rayleigh); for a table the least power that
        reaches half of its last mu (the last power where that is 0: mu(0) already there, or a dead channel).
        The conic program's variable is P / unit, so the unit in which a user states powers (1e-12 or 1e12)
        sits in no coefficient of the cones; a table's half-way power, not its last (a last row at 1e9 beside
        the action at 1 made Clarabel fail where unit 1 did not). O(K m)."""
        if self.kind == "table":
            half = self.power(self.table[-1] / 2.0)
            return np.where((half > 0) & np.isfinite(half), half, float(self.powers[-1]))
        return self.scale.copy()

    def concave_from(self) -> np.ndarray:
        """Per channel the least power from which mu_i is concave (inf: nowhere on a whole table)."""
        if self.kind == "exponential":
            return np.zeros(self.m)
        if self.kind == "rayleigh":
            return self.scale / 2.0
        slopes = np.diff(self.table, axis=0) / np.diff(self.powers)[:, None]
        concave = np.all(np.diff(slopes, axis=0) <= 1e-12 * np.max(np.abs(slopes), axis=0), axis=0)
        return np.where(concave, 0.0, np.inf)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists for JSON. O(K m)."""
        if self.kind == "table":
            return {"model": "table", "powers": self.powers.tolist(), "table": self.table.tolist()}
        return {"model": self.kind, "scale": self.scale.tolist()}


def power_model(model: str, m: int, scale: Any = None, table: Any = None,
                lines: tuple[int, ...] | None = None) -> PowerModel:
    """A validated `PowerModel` for m channels.

    ``scale``: one c > 0 per channel (or one for all); ``table``: rows ``(power, mu)`` (one curve for every
    channel) or ``(power, mu_1, .., mu_m)``, powers increasing from 0, mu non-decreasing in [0, 1]. ``lines``: the
    file line of each table row (a CSV file's, `read_csv_rows`), which errors then cite (``line L``) in place of
    the row's number in the table (``row k``, 1-based).

    Raises
    ------
    InputError
        Field ``power.model``, ``power.scale`` or ``power.table``: an unknown model, a scale that is not
        positive and finite, a table that is not monotone or leaves [0, 1].

    Examples
    --------
    >>> power_model("rayleigh", 2, scale=2.0).scale.tolist()
    [2.0, 2.0]
    >>> power_model("table", 1, table=[[0, 0], [1, 0.5], [2, 0.4]])
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: power.table: mu must not fall as power rises (row 3: 0.4 after 0.5)
    """
    if model not in MODELS:
        raise InputError("power.model", f"expected one of {', '.join(MODELS)}, found {str(model)[:40]!r}")
    if isinstance(m, bool) or not isinstance(m, int | np.integer) or m < 1:
        raise InputError("m", f"expected the number of channels, an integer >= 1, found {m!r:.40}")
    m = int(m)
    if model == "table":
        if table is None or scale is not None:
            raise InputError("power.table", "the table model takes a table of (power, mu) rows and no scale")
        rows = np.atleast_2d(numeric_array(table, "power.table"))
        if rows.ndim != 2 or rows.shape[1] not in (2, m + 1) or rows.shape[0] < 2:
            raise InputError("power.table", f"expected at least 2 rows of (power, mu) or (power, mu1..mu{m}), "
                             f"found shape {rows.shape}")
        powers = rows[:, 0].copy()
        mus = np.repeat(rows[:, 1:], m, axis=1) if rows.shape[1] == 2 else rows[:, 1:].copy()
        if lines is not None and len(lines) != rows.shape[0]:
            raise InputError("power.table", f"expected a line for each of the {rows.shape[0]} rows, found "
                                            f"{len(lines)}")

        def where(k: int) -> str:       # row k, 1-based: its file line where the table came from a file
            return f"row {k}" if lines is None else f"line {lines[k - 1]}"

        if powers[0] != 0.0:
            raise InputError("power.table", f"the first row's power must be 0 (the delivery of a silent channel), "
                             f"found {powers[0]:g}" + ("" if lines is None else f" ({where(1)})"))
        if np.any(np.diff(powers) <= 0):
            k = int(np.argmax(np.diff(powers) <= 0)) + 2
            raise InputError("power.table", f"powers must increase ({where(k)}: {powers[k - 1]:g} after "
                             f"{powers[k - 2]:g})")
        if np.any((mus < 0) | (mus > 1)):
            k = int(np.argmax(np.any((mus < 0) | (mus > 1), axis=1))) + 1
            raise InputError("power.table", f"mu must lie in [0, 1] ({where(k)})")
        if np.any(np.diff(mus, axis=0) < 0):
            k = int(np.argmax(np.any(np.diff(mus, axis=0) < 0, axis=1))) + 2
            col = int(np.argmax(np.diff(mus, axis=0)[k - 2] < 0))
            raise InputError("power.table", f"mu must not fall as power rises ({where(k)}: {mus[k - 1, col]:g} "
                             f"after {mus[k - 2, col]:g})")
        return PowerModel(model, m, powers=_frozen(powers), table=_frozen(mus))
    if table is not None:
        raise InputError("power.table", f"the {model} model takes a scale, not a table")
    if scale is None:
        raise InputError("power.scale", f"the {model} model needs a scale c > 0 per channel")
    c = np.atleast_1d(numeric_array(scale, "power.scale"))
    if c.ndim != 1 or len(c) not in (1, m):
        raise InputError("power.scale", f"expected 1 or {m} numbers, found shape {c.shape}")
    if np.any(~(c > 0)):
        raise InputError("power.scale", f"expected positive numbers, found {c.tolist()}")
    return PowerModel(model, m, scale=_frozen(np.broadcast_to(c, (m,)).copy()))


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def load_power(path: str | Path, m: int) -> PowerModel | None:
    """The ``[power]`` table of a system file (None when it has none): ``model``, and ``scale`` or ``table``
    (inline rows, or a CSV file's name relative to the system file, read by
    `read_csv_rows`, its errors citing the file's lines). Errors name ``power.<key>``. O(size).

    Examples
    --------
    >>> load_power("two_actuator", 2) is None          # the packaged example has no [power] table
    True
    """
    section = load_table(path).get("power")
    if section is None:
        return None
    if not isinstance(section, dict):
        raise InputError("power", "expected a table")
    for key in section:
        if key not in ("model", "scale", "table"):
            raise InputError(f"power.{key}", "unknown key; expected one of model, scale, table")
    if "model" not in section:
        raise InputError("power.model", "missing field")
    table = section.get("table")
    lines = None
    if isinstance(table, str):
        csv = read_csv_rows(Path(path).parent / table, "power.table")
        table, lines = csv.rows, csv.lines
    return power_model(section["model"], m, scale=section.get("scale"), table=table, lines=lines)


def rayleigh_majorant(model: PowerModel, at: np.ndarray) -> PowerModel:
    """A concave table above the rayleigh curve ``f(P) = exp(-c/P)`` everywhere on P >= 0: the least of its
    tangents at the powers ``p c`` for each ``p`` of ``at`` (in units of c, clipped to >= 1) and of mu = 1.

    With ``l = 1/p`` the tangent at ``p c`` is ``e^-l (1 - l + l^2 P / c)``; f is the least of these over
    ``p >= 1/2`` (docs/mathematics.md, "Rayleigh's concave part"), and those with ``p >= 1`` lie above f's concave
    envelope (the line ``P / (e c)`` up to c, where the tangent at p = 1 passes through the origin, then f),
    so every finite set of them, with mu <= 1, is a concave majorant: `J*` of it bounds `J*` of f below. Its
    breakpoints (consecutive tangents' crossings, then the last one's meeting mu = 1) per channel, merged
    into one power column. O(K m log(K m)) for K tangents.

    Examples
    --------
    One tangent (at P = c, the line P / (e c)) and the cap: the table is (0, 0), (e c, 1).

    >>> t = rayleigh_majorant(power_model("rayleigh", 1, scale=2.0), np.array([1.0]))
    >>> np.round(t.powers, 6).tolist(), t.table[:, 0].tolist()
    ([0.0, 5.436564], [0.0, 1.0])
    """
    if model.kind != "rayleigh":
        raise InputError("model", f"a rayleigh majorant needs the rayleigh model, found {model.kind}")
    p = np.unique(np.maximum(np.asarray(at, dtype=float).ravel(), 1.0))
    l = 1.0 / p
    lines = []                   # per channel: (breakpoints, slopes, intercepts) in P
    for c in model.scale:
        slope = np.exp(-l) * l ** 2 / c              # falls as p rises: the tangents in order
        start = np.exp(-l) * (1.0 - l)
        cross = (start[1:] - start[:-1]) / (slope[:-1] - slope[1:])
        full = (1.0 - start[-1]) / slope[-1]
        lines.append((np.concatenate([[0.0], cross, [full]]), slope, start))
    powers = np.unique(np.concatenate([b for b, _, _ in lines]))
    table = np.empty((len(powers), model.m))
    for i, (_, slope, start) in enumerate(lines):
        table[:, i] = np.minimum(np.min(start[None, :] + slope[None, :] * powers[:, None], axis=1), 1.0)
    return PowerModel("table", model.m, powers=_frozen(powers), table=_frozen(np.clip(table, 0.0, 1.0)))
