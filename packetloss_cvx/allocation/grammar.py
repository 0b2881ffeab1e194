"""The allocation problem's inputs: the constraint grammar and the argument checks.

``parse_constraint`` reads ``"mu1 + 2*mu2 <= 1.5"`` into rows ``(G, h)`` of ``G mu <= h``
without ``eval``; ``check_inputs`` and ``polytope`` validate the arguments of
:func:`~packetloss_cvx.allocation.allocate`; ``base_constraints`` states the bounds and
constraints on a cvxpy variable.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Any

import cvxpy as cp
import numpy as np

from ..errors import InputError
from ..model import System

__all__ = ["Constraint", "base_constraints", "check_inputs", "parse_constraint", "polytope"]

Constraint = Callable[[cp.Variable], Any] | tuple[Any, Any]


_TERM = re.compile(r"\s*([+-]?)\s*(?:(\d+(?:\.\d*)?(?:[eE][+-]?\d+)?|\.\d+)\s*\*?\s*)?(mu(\d+))?\s*")


def _side(text: str, m: int, field: str) -> tuple[np.ndarray, float]:
    """Parse a sum of terms ``[+-] [c [*]] mu<k>`` or ``[+-] c``: returns (coefficients, constant)."""
    coef, const, pos = np.zeros(m), 0.0, 0
    text = text.strip()
    if not text:
        raise InputError(field, "expected an expression on both sides")
    while pos < len(text):
        match = _TERM.match(text, pos)
        if match is None or match.end() == pos or (match.group(2) is None and match.group(3) is None):
            raise InputError(field, f"cannot parse {text[pos:]!r}; expected terms like '2*mu1', 'mu2' or '0.5'")
        sign = -1.0 if match.group(1) == "-" else 1.0
        if pos > 0 and not match.group(1):
            raise InputError(field, f"expected '+' or '-' before {text[pos:].strip()!r}")
        value = sign * (float(match.group(2)) if match.group(2) else 1.0)
        if match.group(3):
            k = int(match.group(4))
            if not 1 <= k <= m:
                raise InputError(field, f"unknown channel {match.group(3)!r}; expected mu1..mu{m}")
            coef[k - 1] += value
        else:
            const += value
        pos = match.end()
    return coef, const


def parse_constraint(text: str, m: int, field: str = "--constraint") -> tuple[np.ndarray, np.ndarray]:
    """Parse ``"mu1 + 2*mu2 <= 1.5"``, ``"mu1 >= mu2"``, ``"mu2 == 0.8"`` into (G, h), G mu <= h.

    A small grammar, no ``eval``: linear terms in mu1..mu<m>, numbers, one of <=, >=, ==
    (< and > are read as <= and >=).
    """
    parts = re.split(r"(<=|>=|==|<|>|=)", text)
    if len(parts) != 3:
        raise InputError(field, f"expected one comparison (<=, >= or ==) in {text!r}")
    left, op, right = parts
    a, c1 = _side(left, m, field)
    b, c2 = _side(right, m, field)
    row, rhs = a - b, c2 - c1          # row mu  op  rhs
    if not np.any(row):
        raise InputError(field, f"{text!r} does not involve any channel")
    if op in ("<=", "<"):
        return row[None, :], np.array([rhs])
    if op in (">=", ">"):
        return -row[None, :], np.array([-rhs])
    return np.vstack([row, -row]), np.array([rhs, -rhs])


def check_inputs(system: System, alpha: float, beta, bounds) -> tuple[float, np.ndarray, float, float]:
    if not system.is_stationary:
        raise InputError("system", "allocation needs a stationary channel (mu, not mu_schedule)")
    try:
        alpha = float(alpha)
    except (TypeError, ValueError):
        raise InputError("alpha", f"expected a number, found {alpha!r}") from None
    if not np.isfinite(alpha) or alpha <= 0:
        raise InputError("alpha", f"expected a positive finite number, found {alpha}")
    beta_ = np.asarray(beta, dtype=float) if not isinstance(beta, str) else None
    if beta_ is None or beta_.shape != (system.m,):
        raise InputError("beta", f"expected {system.m} non-negative numbers, one per channel")
    if not np.all(np.isfinite(beta_)) or np.any(beta_ < 0):
        raise InputError("beta", "expected finite non-negative numbers")
    try:
        lo, hi = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise InputError("bounds", f"expected (lo, hi), found {bounds!r}") from None
    if not 0.0 <= lo <= hi <= 1.0:
        raise InputError("bounds", f"expected 0 <= lo <= hi <= 1, found ({lo}, {hi})")
    return alpha, beta_, lo, hi


def polytope(constraints: Sequence[Constraint], m: int) -> tuple[np.ndarray, np.ndarray, list[Callable]]:
    G, h, calls = np.zeros((0, m)), np.zeros(0), []
    for k, item in enumerate(constraints):
        if callable(item):
            calls.append(item)
            continue
        try:
            Gk, hk = item
            Gk = np.atleast_2d(np.asarray(Gk, dtype=float))
            hk = np.atleast_1d(np.asarray(hk, dtype=float))
        except (TypeError, ValueError):
            raise InputError(f"constraints[{k}]", "expected a callable or a pair (G, h) meaning G mu <= h") from None
        if Gk.shape[1] != m or Gk.shape[0] != hk.shape[0]:
            raise InputError(f"constraints[{k}]", f"expected G of shape (r, {m}) and h of shape (r,)")
        G, h = np.vstack([G, Gk]), np.concatenate([h, hk])
    return G, h, calls


def base_constraints(mu: cp.Variable, lo: float, hi: float, G: np.ndarray, h: np.ndarray,
                      calls: list[Callable]) -> list:
    cons = [mu >= lo, mu <= hi]
    if G.shape[0]:
        cons.append(G @ mu <= h)
    for k, fn in enumerate(calls):
        out = fn(mu)
        out = list(out) if isinstance(out, (list, tuple)) else [out]
        if not all(isinstance(c, cp.constraints.constraint.Constraint) for c in out):
            raise InputError(f"constraints[{k}]", "a callable must return cvxpy constraints on mu")
        cons += out
    return cons
