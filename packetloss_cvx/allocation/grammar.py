"""The allocation problem's inputs: the constraint grammar, the argument checks and the
constraint set they define.

``parse_constraint`` reads ``"mu1 + 2*mu2 <= 1.5"`` into rows ``(G, h)`` of ``G mu <= h``
without ``eval``; `read_polytope` turns the ``constraints`` argument of
[`allocate`][packetloss_cvx.allocation.api.allocate] (pairs ``(G, h)`` or callables returning affine
cvxpy constraints) and the bounds into one [`Polytope`][packetloss_cvx.allocation.grammar.Polytope], every row scaled to
unit largest coefficient; the ``check_*`` functions validate the scalar arguments. Every error is
an [`InputError`][packetloss_cvx.errors.InputError] naming its field.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import cvxpy as cp
import numpy as np

from ..budgets import check, constraint_bytes, count_text, gib_text
from ..errors import InfeasibleError, InputError
from ..model.system import System, numeric_array
from ..tolerances import ALLOCATION_GAP_MIN

__all__ = [
    "Constraint", "Polytope", "check_alpha", "check_beta", "check_bounds", "check_count", "check_gap",
    "check_number", "check_system", "infeasible_row_text", "parse_constraint", "read_polytope",
]

Constraint = Callable[[cp.Variable], Any] | tuple[Any, Any]

#: A channel index has at most this many digits (mu1 .. mu999999).
_MAX_INDEX_DIGITS = 6
#: the variables a constraint may name: mu1.. (delivery probabilities) or P1.. (transmit powers, allocation/power.py)
_TERMS = {name: re.compile(r"\s*([+-]?)\s*(?:(\d+(?:\.\d*)?(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)\s*\*?\s*)?"
                           rf"({name}(\d{{1,{_MAX_INDEX_DIGITS}}})(?!\d))?\s*") for name in ("mu", "P")}


def _numbers(value: Any, field: str) -> np.ndarray:
    """`numeric_array`, with integers too large for a float and
    absurdly deep nesting reported as InputError too."""
    try:
        return numeric_array(value, field)
    except OverflowError:
        raise InputError(field, "expected numbers that fit a float (|x| < 1.8e308)") from None
    except RecursionError:
        raise InputError(field, "expected a flat list of numbers, found a deeply nested one") from None


def _side(text: str, m: int, field: str, name: str = "mu") -> tuple[np.ndarray, float]:
    """Parse a sum of terms ``[+-] [c [*]] mu<k>`` or ``[+-] c``: returns (coefficients, constant).
    O(len(text))."""
    coef, const, pos = np.zeros(m), 0.0, 0
    text = text.strip()
    if not text:
        raise InputError(field, "expected an expression on both sides")
    while pos < len(text):
        match = _TERMS[name].match(text, pos)
        if match is None or match.end() == pos or (match.group(2) is None and match.group(3) is None):
            raise InputError(field, f"cannot parse {text[pos:pos + 40]!r}; expected terms like '2*{name}1', '{name}2' "
                             f"or '0.5' (channel numbers up to {_MAX_INDEX_DIGITS} digits)")
        sign = -1.0 if match.group(1) == "-" else 1.0
        if pos > 0 and not match.group(1):
            raise InputError(field, f"expected '+' or '-' before {text[pos:pos + 40].strip()!r}")
        value = sign * (float(match.group(2)) if match.group(2) else 1.0)
        if not np.isfinite(value):
            raise InputError(field, f"the number {match.group(2)[:40]!r} does not fit a float (|x| < 1.8e308)")
        if match.group(3):
            k = int(match.group(4))
            if not 1 <= k <= m:
                raise InputError(field, f"unknown channel {match.group(3)!r}; expected {name}1..{name}{m}")
            coef[k - 1] += value
        else:
            const += value
        pos = match.end()
    if not (np.all(np.isfinite(coef)) and np.isfinite(const)):
        raise InputError(field, "the terms add up to more than a float holds")
    return coef, const


def parse_constraint(text: str, m: int, field: str = "constraint", name: str = "mu") -> tuple[np.ndarray, np.ndarray]:
    """Parse ``"mu1 + 2*mu2 <= 1.5"``, ``"mu1 >= mu2"``, ``"mu2 == 0.8"`` into (G, h), G mu <= h
    (``name="P"``: the same in transmit powers, ``"P1 <= 2*P2"``).

    A small grammar, no ``eval``: linear terms in mu1..mu<m>, finite numbers, one of
    <=, >=, == (< and > are read as <= and >=). O(len(text) + m).

    Raises
    ------
    InputError
        Anything else, under ``field`` (the command line passes ``"--constraint"``); ``m`` not a positive
        integer, under ``m``.
    BudgetError
        ``m`` whose dense rows (five arrays of m doubles while parsing) exceed the ``memory_bytes`` budget, under
        ``m``, before any is allocated.

    Examples
    --------
    >>> G, h = parse_constraint("mu1 + 2*mu2 <= 1.5", 2)
    >>> G.tolist(), h.tolist()
    ([[1.0, 2.0]], [1.5])
    >>> parse_constraint("P1 <= 2*P2", 2, name="P")[0].tolist()
    [[1.0, -2.0]]
    """
    m = check_count(m, "m")
    check("memory_bytes", constraint_bytes(m), "m", f"{count_text(m)} channels (dense rows of m coefficients, "
                                                    f"about {gib_text(constraint_bytes(m))})")
    if not isinstance(text, str):
        raise InputError(field, f"expected a string, found {type(text).__name__}")
    parts = re.split(r"(<=|>=|==|<|>|=)", text)
    if len(parts) != 3:
        raise InputError(field, f"expected one comparison (<=, >= or ==) in {text[:80]!r}")
    left, op, right = parts
    if name not in _TERMS:
        raise InputError("name", f"expected one of {', '.join(_TERMS)}, found {name!r}")
    a, c1 = _side(left, m, field, name)
    b, c2 = _side(right, m, field, name)
    row, rhs = a - b, c2 - c1          # row mu  op  rhs
    if not (np.all(np.isfinite(row)) and np.isfinite(rhs)):
        raise InputError(field, "the two sides differ by more than a float holds")
    if not np.any(row):
        raise InputError(field, f"{text[:80]!r} does not involve any channel")
    if op in ("<=", "<"):
        return row[None, :], np.array([rhs])
    if op in (">=", ">"):
        return -row[None, :], np.array([-rhs])
    return np.vstack([row, -row]), np.array([rhs, -rhs])


def infeasible_row_text(g: np.ndarray, c: float, least: float, name: str = "mu") -> str:
    """The row ``g mu <= c`` in the signs a user writes it (the first coefficient positive: ``mu1 + mu2 >= 2.5``,
    not ``-mu1 - mu2 <= -2.5``) with the value it cannot reach over the bounds (``least``: the least of g mu).
    O(m).

    Examples
    --------
    >>> infeasible_row_text(np.array([-1.0, -1.0]), -2.5, -2.0)
    'mu1 + mu2 >= 2.5 (largest value 2 < 2.5)'
    >>> infeasible_row_text(np.array([1.0, 1.0]), 1.0, 1.2)
    'mu1 + mu2 <= 1 (least value 1.2 > 1)'
    """
    sign = -1.0 if g[np.flatnonzero(g)[0]] < 0 else 1.0
    terms = []
    for i, a in enumerate(sign * g):
        if a == 0:
            continue
        size = "" if abs(a) == 1 else f"{abs(a):.6g}*"
        terms.append(("-" if a < 0 else "+") + f" {size}{name}{i + 1}")
    text = " ".join(terms)
    text = text[2:] if text.startswith("+ ") else "-" + text[2:]
    if sign > 0:
        return f"{text} <= {c:.6g} (least value {least:.6g} > {c:.6g})"
    return f"{text} >= {-c:.6g} (largest value {-least:.6g} < {-c:.6g})"


def _box_text(lo: float, hi: float, name: str, units: np.ndarray) -> str:
    """The box in the user's units: ``the bounds [0, 1]``, or each channel's range where they differ."""
    low, high = lo * units, hi * units
    if np.all(low == low[0]) and np.all(high == high[0]):
        return f"the bounds [{low[0]:g}, {high[0]:g}]"
    return "the box " + " x ".join(f"[{a:g}, {b:g}]" for a, b in zip(low, high, strict=True))


# ------------------------------------------------------------------ scalar arguments

def check_system(system: Any) -> System:
    """A [`System`][packetloss_cvx.model.system.System] with a stationary channel. O(1).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> check_system(s) is s
    True
    >>> check_system(s.with_mu([[0.2], [0.4]]))
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: system: allocation needs a stationary channel (mu, not mu_schedule)
    """
    if not isinstance(system, System):
        raise InputError("system", f"expected a System, found {type(system).__name__}")
    if not system.is_stationary:
        raise InputError("system", "allocation needs a stationary channel (mu, not mu_schedule)")
    return system


def check_number(value: Any, field: str) -> float:
    """One finite real number (no strings, booleans, NaN, inf). O(1).

    Examples
    --------
    >>> check_number(np.float32(0.5), "alpha"), check_number(3, "budget")
    (0.5, 3.0)
    >>> check_number([1.0, 2.0], "budget")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: budget: expected one number, found an array of shape (2,)
    """
    arr = _numbers(value, field)
    if arr.shape != ():
        raise InputError(field, f"expected one number, found an array of shape {arr.shape}")
    return float(arr)


def check_alpha(alpha: Any) -> float:
    """The cost bound: a positive finite number. O(1).

    Examples
    --------
    >>> check_alpha(1.5)
    1.5
    >>> check_alpha(0)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: alpha: expected a positive finite number, found 0.0
    """
    alpha = check_number(alpha, "alpha")
    if alpha <= 0:
        raise InputError("alpha", f"expected a positive finite number, found {alpha}")
    return alpha


def check_beta(beta: Any, m: int, field: str = "beta") -> np.ndarray:
    """The channel prices: m finite non-negative numbers. O(m).

    Examples
    --------
    >>> check_beta([1, 0.05], 2).tolist()
    [1.0, 0.05]
    >>> check_beta([1.0], 2)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: beta: expected 2 non-negative numbers, one per channel, found shape (1,)
    """
    arr = _numbers(beta, field)
    if arr.shape != (m,):
        raise InputError(field, f"expected {m} non-negative numbers, one per channel, found shape {arr.shape}")
    if np.any(arr < 0):
        raise InputError(field, f"expected finite non-negative numbers, found {arr.tolist()}"[:200])
    return arr


def check_bounds(bounds: Any) -> tuple[float, float]:
    """The box for every mu_i: (lo, hi) with 0 <= lo <= hi <= 1. O(1).

    Examples
    --------
    >>> check_bounds([0, 1])
    (0.0, 1.0)
    >>> check_bounds((0.6, 0.4))
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: bounds: expected 0 <= lo <= hi <= 1, found (0.6, 0.4)
    """
    arr = _numbers(bounds, "bounds")
    if arr.shape != (2,):
        raise InputError("bounds", f"expected (lo, hi), found shape {arr.shape}")
    lo, hi = float(arr[0]), float(arr[1])
    if not 0.0 <= lo <= hi <= 1.0:
        raise InputError("bounds", f"expected 0 <= lo <= hi <= 1, found ({lo}, {hi})")
    return lo, hi


def check_gap(gap: Any) -> float:
    """The relative optimality gap to certify: ALLOCATION_GAP_MIN <= gap < 1. O(1).

    Examples
    --------
    >>> check_gap(0.01)
    0.01
    >>> try:
    ...     check_gap(1)                               # a gap of 100 % certifies nothing
    ... except InputError as err:
    ...     err.field
    'gap'
    """
    gap = check_number(gap, "gap")
    if not ALLOCATION_GAP_MIN <= gap < 1:
        raise InputError("gap", f"expected a number in [{ALLOCATION_GAP_MIN:g}, 1), found {gap:g}")
    return gap


def check_count(value: Any, field: str) -> int:
    """A positive integer (a cap on boxes or iterations). O(1).

    Examples
    --------
    >>> check_count(np.int64(20), "max_boxes")
    20
    >>> check_count(True, "max_boxes")                  # a bool is not a count
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: max_boxes: expected a positive integer, found True
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InputError(field, f"expected a positive integer, found {value!r}")
    return int(value)


