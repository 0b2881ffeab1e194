"""How the package's objects show themselves: a one-line ``repr`` with the headline numbers and a
small HTML table for notebooks (``_repr_html_``), never an array dump; and ``to_json``.

The model and the result types bind these as methods (``__repr__ = system_repr``), so this module
imports neither: it reads the attributes it shows. Each function is O(size of what it shows):
matrices are shown only up to :data:`MAX_SHOWN` rows and columns, larger ones by their shape.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "MAX_SHOWN", "allocation_html", "allocation_repr", "batch_repr", "claim_html", "claim_repr", "html_table",
    "fields_repr", "maximiser_repr", "short", "solution_html", "solution_repr", "system_html", "system_repr", "to_json",
]

#: matrices with more rows or columns than this are shown by their shape
MAX_SHOWN = 6


def short(value: Any, digits: int = 6) -> str:
    """A number in ``%.{digits}g``, a small array as a nested list of such numbers, a large one by its shape.

    >>> short(2.7984700883), short(np.array([0.9, 0.5])), short(np.zeros((8, 8))), short(None)
    ('2.79847', '[0.9, 0.5]', 'array of shape (8, 8)', 'None')
    """
    if value is None or isinstance(value, str):
        return str(value)
    arr = np.asarray(value)
    if arr.ndim == 0:
        return f"{complex(arr):.{digits}g}".strip("()") if np.iscomplexobj(arr) else f"{float(arr):.{digits}g}"
    if arr.ndim > 2 or max(arr.shape) > MAX_SHOWN:
        return f"array of shape {arr.shape}"
    return "[" + ", ".join(short(v, digits) for v in arr) + "]"


def fields_repr(obj: Any) -> str:
    """A dataclass's fields in one line: numbers to 6 digits, small arrays as lists, large ones by shape,
    mappings by key (the headline numbers, not an array dump).

    >>> from dataclasses import dataclass
    >>> @dataclass
    ... class Run:
    ...     law: str
    ...     cost: float
    ...     path: np.ndarray
    ...     curves: dict
    >>> fields_repr(Run("tcp", 2.7984700883, np.zeros(500), {"udp": np.array([1.0, 2.0])}))
    "Run(law='tcp', cost=2.79847, path=array of shape (500,), curves={'udp': [1, 2]})"
    """
    def one(value: Any) -> str:
        if isinstance(value, str):
            return repr(value)
        if isinstance(value, bool) or value is None:
            return str(value)
        if isinstance(value, dict):
            return "{" + ", ".join(f"{k!r}: {one(v)}" for k, v in value.items()) + "}"
        if isinstance(value, (int, float, complex, np.number, np.ndarray, list, tuple)):
            try:
                return short(value)
            except (TypeError, ValueError):
                return f"<{type(value).__name__}>"
        return f"<{type(value).__name__}>"

    names = getattr(obj, "__dataclass_fields__", vars(obj))
    return f"{type(obj).__name__}(" + ", ".join(f"{name}={one(getattr(obj, name))}" for name in names) + ")"


def to_json(obj: Any, **kwargs: Any) -> str:
    """``obj.to_dict()`` as JSON text (``kwargs`` go to :func:`json.dumps`, e.g. ``indent=2``).

    Raises ValueError on a non-finite number (strict JSON has none). O(size of the dict).

    >>> from packetloss_cvx.results import CrossCheck
    >>> CrossCheck("dense", 1e-9, 0.0).to_json()
    '{"max_input_diff": 1e-09, "cost_rel_diff": 0.0}'
    """
    return json.dumps(obj.to_dict(), allow_nan=False, **kwargs)


def html_table(title: str, rows: Sequence[tuple[str, Any]]) -> str:
    """A two-column HTML table under a bold title; every value escaped.

    >>> text = html_table("System", [("n", 2), ("name", "<b>x</b>")])
    >>> text.startswith("<table>"), "&lt;b&gt;x&lt;/b&gt;" in text, "<b>x</b>" in text
    (True, True, False)
    """
    cells = "".join(f'<tr><th style="text-align:left">{html.escape(str(label))}</th>'
                    f'<td style="text-align:left">{html.escape(str(value))}</td></tr>' for label, value in rows)
    return f'<table><caption style="text-align:left"><b>{html.escape(title)}</b></caption>{cells}</table>'


def channel_text(system: Any) -> str:
    """The delivery probabilities, or how many steps a non-stationary schedule has; a Gilbert-Elliott
    chain is named (its mu_t are only the plug-in prediction, the losses are correlated)."""
    sched = system.mu_schedule
    text = short(sched[0]) if np.all(sched == sched[0]) else f"non-stationary, {sched.shape[0]} steps (mu_schedule)"
    chain = getattr(system, "channel", None)
    return text if chain is None else f"{text}, channel={chain!r}"


def system_repr(system: Any) -> str:
    """``System('two-actuator', n=2, m=2, horizon=10, mu=[0.9, 0.5])``.

    >>> from packetloss_cvx import load_example
    >>> system_repr(load_example("pendulum"))
    "System('pendulum', n=4, m=1, horizon=80, mu=[0.9])"
    """
    label = f"{system.name!r}, " if system.name else ""
    return f"System({label}n={system.n}, m={system.m}, horizon={system.horizon}, mu={channel_text(system)})"


def system_html(system: Any) -> str:
    """The dimensions, channel, initial state and (when small) A and B, as an HTML table.

    >>> from packetloss_cvx.model import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0],
    ...            noise_cov=[[2.0]], name="a<b")
    >>> text = system_html(s)
    >>> "a&lt;b" in text, "a<b" in text, "Sigma_W, trace 2" in text, "1, 1, 2" in text   # escaped; n, m, N
    (True, False, True, True)
    """
    rows = [("name", system.name or "(unnamed)"), ("n, m, horizon N", f"{system.n}, {system.m}, {system.horizon}"),
            ("mu", channel_text(system)), ("x0", short(system.x0)), ("A", short(system.A)), ("B", short(system.B)),
            ("noise", "none" if not np.any(system.noise_cov) else f"Sigma_W, trace {np.trace(system.noise_cov):.4g}")]
    return html_table("System", rows)


def _solution_rows(sol: Any) -> list[tuple[str, Any]]:
    rows: list[tuple[str, Any]] = [("protocol", f"{sol.protocol.upper()}-like"), ("J*", f"{sol.cost:.10g}"),
                                   ("method", sol.method)]
    if sol.closed_loop_eigenvalues is not None and len(sol.closed_loop_eigenvalues):
        rows.append(("spectral radius of A - B K", f"{np.max(np.abs(sol.closed_loop_eigenvalues)):.6g}"))
    if sol.status is not None:
        rows.append(("status", f"{sol.status} in {sol.solve_time:.3g} s"))
    if sol.cross_check is not None:
        rows.append(("vs closed form", f"max|Vbar dU| {sol.cross_check.max_input_diff:.1e}, "
                                       f"rel dJ {sol.cross_check.cost_rel_diff:.1e}"))
    rows.append(("inputs U*", f"shape {sol.inputs.shape}"))
    if sol.gain is not None:
        rows.append(("gain K", short(sol.gain, 4)))
    return rows


def solution_repr(sol: Any) -> str:
    """``Solution(protocol='tcp', cost=2.798470088, method='dense', N=10, m=2)``.

    >>> from packetloss_cvx.results import Solution
    >>> Solution("udp", 10.25, np.zeros((10, 2)), None, None, "recursion")
    Solution(protocol='udp', cost=10.25, method='recursion', N=10, m=2)
    """
    status = f", status={sol.status!r}" if sol.status is not None else ""
    N, m = sol.inputs.shape
    return f"Solution(protocol={sol.protocol!r}, cost={sol.cost:.10g}, method={sol.method!r}{status}, N={N}, m={m})"


def solution_html(sol: Any) -> str:
    """The cost, method, closed-loop spectral radius and (QPs) solver status, as an HTML table.

    >>> from packetloss_cvx.results import Solution
    >>> text = solution_html(Solution("udp", 10.25, np.zeros((10, 2)), None, None, "recursion"))
    >>> "UDP-like" in text, "10.25" in text, "shape (10, 2)" in text, "status" in text   # no solver: no status
    (True, True, True, False)
    """
    return html_table("Solution", _solution_rows(sol))


def allocation_repr(a: Any) -> str:
    """``Allocation(protocol='udp', status='optimal', mu=[0.4856, 1], communication_cost=0.535637, cost=8,
    alpha=8, gap=5.9e-05)``.

    >>> from types import SimpleNamespace
    >>> print(allocation_repr(SimpleNamespace(protocol="udp", status="optimal", mu=np.array([0.485612, 1.0]),
    ...                                       communication_cost=0.5, cost=8.0, alpha=8.0, gap=1e-3)))
    Allocation(protocol='udp', status='optimal', mu=[0.4856, 1], communication_cost=0.5, cost=8, alpha=8, gap=1.0e-03)
    """
    return (f"Allocation(protocol={a.protocol!r}, status={a.status!r}, mu={short(a.mu, 4)}, "
            f"communication_cost={a.communication_cost:.6g}, cost={a.cost:.6g}, alpha={a.alpha:.6g}, gap={a.gap:.1e})")


def allocation_html(a: Any) -> str:
    """The allocation, its costs and its certificate, as an HTML table.

    >>> from types import SimpleNamespace
    >>> a = SimpleNamespace(protocol="tcp", status="optimal", mu=np.array([0.5]), beta=np.array([2.0]),
    ...                     communication_cost=1.0, cost=7.5, alpha=8.0, lower_bound=7.4, gap=1e-3, method="bnb",
    ...                     boxes=3)
    >>> text = allocation_html(a)
    >>> "TCP-like" in text, "7.5 &lt;= alpha = 8" in text, "<= alpha" in text   # the certificate, escaped
    (True, True, False)
    """
    return html_table("Allocation", [
        ("protocol", f"{a.protocol.upper()}-like"), ("status", a.status), ("mu*", short(a.mu)),
        ("beta", short(a.beta)), ("beta'mu", f"{a.communication_cost:.6g}"),
        ("J*(mu*)", f"{a.cost:.10g} <= alpha = {a.alpha:.6g}"), ("lower bound (proved)", f"{a.lower_bound:.6g}"),
        ("gap", f"{a.gap:.1e}"), ("method", a.method), ("boxes", a.boxes)])


def batch_repr(b: Any) -> str:
    """``BatchSolution(protocol='tcp', points=1000, method='dense', costs in [2.7985, 41.07])``.

    >>> from types import SimpleNamespace
    >>> batch_repr(SimpleNamespace(protocol="tcp", costs=np.array([41.07, 2.79847, 9.0]), method="dense"))
    "BatchSolution(protocol='tcp', points=3, method='dense', costs in [2.79847, 41.07])"
    >>> batch_repr(SimpleNamespace(protocol="udp", costs=np.array([]), method="dense"))
    "BatchSolution(protocol='udp', points=0, method='dense', costs in [])"
    """
    span = f"[{np.min(b.costs):.6g}, {np.max(b.costs):.6g}]" if len(b.costs) else "[]"
    return f"BatchSolution(protocol={b.protocol!r}, points={len(b.costs)}, method={b.method!r}, costs in {span})"


def maximiser_repr(x: Any) -> str:
    """``Maximiser(point=[0.02183], value=83.4246, method='logit-grid + bounded Brent')``.

    >>> from types import SimpleNamespace
    >>> maximiser_repr(SimpleNamespace(point=np.array([0.0218345]), value=83.424612, method="grid"))
    "Maximiser(point=[0.02183], value=83.4246, method='grid')"
    """
    return f"Maximiser(point={short(x.point, 4)}, value={x.value:.6g}, method={x.method!r})"


def claim_repr(r: Any) -> str:
    """``ClaimResult('theorem-2', 'holds', checked=52, violations=0, errors=0)``.

    >>> from packetloss_cvx.results import ClaimResult
    >>> ClaimResult("lemma-2", "...", "fails", 4, 1, -0.5, None, "")
    ClaimResult('lemma-2', 'fails', checked=4, violations=1, errors=0)
    """
    return (f"ClaimResult({r.id!r}, {r.verdict!r}, checked={r.checked}, violations={r.violations}, "
            f"errors={r.errors})")


def claim_html(r: Any) -> str:
    """The verdict, its counts, the worst margin, the cases and the note, as an HTML table.

    >>> from packetloss_cvx.results import ClaimResult
    >>> text = claim_html(ClaimResult("lemma-2", "J_tcp < J_udp", "fails", 4, 1, -0.5, None, ""))
    >>> "J_tcp &lt; J_udp" in text, "4, 1, 0" in text, "-0.5" in text, "none" in text   # no counterexample
    (True, True, True, True)
    """
    rows = [("verdict", r.verdict), ("claim", r.statement),
            ("checked, violations, errors", f"{r.checked}, {r.violations}, {r.errors}"),
            ("worst margin", short(r.worst))]
    if r.outcomes:
        rows.append(("cases (+ - . E)", r.outcomes))
    rows += [("counterexample", "yes (see .counterexample)" if r.counterexample else "none"), ("note", r.note)]
    return html_table(f"ClaimResult {r.id}", rows)
