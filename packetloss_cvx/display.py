"""How the package's objects show themselves: a one-line ``repr`` with the headline numbers and a
small HTML table for notebooks (``_repr_html_``), never an array dump; and ``to_json``.

The model and the result types bind these as methods (``__repr__ = system_repr``), so this module
imports neither: it reads the attributes it shows. Each function is O(size of what it shows):
matrices are shown only up to `MAX_SHOWN` rows and columns, larger ones by their shape.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "MAX_SHOWN", "allocation_html", "allocation_repr", "batch_repr", "claim_html", "claim_repr", "closed_loop_html",
    "design_sweep_html", "design_sweep_repr", "field_text", "fields_html", "fields_repr", "html_grid", "html_table",
    "json_text", "maximiser_repr", "plain", "supported", "supported_digits", "apart",
    "short", "simulation_html", "span", "solution_html", "solution_repr", "system_html", "system_repr", "to_json",
    "SOLUTION_BASIS", "all_delivered_flag",
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
    names = getattr(obj, "__dataclass_fields__", vars(obj))
    return f"{type(obj).__name__}(" + ", ".join(f"{name}={field_text(getattr(obj, name))}" for name in names) + ")"


def field_text(value: Any) -> str:
    """One field's value as `fields_repr` shows it: strings quoted, numbers and small arrays by
    `short`, mappings by key, other objects by their type. O(size of what it shows).

    >>> field_text("tcp"), field_text(np.ones(9)), field_text({"a": 1.5}), field_text(object())
    ("'tcp'", 'array of shape (9,)', "{'a': 1.5}", '<object>')
    """
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k!r}: {field_text(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (int, float, complex, np.number, np.ndarray, list, tuple)):
        try:
            return short(value)
        except (TypeError, ValueError):
            return f"<{type(value).__name__}>"
    return f"<{type(value).__name__}>"


def fields_html(obj: Any) -> str:
    """A dataclass's fields as an HTML table, each value as `fields_repr` shows it (the notebook view of
    the result types without one of their own). O(size of what it shows).

    >>> from packetloss_cvx.results import Maximiser
    >>> text = fields_html(Maximiser(np.array([0.0218345]), 83.424612, "a<b"))
    >>> "Maximiser" in text, "[0.0218345]" in text, "83.4246" in text, "a&lt;b" in text
    (True, True, True, True)
    """
    names = getattr(obj, "__dataclass_fields__", vars(obj))
    return html_table(type(obj).__name__, [(name, field_text(getattr(obj, name))) for name in names])


def plain(value: Any) -> Any:
    """``value`` with JSON's types only: arrays to (nested) lists, NumPy scalars to Python numbers, complex
    numbers to ``[re, im]``, tuple keys to ``"a, b"``, any other key to text. The one converter behind
    [`to_json`][packetloss_cvx.display.to_json] and ``reproduce``'s results.json. O(size of ``value``).

    >>> plain({(0.9, 0.5): np.array([1.0, 2.0]), "z": 1 + 2j, "n": np.int64(3), 4: [np.float64(0.5)]})
    {'0.9, 0.5': [1.0, 2.0], 'z': [1.0, 2.0], 'n': 3, '4': [0.5]}
    """
    if isinstance(value, dict):
        return {(", ".join(map(str, k)) if isinstance(k, tuple) else str(k)): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, complex):
        return [value.real, value.imag]
    if isinstance(value, np.generic):
        return plain(value.item())
    return value


def json_text(value: Any, **kwargs: Any) -> str:
    """``value`` as strict JSON text through `plain` (``kwargs`` go to `json.dumps`, e.g.
    ``indent=2``). Raises ValueError on a non-finite number (strict JSON has none). O(size of ``value``).

    >>> json_text({"mu": np.array([0.9, 0.5])})
    '{"mu": [0.9, 0.5]}'
    """
    return json.dumps(plain(value), allow_nan=False, **kwargs)


def to_json(obj: Any, **kwargs: Any) -> str:
    """``obj.to_dict()`` as JSON text (`json_text`; ``kwargs`` go to `json.dumps`, e.g. ``indent=2``).

    Raises ValueError on a non-finite number (strict JSON has none). O(size of the dict).

    >>> from packetloss_cvx.results import CrossCheck
    >>> CrossCheck("dense", 1e-9, 0.0).to_json()
    '{"max_input_diff": 1e-09, "cost_rel_diff": 0.0}'
    """
    return json_text(obj.to_dict(), **kwargs)


def html_table(title: str, rows: Sequence[tuple[str, Any]]) -> str:
    """A two-column HTML table under a bold title; every value escaped.

    >>> text = html_table("System", [("n", 2), ("name", "<b>x</b>")])
    >>> text.startswith("<table>"), "&lt;b&gt;x&lt;/b&gt;" in text, "<b>x</b>" in text
    (True, True, False)
    """
    cells = "".join(f'<tr><th style="text-align:left">{html.escape(str(label))}</th>'
                    f'<td style="text-align:left">{html.escape(str(value))}</td></tr>' for label, value in rows)
    return f'<table><caption style="text-align:left"><b>{html.escape(title)}</b></caption>{cells}</table>'


def html_grid(title: str, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """An HTML table with a header row under a bold title; every cell escaped. O(cells).

    >>> text = html_grid("Runs", ["law", "cost"], [("tcp", "<1>")])
    >>> text.count("<th"), "&lt;1&gt;" in text, "<1>" in text
    (2, True, False)
    """
    head = "".join(f'<th style="text-align:left">{html.escape(str(h))}</th>' for h in header)
    body = "".join("<tr>" + "".join(f'<td style="text-align:left">{html.escape(str(v))}</td>' for v in row) + "</tr>"
                   for row in rows)
    return f'<table><caption style="text-align:left"><b>{html.escape(title)}</b></caption><tr>{head}</tr>{body}</table>'


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

    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0],
    ...            noise_cov=[[2.0]], name="a<b")
    >>> text = system_html(s)
    >>> "a&lt;b" in text, "a<b" in text, "Sigma_W, trace 2" in text, "1, 1, 2" in text   # escaped; n, m, N
    (True, False, True, True)
    """
    rows = [("name", system.name or "(unnamed)"), ("n, m, horizon N", f"{system.n}, {system.m}, {system.horizon}"),
            ("mu", channel_text(system)), ("x0", short(system.x0)), ("A", short(system.A)), ("B", short(system.B)),
            ("noise", "none" if not np.any(system.noise_cov) else f"Sigma_W, trace {np.trace(system.noise_cov):.4g}")]
    if getattr(system, "dt", None) is not None:
        rows.append(("sampling time dt", f"{system.dt:g} s"))
    return html_table("System", rows)