# ------------------------------------------------------------------ the constraint set

@dataclass(frozen=True)
class Polytope:
    """The feasible set of mu: ``lo <= mu_i <= hi`` and ``G mu <= h``.

    Rows are scaled so that max |G_k| = 1, and rows that no point of the box can violate are
    dropped, so no extreme number reaches a solver. Built by `read_polytope`.

    Examples
    --------
    >>> box = read_polytope([], 2, 0.1, 0.9)              # the bounds alone: no rows
    >>> box.m, box.G.shape, box.lower().tolist(), box.upper().tolist()
    (2, (0, 2), [0.1, 0.1], [0.9, 0.9])
    """

    lo: float
    hi: float
    G: np.ndarray
    h: np.ndarray

    @property
    def m(self) -> int:
        """The number of channels."""
        return self.G.shape[1]

    def lower(self) -> np.ndarray:
        """The box's lower corner (lo, ..., lo). O(m)."""
        return np.full(self.m, self.lo)

    def upper(self) -> np.ndarray:
        """The box's upper corner (hi, ..., hi). O(m)."""
        return np.full(self.m, self.hi)


def _affine_rows(fn: Callable, m: int, field: str) -> tuple[np.ndarray, np.ndarray]:
    """Read a callable's affine cvxpy constraints on mu into rows (G, h): O(m r)."""
    mu = cp.Variable(m, name="mu")
    try:
        out = fn(mu)
    except Exception as err:  # noqa: BLE001 - the user's code: report it as their input
        raise InputError(field, f"the callable raised {type(err).__name__}: {err}") from None
    out = list(out) if isinstance(out, (list, tuple)) else [out]
    G, h = [], []
    for c in out:
        if not isinstance(c, (cp.constraints.Inequality, cp.constraints.Equality)):
            raise InputError(field, "a callable must return cvxpy comparisons (<=, >=, ==) on mu")
        if not c.expr.is_affine() or any(v is not mu for v in c.variables()):
            raise InputError(field, "a callable's constraints must be affine in mu alone "
                             "(pass (G, h) pairs for anything else)")
        if any(p.value is None for p in c.parameters()):
            raise InputError(field, "a callable's constraint has a cvxpy Parameter without a value")
        mu.value = np.zeros(m)
        b0 = np.atleast_1d(np.asarray(c.expr.value, dtype=float)).ravel(order="F")
        grad = c.expr.grad[mu]
        rows = np.atleast_2d(grad.toarray() if hasattr(grad, "toarray") else np.asarray(grad)).T
        pairs = [(rows, -b0)] if isinstance(c, cp.constraints.Inequality) else [(rows, -b0), (-rows, b0)]
        for Gk, hk in pairs:
            G.append(Gk)
            h.append(hk)
    if not G:
        return np.zeros((0, m)), np.zeros(0)
    return np.vstack(G), np.concatenate(h)


