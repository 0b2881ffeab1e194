"""Constraints on a plan: input and rate bounds, limits on the expected state, chance constraints.

A `Constraints` is data only (validated once, immutable, no cvxpy): the constrained expected-cost QP
(`packetloss_cvx.qp.constrained`) poses it, the system file's ``[constraints]`` table holds it
(`constraints_from_dict`, `Constraints.to_dict`). The mathematics is docs/mathematics.md §7.

* ``u_min <= u_t <= u_max`` (m numbers each) on every commanded input ``t = 0..N-1``. A lost packet applies zero,
  so zero must lie inside the bounds (``u_min <= 0 <= u_max``): otherwise the constraint cannot hold on the
  realised loop, and it is refused.
* ``|u_t - u_{t-1}| <= du_max`` (m numbers) between successive commanded inputs ``t = 1..N-1``.
* ``x_min <= E[x_k] <= x_max`` (n numbers each) and ``F E[x_k] <= g`` on every predicted step ``k = 1..N``.
* the terminal set: ``terminal_min <= E[x_N] <= terminal_max`` (n numbers each) and ``terminal_F E[x_N] <=
  terminal_g``, on the last predicted state only.
* ``chance``: rows ``(a, b, eps)``, each ``P(a' x_k <= b) >= 1 - eps`` on every ``k = 1..N``, posed through
  Cantelli's inequality from the exact mean and covariance of ``x_k``.
* ``soft``: the state limits (terminal set included) and chance constraints become exact-penalty slacks of weight
  ``soft_weight`` (cost units per unit of violation, summed over rows and steps). Input and rate bounds stay hard:
  U = 0 satisfies them, so a soft problem is always feasible.

Infinite entries (``-inf``/``inf``) leave a bound out.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import DimensionError, InputError

__all__ = ["SOFT_WEIGHT_DEFAULT", "Constraints", "cantelli_factor", "check_constraints", "constraints_from_dict"]

#: The default exact-penalty weight of soft constraints, in cost units per unit of violation. The penalty is exact
#: (the soft optimum is the hard one whenever the hard problem is feasible) once the weight exceeds the largest
#: multiplier of the hard problem; a solve reports the slack it used, so a weight that was too small shows.
SOFT_WEIGHT_DEFAULT = 1e4

#: the keys of the ``[constraints]`` table, in the order they are written
KEYS = ("u_min", "u_max", "du_max", "x_min", "x_max", "F", "g", "terminal_min", "terminal_max", "terminal_F",
        "terminal_g", "chance", "soft", "soft_weight")
#: the vector fields of n numbers (box limits on E[x_k], on E[x_N])
STATE_BOXES = (("x_min", "x_max"), ("terminal_min", "terminal_max"))
#: the polyhedra (F, g): on every E[x_k], on E[x_N]
POLYHEDRA = (("F", "g"), ("terminal_F", "terminal_g"))


def cantelli_factor(eps: float) -> float:
    """``sqrt((1 - eps) / eps)``: ``mean + factor * std <= b`` gives ``P(Y > b) <= eps`` for every distribution of
    that mean and standard deviation (Cantelli's one-sided inequality), and the two-point distribution attains it.

    Examples
    --------
    >>> cantelli_factor(0.5), cantelli_factor(0.2)
    (1.0, 2.0)
    """
    return float(np.sqrt((1.0 - eps) / eps))


def _vector(value: Any, size: int | None, field_name: str) -> np.ndarray | None:
    """A read-only float vector of ``size`` numbers (any length when ``size`` is None, a scalar read as one)."""
    if value is None:
        return None
    try:
        array = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise InputError(field_name, f"expected numbers, found {value!r}"[:200]) from None
    if array.ndim != 1 or (size is not None and array.size != size):
        expected = f"{size} numbers" if size is not None else "a vector of numbers"
        raise DimensionError(field_name, f"expected {expected} but found shape {array.shape}")
    if np.any(np.isnan(array)):
        raise InputError(field_name, "expected numbers, found NaN")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class Constraints:
    """Constraints on a plan (module docstring); every field optional. The sizes are checked against a system by
    `check_constraints` (every solve does): ``u_*``, ``du_max`` m numbers, ``x_*``, ``a``, ``F``'s rows n.

    Parameters
    ----------
    u_min, u_max : m numbers, optional
        Bounds on every commanded input; ``u_min <= 0 <= u_max`` (a lost packet applies zero).
    du_max : m numbers >= 0, optional
        Bound on ``|u_t - u_{t-1}|``.
    x_min, x_max : n numbers, optional
        Bounds on the expected state ``E[x_k]``, k = 1..N.
    F, g : r x n and r numbers, optional
        The polyhedron ``F E[x_k] <= g``, k = 1..N (both or neither).
    terminal_min, terminal_max : n numbers, optional
        The terminal box ``terminal_min <= E[x_N] <= terminal_max``.
    terminal_F, terminal_g : r x n and r numbers, optional
        The terminal polyhedron ``terminal_F E[x_N] <= terminal_g`` (both or neither).
    chance : rows (a, b, eps), optional
        ``P(a' x_k <= b) >= 1 - eps`` for k = 1..N, ``a`` n numbers, ``0 < eps < 1``.
    soft : bool
        State limits (terminal set included) and chance constraints as exact-penalty slacks of weight
        ``soft_weight``.
    soft_weight : float > 0

    Raises
    ------
    InputError
        Naming the field: a shape that does not match n or m (a DimensionError), ``u_min > u_max``, zero input
        outside the bounds, a negative ``du_max``, ``x_min > x_max`` (``terminal_min > terminal_max``), ``eps``
        outside (0, 1), a non-finite ``a``, ``b``, ``F`` (``terminal_F``) or a NaN ``g``, a weight that is not
        positive.

    Examples
    --------
    >>> c = Constraints(u_min=[-1, -2], u_max=[1, 2], chance=[([1.0], 3.0, 0.1)])
    >>> c.u_max.tolist(), c.chance[0][2], c.kinds()
    ([1.0, 2.0], 0.1, ['u_min', 'u_max', 'chance'])
    >>> Constraints(u_min=[0.5])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: u_min: a lost packet applies zero input, ...; found u_min[0] = 0.5 > 0
    """

    u_min: np.ndarray | None = None
    u_max: np.ndarray | None = None
    du_max: np.ndarray | None = None
    x_min: np.ndarray | None = None
    x_max: np.ndarray | None = None
    F: np.ndarray | None = None
    g: np.ndarray | None = None
    terminal_min: np.ndarray | None = None
    terminal_max: np.ndarray | None = None
    terminal_F: np.ndarray | None = None
    terminal_g: np.ndarray | None = None
    chance: tuple[tuple[np.ndarray, float, float], ...] = field(default=())
    soft: bool = False
    soft_weight: float = SOFT_WEIGHT_DEFAULT

    def __post_init__(self) -> None:
        put = object.__setattr__
        for names in (("u_min", "u_max", "du_max"), *STATE_BOXES):
            size = None
            for name in names:
                vector = _vector(getattr(self, name), size, name)
                put(self, name, vector)
                size = size if vector is None else vector.size
        for low, high in STATE_BOXES:
            lower, upper = getattr(self, low), getattr(self, high)
            if lower is not None and np.any(lower == np.inf) or upper is not None and np.any(upper == -np.inf):
                raise InputError(low if lower is not None and np.any(lower == np.inf) else high,
                                 "a bound of inf from below (or -inf from above) admits no state")
        if self.u_min is not None and np.any(self.u_min > 0):
            i = int(np.argmax(self.u_min > 0))
            raise InputError("u_min", "a lost packet applies zero input, which must lie inside the bounds; found "
                                      f"u_min[{i}] = {self.u_min[i]:g} > 0")
        if self.u_max is not None and np.any(self.u_max < 0):
            i = int(np.argmax(self.u_max < 0))
            raise InputError("u_max", "a lost packet applies zero input, which must lie inside the bounds; found "
                                      f"u_max[{i}] = {self.u_max[i]:g} < 0")
        if self.u_min is not None and self.u_max is not None and np.any(self.u_min > self.u_max):
            i = int(np.argmax(self.u_min > self.u_max))   # (unreachable past the zero checks; kept for the message)
            raise InputError("u_min", f"u_min[{i}] = {self.u_min[i]:g} exceeds u_max[{i}] = {self.u_max[i]:g}")
        if self.du_max is not None and np.any(self.du_max < 0):
            i = int(np.argmax(self.du_max < 0))
            raise InputError("du_max", f"expected rate bounds >= 0, found du_max[{i}] = {self.du_max[i]:g}")
        for low, high in STATE_BOXES:
            lower, upper = getattr(self, low), getattr(self, high)
            if lower is not None and upper is not None and np.any(lower > upper):
                i = int(np.argmax(lower > upper))
                raise InputError(low, f"{low}[{i}] = {lower[i]:g} exceeds {high}[{i}] = {upper[i]:g}")
        for names in POLYHEDRA:
            self._polyhedron(*names)
        put(self, "chance", self._chance_rows())
        if not isinstance(self.soft, bool | np.bool_):
            raise InputError("soft", f"expected true or false, found {self.soft!r}")
        put(self, "soft", bool(self.soft))
        weight = self.soft_weight
        if isinstance(weight, bool) or not isinstance(weight, int | float | np.floating | np.integer) \
                or not (np.isfinite(weight) and weight > 0):
            raise InputError("soft_weight", f"expected a finite number > 0, found {weight!r}")
        put(self, "soft_weight", float(weight))

    def _polyhedron(self, f: str, h: str) -> None:
        """The polyhedron held in the fields ``f`` (r x n) and ``h`` (r), checked and frozen."""
        F, g = getattr(self, f), getattr(self, h)
        if (F is None) != (g is None):
            on = "E[x_N]" if f.startswith("terminal") else "E[x_k]"
            raise InputError(f if F is None else h, f"{f} and {h} come together ({f} {on} <= {h})")
        if F is None:
            return
        try:
            F, g = np.atleast_2d(np.asarray(F, dtype=float)), np.asarray(g, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f, f"expected a matrix of numbers and {h} a vector of numbers") from None
        if F.ndim != 2 or F.shape[0] < 1:
            raise DimensionError(f, f"expected a matrix of r rows but found shape {F.shape}")
        if g.shape != (F.shape[0],):
            raise DimensionError(h, f"expected {F.shape[0]} numbers (one per row of {f}) but found shape {g.shape}")
        if not np.all(np.isfinite(F)):
            raise InputError(f, "expected finite numbers")
        if np.any(np.isnan(g)) or np.any(g == -np.inf):
            raise InputError(h, "expected numbers (inf leaves a row out; -inf or NaN is not a limit)")
        F.setflags(write=False)
        g.setflags(write=False)
        object.__setattr__(self, f, F)
        object.__setattr__(self, h, g)

    def _chance_rows(self) -> tuple[tuple[np.ndarray, float, float], ...]:
        rows = []
        try:
            given = list(self.chance or ())
        except TypeError:
            raise InputError("chance", f"expected rows (a, b, eps), found {self.chance!r}"[:200]) from None
        for i, row in enumerate(given):
            where = f"chance[{i}]"
            try:
                a, b, eps = row
            except (TypeError, ValueError):
                raise InputError(where, f"expected a row (a, b, eps), found {row!r}"[:200]) from None
            a = _vector(a, None if not rows else rows[0][0].size, f"{where}.a")
            if not np.all(np.isfinite(a)) or not np.any(a != 0):
                raise InputError(f"{where}.a", "expected finite numbers, not all zero")
            try:
                b, eps = float(b), float(eps)
            except (TypeError, ValueError):
                raise InputError(where, f"expected numbers b and eps, found {row!r}"[:200]) from None
            if not np.isfinite(b):
                raise InputError(f"{where}.b", f"expected a finite number, found {b!r}")
            if not 0.0 < eps < 1.0:
                raise InputError(f"{where}.eps", f"expected a probability in (0, 1), found {eps!r}")
            rows.append((a, b, eps))
        return tuple(rows)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Constraints) and self.to_dict() == other.to_dict()

    __hash__ = None

    def sizes(self) -> tuple[int | None, int | None]:
        """``(n, m)`` as the fields imply them (None where no field does)."""
        m = next((v.size for v in (self.u_min, self.u_max, self.du_max) if v is not None), None)
        n = next((v.size for v in (self.x_min, self.x_max, self.terminal_min, self.terminal_max) if v is not None),
                 None)
        n = n if n is not None or self.F is None else self.F.shape[1]
        n = n if n is not None or self.terminal_F is None else self.terminal_F.shape[1]
        return (n if n is not None or not self.chance else self.chance[0][0].size), m

    def kinds(self) -> list[str]:
        """The fields that constrain anything, in `KEYS` order (``F``, ``terminal_F`` for the polyhedra)."""
        out = [name for name in ("u_min", "u_max", "du_max", "x_min", "x_max", "F", "terminal_min", "terminal_max",
                                 "terminal_F") if getattr(self, name) is not None]
        return out + (["chance"] if self.chance else [])

    def loop_rows(self) -> int:
        """The rows a sampled loop checks at each step (montecarlo/mpc.py): each finite input, rate and state bound,
        each finite row of ``g``, each chance row (the terminal set constrains the prediction only). O(n + m + r).

        Examples
        --------
        >>> Constraints(u_min=[-1, -1], u_max=[1, np.inf], chance=[([1.0], 2.0, 0.1)]).loop_rows()
        4
        """
        bounds = (self.u_max, self.u_min, self.du_max, self.x_max, self.x_min, self.g)
        return sum(int(np.isfinite(v).sum()) for v in bounds if v is not None) + len(self.chance)

    def program_rows(self, horizon: int) -> int:
        """The linear rows of the program over ``horizon`` steps (qp/constrained.py): each finite input and state
        bound and row of ``g`` at every step, both directions of each finite rate bound at every step (the first
        against the previous command), the terminal set's once; chance rows are cones, counted apart. O(n + m + r).

        Examples
        --------
        >>> Constraints(u_min=[-1], u_max=[1], du_max=[0.5], terminal_max=[0.1]).program_rows(10)
        41
        """
        def finite(values: np.ndarray | None) -> int:
            return 0 if values is None else int(np.isfinite(values).sum())
        steps = sum(finite(v) for v in (self.u_max, self.u_min, self.x_max, self.x_min, self.g)) + 2 * finite(
            self.du_max)
        once = sum(finite(v) for v in (self.terminal_max, self.terminal_min, self.terminal_g))
        return int(horizon) * steps + once

    def to_dict(self) -> dict[str, Any]:
        """The ``[constraints]`` table (JSON and TOML values; infinite entries as floats). O(size)."""
        out: dict[str, Any] = {}
        for name in ("u_min", "u_max", "du_max", "x_min", "x_max", "F", "g", "terminal_min", "terminal_max",
                     "terminal_F", "terminal_g"):
            value = getattr(self, name)
            if value is not None:
                out[name] = value.tolist()
        if self.chance:
            out["chance"] = [[a.tolist(), b, eps] for a, b, eps in self.chance]
        if self.soft:
            out["soft"] = True
        if self.soft_weight != SOFT_WEIGHT_DEFAULT:
            out["soft_weight"] = self.soft_weight
        return out


def constraints_from_dict(table: Mapping[str, Any], n: int, m: int, prefix: str = "constraints.") -> Constraints:
    """A `Constraints` from the ``[constraints]`` table (docs/design.md §4), errors naming ``constraints.<key>``.

    Examples
    --------
    >>> c = constraints_from_dict({"u_max": [1.0], "u_min": [-1.0], "chance": [[[1.0, 0.0], 2.0, 0.05]]}, 2, 1)
    >>> c.kinds(), constraints_from_dict(c.to_dict(), 2, 1) == c
    (['u_min', 'u_max', 'chance'], True)
    >>> constraints_from_dict({"chance": [[[1.0, 0.0], 2.0, 1.5]]}, 2, 1)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: constraints.chance[0].eps: expected a probability in (0, 1), found 1.5
    """
    if not isinstance(table, Mapping):
        raise InputError(prefix.rstrip("."), f"expected a table, found {type(table).__name__}")
    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        raise InputError(prefix + unknown[0], f"unknown key; expected one of {', '.join(KEYS)}")
    try:
        return check_constraints(Constraints(**dict(table)), n, m)
    except InputError as err:
        raise err.renamed(prefix + err.field) from None


def check_constraints(constraints: Any, n: int, m: int) -> Constraints:
    """``constraints`` for a system of n states and m inputs: a `Constraints` of that size, or a mapping read
    as the ``[constraints]`` table.

    Examples
    --------
    >>> check_constraints({"u_max": [1.0]}, 1, 1).u_max.tolist()
    [1.0]
    >>> check_constraints(Constraints(x_max=[1.0, 2.0]), 1, 1)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.DimensionError: x_max: expected 1 numbers (n = 1) but found 2
    """
    if isinstance(constraints, Mapping):
        return constraints_from_dict(constraints, n, m, prefix="")
    if not isinstance(constraints, Constraints):
        raise InputError("constraints", f"expected a Constraints, found {type(constraints).__name__}")
    c = constraints
    for name in ("u_min", "u_max", "du_max", "x_min", "x_max", "terminal_min", "terminal_max"):
        letter = "m" if name[0] in "ud" else "n"
        value, size = getattr(c, name), (m if letter == "m" else n)
        if value is not None and value.size != size:
            raise DimensionError(name, f"expected {size} numbers ({letter} = {size}) but found {value.size}")
    for name, _ in POLYHEDRA:
        F = getattr(c, name)
        if F is not None and F.shape[1] != n:
            raise DimensionError(name, f"expected shape (r, {n}) but found {F.shape}")
    for i, (a, _, _) in enumerate(c.chance):
        if a.size != n:
            raise DimensionError(f"chance[{i}].a", f"expected {n} numbers but found {a.size}")
    return c