#: what a Solution's ``cost`` is: the paper's J* (Theorem 1's expression, exact); for the TCP-like protocol a
#: first-moment value no causal law attains (allocation.attainable gives the attainable one)
SOLUTION_BASIS = "paper"


def all_delivered_flag(sol: Any) -> str | None:
    """One line when the receding-horizon law is unstable even with every packet delivered (the radius of A - B K,
    the paper's Tables I-II convention, at least 1); None otherwise or without eigenvalues. O(n).

    >>> from types import SimpleNamespace
    >>> all_delivered_flag(SimpleNamespace(closed_loop_eigenvalues=np.array([1.077, 0.5])))
    'UNSTABLE even with every packet delivered (radius of A - B K = 1.077)'
    >>> all_delivered_flag(SimpleNamespace(closed_loop_eigenvalues=np.array([0.9]))) is None
    True
    """
    eigs = sol.closed_loop_eigenvalues
    if eigs is None or not len(eigs):
        return None
    radius = float(np.max(np.abs(eigs)))
    return f"UNSTABLE even with every packet delivered (radius of A - B K = {radius:.6g})" if radius >= 1 else None


def _solution_rows(sol: Any) -> list[tuple[str, Any]]:
    rows: list[tuple[str, Any]] = [("protocol", f"{sol.protocol.upper()}-like"),
                                   (f"J*, {SOLUTION_BASIS}", f"{sol.cost:.10g}"), ("method", sol.method)]
    if sol.closed_loop_eigenvalues is not None and len(sol.closed_loop_eigenvalues):
        # the paper's Tables I-II convention, every packet delivered: not the loop over the lossy channel
        radius = f"{np.max(np.abs(sol.closed_loop_eigenvalues)):.6g}"
        flag = all_delivered_flag(sol)
        rows.append(("radius of A - B K (all delivered)",
                     radius if flag is None else f"{radius}: UNSTABLE even with every packet delivered"))
    if sol.stability is not None:   # attached by closed_form (or with_stability): the loop over the lossy channel
        rows.append(("mean-square stability", sol.stability.verdict))
    elif sol.gain is not None:
        rows.append(("mean-square stability",
                     "not computed (skipped, or a plan solved without its system): "
                     "packetloss_cvx.closedloop.law_stability.with_stability(system, solution)"))
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
    """``Solution(protocol='tcp', cost=2.798470088, basis='paper', method='dense', N=10, m=2, loop='mean-square
    stable, radius 0.53')``: the loop's verdict when attached, and one flag when the law is unstable even with every
    packet delivered.

    >>> from packetloss_cvx.results import LoopStability, Solution
    >>> Solution("udp", 10.25, np.zeros((10, 2)), None, None, "recursion")
    Solution(protocol='udp', cost=10.25, basis='paper', method='recursion', N=10, m=2)
    >>> text = repr(Solution("udp", 0.9, np.zeros((1, 1)), np.ones((1, 1)), np.array([1.077]), "dense",
    ...                      stability=LoopStability(2.5, False, "mu = 0.5")))
    >>> text.endswith("m=1, loop='NOT mean-square stable, radius 2.5', all_delivered='UNSTABLE even with every packet "
    ...               "delivered (radius of A - B K = 1.077)')")
    True
    """
    status = f", status={sol.status!r}" if sol.status is not None else ""
    N, m = sol.inputs.shape
    text = (f"Solution(protocol={sol.protocol!r}, cost={sol.cost:.10g}, basis={SOLUTION_BASIS!r}, "
            f"method={sol.method!r}{status}, N={N}, m={m}")
    st = sol.stability
    if st is not None:
        loop = (f"not computed: {st.note}" if st.radius is None else
                ("mean-square stable" if st.stable else "NOT mean-square stable") + f", radius {st.radius:.6g}")
        text += f", loop={loop!r}"
    flag = all_delivered_flag(sol)
    if flag is not None:
        text += f", all_delivered={flag!r}"
    return text + ")"