def read_polytope(constraints: Sequence[Constraint], m: int, lo: float, hi: float, *, name: str = "mu",
                  scale: np.ndarray | None = None) -> Polytope:
    """The bounds and ``constraints`` as one [`Polytope`][packetloss_cvx.allocation.grammar.Polytope].

    Parameters
    ----------
    constraints : sequence
        Pairs ``(G, h)`` meaning ``G mu <= h`` (finite numbers), or callables ``f(mu)``
        returning affine cvxpy constraints on the variable ``mu`` (read into rows once, by
        cvxpy's exact coefficients).
    m : int
    lo, hi : float
        The box, already checked.
    name, scale : str, array, optional
        How an infeasible row is written for its reader: in the variable ``name`` (``"P"`` for powers), whose
        value is ``scale`` times the rows' variable (power rows are read on x = P / cap), so the row and the
        box are given back in the user's units.

    Raises
    ------
    InputError
        A malformed constraint, named ``constraints[k]``.
    InfeasibleError
        A row that no point of the box satisfies (its least value over the box exceeds h):
        proven infeasible without a solver.

    Notes
    -----
    O(r m) for r rows.

    Examples
    --------
    Rows are scaled to unit largest coefficient; a row no point of the box violates is dropped.

    >>> poly = read_polytope([([[2.0, 4.0]], [3.0]), ([[1.0, 1.0]], [5.0])], 2, 0.0, 1.0)
    >>> poly.G.tolist(), poly.h.tolist(), poly.upper().tolist()
    ([[0.5, 1.0]], [0.75], [1.0, 1.0])
    >>> read_polytope([lambda mu: mu[0] >= mu[1]], 2, 0.0, 1.0).G.tolist()     # mu2 - mu1 <= 0
    [[-1.0, 1.0]]
    """
    if isinstance(constraints, (str, bytes)) or not isinstance(constraints, Sequence):
        raise InputError("constraints", "expected a list of (G, h) pairs or callables")
    units = np.ones(m) if scale is None else np.asarray(scale, dtype=float)
    rows, rhs = [np.zeros((0, m))], [np.zeros(0)]
    for k, item in enumerate(constraints):
        field = f"constraints[{k}]"
        if callable(item):
            Gk, hk = _affine_rows(item, m, field)
        else:
            if not isinstance(item, (tuple, list)) or len(item) != 2:
                raise InputError(field, "expected a callable or a pair (G, h) meaning G mu <= h")
            Gk = np.atleast_2d(_numbers(item[0], field))
            hk = np.atleast_1d(_numbers(item[1], field))
            if Gk.ndim != 2 or hk.ndim != 1 or Gk.shape[1] != m or Gk.shape[0] != hk.shape[0]:
                raise InputError(field, f"expected G of shape (r, {m}) and h of shape (r,), "
                                 f"found {Gk.shape} and {hk.shape}")
        if not (np.all(np.isfinite(Gk)) and np.all(np.isfinite(hk))):
            raise InputError(field, "expected finite coefficients")
        for g, c in zip(Gk, hk, strict=True):
            scale = np.max(np.abs(g))
            if scale == 0:                        # 0 <= c: always true or never
                if c < 0:
                    raise InfeasibleError(f"{field}: 0 <= {c:g} is false for every mu", None)
                continue
            g, c = g / scale, c / scale
            least = float(np.sum(np.minimum(g * lo, g * hi)))
            most = float(np.sum(np.maximum(g * lo, g * hi)))
            if c >= most:                         # no point of the box violates it
                continue
            if c < least:
                raise InfeasibleError(f"{field}: no {name} in {_box_text(lo, hi, name, units)} satisfies "
                                      f"{infeasible_row_text(g * scale / units, c * scale, least * scale, name)}",
                                      None)
            rows.append(g[None, :])
            rhs.append(np.array([c]))
    G, h = np.vstack(rows), np.concatenate(rhs)
    if len(h) > 1 and _proved_empty(G, h, lo, hi):
        raise InfeasibleError(f"constraints: no mu in the bounds [{lo:g}, {hi:g}] satisfies them together (a "
                              "contradiction proved in exact rational arithmetic, however small)", None)
    G.setflags(write=False)
    h.setflags(write=False)
    return Polytope(lo=lo, hi=hi, G=G, h=h)


#: Fourier–Motzkin elimination in exact arithmetic gives up beyond this many rows (the count can square at each
#: eliminated channel); the set is then left to the solvers, whose rows hold to ALLOCATION_LP_FEASIBILITY.
EXACT_EMPTINESS_MAX_ROWS = 4096


def _proved_empty(G: np.ndarray, h: np.ndarray, lo: float, hi: float) -> bool:
    """True when no mu in [lo, hi]^m satisfies G mu <= h, proved by Fourier–Motzkin elimination over the
    rationals (every float is an exact rational; the rows as the solvers see them, each scaled to unit largest
    coefficient): a contradiction inside the solvers' feasibility tolerance
    (rows apart by 1e-12) is found as surely as a large one. False when the set is not empty, or when the
    elimination would exceed EXACT_EMPTINESS_MAX_ROWS (not proved). Time O(m R^2) for R rows at the largest.

    Examples
    --------
    >>> G = np.array([[-1.0, -1.0], [1.0, 1.0]])            # mu1 + mu2 >= 1.5 and mu1 + mu2 <= 1.5 - 1e-12
    >>> _proved_empty(G, np.array([-1.5, 1.5 - 1e-12]), 0.0, 1.0), _proved_empty(G, np.array([-1.5, 1.5]), 0.0, 1.0)
    (True, False)
    """
    m = G.shape[1]
    rows = [([Fraction(float(x)) for x in g], Fraction(float(c))) for g, c in zip(G, h, strict=True)]
    for j in range(m):                                   # the box as rows: mu_j <= hi, -mu_j <= -lo
        unit = [Fraction(int(k == j)) for k in range(m)]
        rows.append((unit, Fraction(float(hi))))
        rows.append(([-u for u in unit], -Fraction(float(lo))))
    for j in range(m):
        pos = [(a, b) for a, b in rows if a[j] > 0]
        neg = [(a, b) for a, b in rows if a[j] < 0]
        kept = {(tuple(a), b) for a, b in rows if a[j] == 0}
        if len(kept) + len(pos) * len(neg) > EXACT_EMPTINESS_MAX_ROWS:
            return False
        for ap, bp in pos:
            for an, bn in neg:
                sp, sn = ap[j], -an[j]                  # sn * (row p) + sp * (row n) eliminates mu_j
                a = tuple(sn * x + sp * y for x, y in zip(ap, an, strict=True))
                kept.add((a, sn * bp + sp * bn))
        rows = [(list(a), b) for a, b in kept]
        if any(all(x == 0 for x in a) and b < 0 for a, b in rows):
            return True
    return any(b < 0 for _, b in rows)