def solution_html(sol: Any) -> str:
    """The cost, method, the radius of A - B K with every packet delivered (the paper's Tables I-II), the
    mean-square stability of u = -K x over the lossy channel (once
    [`packetloss_cvx.closedloop.law_stability.with_stability`][packetloss_cvx.closedloop.law_stability.with_stability]
    attached it: a Solution does not carry the channel) and (QPs) solver status, as an HTML table.

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
    basis = getattr(a, "basis", None)
    attained = "" if basis is None else (f", basis={basis!r}, attainable_cost={short(a.attainable_cost)}, "
                                         f"stabilisable={a.stabilisable}")
    return (f"Allocation(protocol={a.protocol!r}, status={a.status!r}, mu={short(a.mu, 4)}, "
            f"communication_cost={a.communication_cost:.6g}, cost={a.cost:.6g}{attained}, alpha={a.alpha:.6g}, "
            f"gap={a.gap:.1e})")


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
    basis = getattr(a, "basis", None)
    rows = [("protocol", f"{a.protocol.upper()}-like"), ("status", a.status), ("mu*", short(a.mu)),
            ("beta", short(a.beta)), ("beta'mu", f"{a.communication_cost:.6g}"),
            ("J*(mu*)" if basis is None else f"J*(mu*), {basis}", f"{a.cost:.10g} <= alpha = {a.alpha:.6g}")]
    if basis is not None:
        cost = "not computed" if a.attainable_cost is None else f"{a.attainable_cost:.10g}"
        verdict = {True: "yes", False: "NO", None: "no verdict"}[a.stabilisable]
        rows += [("attainable cost", f"{cost} ({a.attainable_note})"),
                 ("stabilisable", f"{verdict} ({a.stability_note})")]
        if a.warning is not None:
            rows.append(("warning", a.warning.removeprefix("warning: ")))
    rows += [("lower bound (proved)", f"{a.lower_bound:.6g}"), ("gap", f"{a.gap:.1e}"), ("method", a.method),
             ("boxes", a.boxes)]
    return html_table("Allocation", rows)


def batch_repr(b: Any) -> str:
    """``BatchSolution(protocol='tcp', points=1000, method='dense', paper costs in [2.7985, 41.07])``.

    >>> from types import SimpleNamespace
    >>> batch_repr(SimpleNamespace(protocol="tcp", costs=np.array([41.07, 2.79847, 9.0]), method="dense"))
    "BatchSolution(protocol='tcp', points=3, method='dense', paper costs in [2.79847, 41.07])"
    >>> batch_repr(SimpleNamespace(protocol="udp", costs=np.array([]), method="dense"))
    "BatchSolution(protocol='udp', points=0, method='dense', paper costs in [])"
    """
    span = f"[{np.min(b.costs):.6g}, {np.max(b.costs):.6g}]" if len(b.costs) else "[]"
    return (f"BatchSolution(protocol={b.protocol!r}, points={len(b.costs)}, method={b.method!r}, paper costs in "
            f"{span})")


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


def span(values: Any) -> str:
    """``[min, max]`` of the finite values to 6 digits, with how many are not finite. O(len(values)).

    >>> span(np.array([3.0, 1.0, np.inf])), span(np.array([]))
    ('[1, 3] (1 not finite)', 'none')
    """
    arr = np.asarray(values, dtype=float)
    finite = arr[np.isfinite(arr)]
    if not finite.size:
        return "none" if not arr.size else f"none finite ({arr.size})"
    bad = arr.size - finite.size
    return f"[{finite.min():.6g}, {finite.max():.6g}]" + (f" ({bad} not finite)" if bad else "")


def design_sweep_repr(d: Any) -> str:
    """One line: ``DesignSweep('two-actuator', kind='mu-grid', shape={'mu2': 11, 'mu1': 11}, J*_tcp in [..], ...)``:
    each quantity's range, never its values. O(points).

    >>> from types import SimpleNamespace
    >>> d = SimpleNamespace(name="x", kind="horizon", dims=("horizon",), shape=(3,),
    ...                     costs={"tcp": np.array([3.0, 2.0, 1.0])},
    ...                     difference=None, radii={})
    >>> design_sweep_repr(d)
    "DesignSweep('x', kind='horizon', shape={'horizon': 3}, J*_tcp (paper) in [1, 3])"
    """
    label = f"{d.name!r}, " if d.name else ""
    parts = [f"J*_{p} (paper) in {span(v)}" for p, v in d.costs.items()]
    if d.difference is not None:
        parts.append(f"J_Delta (paper) in {span(d.difference)}")
    parts += [f"radius_{p} in {span(v)}" for p, v in d.radii.items()]
    shape = "{" + ", ".join(f"{k!r}: {v}" for k, v in zip(d.dims, d.shape, strict=True)) + "}"
    return f"DesignSweep({label}kind={d.kind!r}, shape={shape}, " + ", ".join(parts) + ")"


def design_sweep_html(d: Any) -> str:
    """The grid's dimensions and, per quantity, its range and where its maximum is (as ``DesignSweep.grid`` indexes
    it), and how many points are mean-square stable. O(points).

    >>> from types import SimpleNamespace
    >>> d = SimpleNamespace(name=None, kind="mu-grid", dims=("mu1",), shape=(3,), axes=(np.array([0.0, 0.5, 1.0]),),
    ...                     costs={"udp": np.array([9.0, 4.0, 1.0])}, difference=None, radii={}, chunk_size=2048,
    ...                     mu=np.array([[0.0], [0.5], [1.0]]))
    >>> text = design_sweep_html(d)
    >>> "mu1: 3 points in [0, 1]" in text, "[1, 9]" in text, "max at (0,): mu1 = 0" in text
    (True, True, True)
    """
    rows: list[tuple[str, Any]] = [("name", d.name or "(unnamed)"), ("kind", d.kind)]
    rows += [(f"axis {k}" if len(d.dims) > 1 else "axis", f"{k}: {a.size} points in [{a.min():.4g}, {a.max():.4g}]")
             for k, a in zip(d.dims, d.axes, strict=True)]
    quantities = {**{f"J*_{p}, paper": v for p, v in d.costs.items()},
                  **({"J_Delta = J*_udp - J*_tcp, paper": d.difference} if d.difference is not None else {}),
                  **{f"mean-square radius, {p}": v for p, v in d.radii.items()}}
    for label, values in quantities.items():
        arr = np.asarray(values, dtype=float)
        text = span(arr)
        if np.any(np.isfinite(arr)):
            k = int(np.nanargmax(np.where(np.isfinite(arr), arr, np.nan)))
            index = np.unravel_index(k, d.shape)
            where = ", ".join(f"{dim} = {axis[i]:.4g}" for dim, axis, i in zip(d.dims, d.axes, index, strict=True))
            text += f"; max at {tuple(int(i) for i in index)}: {where}"
        if label.startswith("mean-square"):
            text += f"; stable (< 1) at {int(np.sum(arr < 1))} of {arr.size}"
        rows.append((label, text))
    rows.append(("arrays", f"flat (points,) fields; shaped {tuple(d.shape)}: .grid(name); to_xarray()"))
    return html_table("DesignSweep", rows)


def closed_loop_html(c: Any) -> str:
    """A law over the lossy channel: its mean-square radius, stability and average stage cost. O(m n).

    >>> from types import SimpleNamespace
    >>> c = SimpleNamespace(law="tcp", mu=np.array([0.9]), spectral_radius=1.2, stable=False, average_stage_cost=np.inf,
    ...                     gain=np.array([[1.0]]), reason="not mean-square stable")
    >>> text = closed_loop_html(c)
    >>> "1.2" in text, "no" in text, "inf (not mean-square stable)" in text
    (True, True, True)
    """
    cost = f"{c.average_stage_cost:.10g}" if np.isfinite(c.average_stage_cost) else f"inf ({c.reason or 'unstable'})"
    return html_table(f"ClosedLoop {c.law}".strip(), [
        ("law u = -K x", c.law or "(unnamed)"), ("mu", short(c.mu)),
        ("mean-square spectral radius", f"{c.spectral_radius:.6g}"),
        ("mean-square stable", "yes" if c.stable else "no"),
        ("average stage cost", cost), ("gain K", short(c.gain, 4))])


def simulation_html(sim: Any) -> str:
    """Monte Carlo against the exact values: one row per law, open loop (mean, exact, z) and closed loop. O(laws).

    >>> from types import SimpleNamespace
    >>> check = SimpleNamespace(formula=2.8, exact=3.0, mean=3.01, stderr=0.02, z=0.5, reason="")
    >>> sim = SimpleNamespace(samples=100, steps=5, seed=0, channel="bernoulli", open_loop={"tcp": check},
    ...                       closed_loop={})
    >>> text = simulation_html(sim)
    >>> "3.01 ± 0.02" in text, "0.5" in text, "100 runs" in text
    (True, True, True)
    """
    def pm(mean: float, err: float) -> str:
        return f"{mean:.6g} ± {err:.2g}" if np.isfinite(mean) else "-"

    rows = []
    for law in dict.fromkeys([*sim.open_loop, *sim.closed_loop]):
        o, c = sim.open_loop.get(law), sim.closed_loop.get(law)
        rows.append((law,
                     "-" if o is None else f"{o.formula:.6g}", "-" if o is None else pm(o.mean, o.stderr),
                     "-" if o is None else f"{o.exact:.6g}", "-" if o is None else f"{o.z:.2f}",
                     "-" if c is None else pm(c.mean_stage_cost, c.stderr),
                     "-" if c is None else f"{c.exact_stage_cost:.6g}",
                     "-" if c is None else f"{c.spectral_radius:.4g} ({'stable' if c.stable else 'not stable'})"))
    title = f"Simulation: {sim.samples} runs, {sim.steps} steps, seed {sim.seed}, {sim.channel} channel"
    return html_grid(title, ["law", "J* (Theorem 1)", "open loop: sampled cost", "exact E[cost] of the plan", "z",
                             "closed loop: mean stage cost", "exact", "mean-square radius"], rows)


def supported_digits(value: float, error: float, most: int = 17) -> int:
    """The significant digits of ``value`` that its accuracy estimate ``error`` (an absolute error) supports:
    ``floor(log10(|value| / error))``, at least 1 and at most ``most`` (``most`` where the error is 0, unknown (nan)
    or the value is not finite). O(1).

    Examples
    --------
    >>> supported_digits(0.8352448407578126, 6.2e-6), supported_digits(0.8352448407578126, 1e-16)
    (5, 15)
    >>> supported_digits(0.5, 0.0), supported_digits(0.5, float("nan"), most=6), supported_digits(1e-3, 1.0)
    (17, 6, 1)
    """
    if not (np.isfinite(value) and error > 0 and np.isfinite(error)) or value == 0:
        return most
    return int(min(most, max(1, np.floor(np.log10(abs(value) / error)))))


def apart(a: float, b: float, digits: int = 6) -> tuple[str, str]:
    """``a`` and ``b`` in ``%.{d}g`` with the least ``d >= digits`` (at most 17) at which the two texts differ, so
    that two different numbers never print alike ("alpha = 1.92192 is below ... 1.92192"); equal numbers print
    alike at ``digits``. O(1).

    Examples
    --------
    >>> apart(1.9219195, 1.9219195438718941), apart(0.5, 0.25), apart(2.0, 2.0)
    (('1.9219195', '1.92191954'), ('0.5', '0.25'), ('2', '2'))
    """
    if a != b:
        for d in range(digits, 18):
            if f"{a:.{d}g}" != f"{b:.{d}g}":
                return f"{a:.{d}g}", f"{b:.{d}g}"
    return f"{a:.{digits}g}", f"{b:.{digits}g}"


def supported(value: float, error: float) -> float:
    """``value`` rounded to the significant digits its accuracy estimate ``error`` supports (`supported_digits`):
    what JSON and CSV print. O(1).

    Examples
    --------
    >>> supported(0.8352448407578126, 6.2e-6), supported(0.8352448407578126, 0.0)
    (0.83524, 0.8352448407578126)
    """
    return float(f"{value:.{supported_digits(value, error)}g}")
