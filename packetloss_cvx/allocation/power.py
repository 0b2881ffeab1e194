"""What to buy: transmit power per channel instead of delivery probabilities.

Each channel's delivery probability is a non-decreasing function of its transmit power P_i, a
`PowerModel` (exponential, rayleigh, table: `.delivery`).
Two problems, both protocols, with linear constraints on P (the grammar of ``allocate``, in P1..Pm):

.. math:: \\min_P \\textstyle\\sum_i P_i \\ \\text{s.t.}\\ J^*(\\mu(P)) \\le \\alpha
   \\qquad\\text{and}\\qquad \\min_P J^*(\\mu(P)) \\ \\text{s.t.}\\ \\textstyle\\sum_i P_i \\le B.

Every search runs on ``x = P / top`` in [0, 1]^m (``top`` a per-channel cap no optimum exceeds), where
``x -> J*(mu(top x))`` falls in every x_i (Theorem 3 and mu non-decreasing): the certified monotone branch
and bound of `.udp` applies unchanged (`MonotoneCost`). The
TCP-like protocol with a model concave on the box (exponential, a concave table) is a convex program
(docs/mathematics.md "Power-limited links": J*_tcp convex and falling in mu, mu concave in P): it is solved
by cvxpy + Clarabel (`PowerProgram`, the exponential cone), its point checked by the closed form and
its lower bound proved by tangent cuts, and the branch and bound only confirms (no box when the cuts
certify the gap).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

import cvxpy as cp
import numpy as np

from ..budgets import check, count_text, program_bytes
from ..errors import InfeasibleError, InputError, SolverError
from ..lq.evaluator import CostEvaluator
from ..model.protocols import check_protocol
from ..model.system import STRUCTURE_CACHE_MAX_BYTES, System
from ..model.validation import numeric_array
from ..qp.convex import ClarabelProgram, require_optimal
from ..results import PowerAllocation
from ..threads import blas_limited
from ..tolerances import (
    ALLOCATION_CLARABEL_ATTEMPTS,
    ALLOCATION_COST_RTOL,
    ALLOCATION_GAP_DEFAULT,
    ALLOCATION_INCUMBENT_SHARE,
)
from .attainable import attainment
from .boxes import boundary, box_lp, gap_unit, reported_gap, small_lp, unit_prices
from .delivery import PowerModel, rayleigh_majorant
from .grammar import Constraint, check_count, check_gap, check_number, check_system, read_polytope
from .tcp import PROGRAMS_KEY, constant_cost, cost_epigraph, cut_points, tangent
from .udp import MonotoneCost, udp_allocate, udp_min_cost

__all__ = ["PowerProgram", "least_cost_within_power", "least_power", "power_pareto"]

#: tangents of the rayleigh curve in its first relaxation (geometric in P / c from 1 to top / c), and the most
#: relaxations solved (TCP-like), each adding the tangents at the last relaxed point's powers
RAYLEIGH_TANGENTS = 16
RAYLEIGH_ROUNDS = 6
SEARCH_HALVINGS = 2100     #: the most halvings of the least-power search box (_search_cap): double precision's span
#: compiled power programs kept (PowerProgram.of), the least recently used dropped first
PROGRAMS_KEPT = 32
_PROGRAMS: OrderedDict = OrderedDict()
_PROGRAMS_LOCK = threading.Lock()

# ------------------------------------------------------------------ the convex program (TCP-like, concave model)

class PowerProgram:
    """The TCP-like power problem with a concave model as one cvxpy program (DPP), solved by Clarabel.

    Variables: y = P / unit (m; the model's own unit, `PowerModel.unit`), mu (m) and
    `cost_epigraph`'s. The link ``mu <= mu(P)`` is convex for a concave
    model: exponential ``exp(-y_i) <= 1 - mu_i`` (the exponential cone, the same numbers at every scale c), a
    concave table ``mu_i <= a_ik + b_ik P_i`` for each segment k and ``mu_i <= mu_last``.
    J*_tcp falls in mu, so the link is tight at the optimum. Parameters: x0, sqrt of the cost scale, the cap
    ``top`` on P and k rows ``G P <= h``. Kind "power": min sum P s.t. scaled cost <= 1 (scale 1 / (alpha - C));
    kind "cost": min the scaled cost. Size O(N (n + m) + K m); compiled once and kept by
    content (`of`), then each solve maps the Parameters and runs Clarabel.

    Examples
    --------
    `J*_tcp` = 1/(1 + mu) (one step of x' = x + v u from x0 = 1), mu = 1 - exp(-P): `J*` <= 0.8 needs mu = 1/4,
    P = log(4/3):

    >>> from packetloss_cvx.allocation.delivery import power_model
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> program = PowerProgram(s, power_model("exponential", 1, scale=1.0), "power", 0)
    >>> P = program.solve(s.x0, 1 / 0.8, np.array([40.0]), np.zeros((0, 1)), np.zeros(0))
    >>> bool(np.isclose(P[0], np.log(4 / 3), atol=1e-6))
    True
    """

    def __init__(self, system: System, model: PowerModel, kind: str, rows: int) -> None:
        n, m = system.n, system.m
        self.kind = kind
        # the variable is y = P / unit, the model's own unit (PowerModel.unit): the exponential cone then reads
        # exp(-y_i) + mu_i <= 1 at every scale c, where with P the variable its coefficient 1/c was 1e12 at c = 1e-12
        # (Clarabel 'optimal_inaccurate' or 'solver_error', and at c = 1e12 a false infeasibility certificate). A
        # program in x = P / top (reverted 4645732) was as well scaled, but puts top / c (40, or B / c) in the cone:
        # the least-cost points moved by up to 4.6e-5 in P from the KKT root (mathematics.md, "Power-limited links")
        self.unit = model.unit()
        self.y = cp.Variable(m, name="P_per_unit")
        self.mu = cp.Variable(m, name="mu")
        self.x0 = cp.Parameter(n, name="x0")
        self.root = cp.Parameter(nonneg=True, name="sqrt_scale")
        self.top = cp.Parameter(m, name="top_per_unit")
        self.rows = (cp.Parameter((rows, m), name="G_per_unit"), cp.Parameter(rows, name="h")) if rows else None
        epigraph, scaled, _ = cost_epigraph(system, self.mu, self.x0, self.root)
        cons = [*epigraph, self.y >= 0, self.y <= self.top, self.mu >= 0, self.mu <= 1]
        if model.kind == "exponential":
            cons.append(cp.exp(-self.y) + self.mu <= 1)
        elif model.kind == "table":
            slopes = np.diff(model.table, axis=0) / np.diff(model.powers)[:, None] * self.unit[None, :]
            starts = model.table[:-1] - slopes * (model.powers[:-1, None] / self.unit[None, :])
            same = np.zeros_like(slopes, dtype=bool)     # a segment on the line of the one before: a duplicate row
            same[1:] = np.isclose(slopes[1:], slopes[:-1], rtol=1e-9, atol=0.0) & \
                np.isclose(starts[1:], starts[:-1], rtol=1e-9, atol=1e-15)
            for k in range(len(slopes)):       # (merged power columns repeat lines: Clarabel stalled on them)
                keep = np.flatnonzero(~same[k])
                if len(keep) == m:
                    cons.append(self.mu <= starts[k] + cp.multiply(slopes[k], self.y))
                elif len(keep):
                    cons.append(self.mu[keep] <= starts[k, keep] + cp.multiply(slopes[k, keep], self.y[keep]))
            cons.append(self.mu <= model.table[-1])
        else:  # pragma: no cover - the API routes only concave models here
            raise ValueError(f"no convex program for the {model.kind} model")
        if self.rows is not None:
            cons.append(self.rows[0] @ self.y <= self.rows[1])
        # sum P in units of the largest unit (sum y where every unit is equal)
        objective = cp.sum(cp.multiply(self.unit / np.max(self.unit), self.y)) if kind == "power" else scaled
        if kind == "power":
            cons.append(scaled <= 1.0)
        self.problem = cp.Problem(cp.Minimize(objective), cons)
        self.compiled = ClarabelProgram(self.problem)

    @classmethod
    def of(cls, system: System, model: PowerModel, kind: str, rows: int) -> PowerProgram:
        """The program for this system's structure, model, kind and number of rows: compiled on first use and kept
        (the ``PROGRAMS_KEPT`` most recent, by content, while its estimated size fits ``STRUCTURE_CACHE_MAX_BYTES``),
        so a problem asked again on an equal system (a fresh copy, another call) does not compile it again (a compile
        costs several solves). The key is every input of the constructor: the system's fields its algebra reads
        (`PROGRAMS_KEY`: `cost_epigraph`), the model's kind and data (its unit and table),
        ``kind`` and ``rows``; x0, the cost scale, the cap and the rows' values are Parameters given to
        `solve`, which assigns none of them (as `TCPProgram`: shared without a lock). O(size of
        the key) when kept.

        Examples
        --------
        >>> from packetloss_cvx.allocation.delivery import power_model
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> model = power_model("exponential", 1, scale=1.0)
        >>> PowerProgram.of(s, model, "power", 0) is PowerProgram.of(s.with_x0([2.0]), model, "power", 0)
        True
        >>> PowerProgram.of(s, model, "power", 0) is PowerProgram.of(s, power_model("exponential", 1, scale=2.0),
        ...                                                          "power", 0)
        False
        """
        N, n, m = system.horizon, system.n, system.m
        if program_bytes(N, n, m) > STRUCTURE_CACHE_MAX_BYTES:
            return cls(system, model, kind, rows)
        parts: list = [kind, rows, model.kind, model.m]
        for value in [*(getattr(system, name) for name in sorted(PROGRAMS_KEY.depends_on)),
                      model.scale, model.powers, model.table]:
            array = None if value is None else np.asarray(value)
            parts.append(None if array is None else (array.dtype.str, array.shape, array.tobytes()))
        key = tuple(parts)
        with _PROGRAMS_LOCK:
            program = _PROGRAMS.pop(key, None)
        if program is None:
            program = cls(system, model, kind, rows)
        with _PROGRAMS_LOCK:
            _PROGRAMS[key] = program            # the most recent last
            while len(_PROGRAMS) > PROGRAMS_KEPT:
                _PROGRAMS.pop(next(iter(_PROGRAMS)))
        return program

    def solve(self, x0: np.ndarray, scale: float, top: np.ndarray, G: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The solver's P (clipped to [0, top]) for the cap ``top`` and rows ``G P <= h``.

        Raises SolverError on any status but "optimal", Clarabel's infeasibility certificate included: it is
        never a verdict here (it was false at c = 1e12 with P the variable); the callers prove infeasibility
        by the branch and bound or an LP."""
        what = "TCP-like power SOCP" if self.kind == "power" else "TCP-like power-budget SOCP"
        values = {self.x0: x0, self.root: np.sqrt(scale), self.top: np.asarray(top, dtype=float) / self.unit}
        if self.rows is not None:
            values.update({self.rows[0]: np.asarray(G, dtype=float) * self.unit[None, :], self.rows[1]: h})
        status, point = self.compiled.solve(values, what, ALLOCATION_CLARABEL_ATTEMPTS)
        require_optimal(status, what)
        return np.clip(self.unit * np.array(point(self.y), dtype=float), 0.0, top)


# ------------------------------------------------------------------ the problems

class _Setup:
    """One problem's data on x = P / top: the model, the cap, the polytope in x, the cost of x."""

    def __init__(self, system: System, protocol: str, model: PowerModel, top: np.ndarray,
                 constraints: Sequence[Constraint]) -> None:
        self.system, self.protocol, self.model, self.top = system, protocol, model, top
        self.poly = read_polytope(_scaled(constraints, top), system.m, 0.0, 1.0, name="P", scale=top)
        self.evaluator = CostEvaluator(system, protocol)
        self.cost = MonotoneCost(self.evaluator, lambda x: model.mu(top * x), lambda i, t: model.channel(i, top[i] * t))

    def convex(self) -> bool:
        """TCP-like with a model concave on the whole box: the convex program applies."""
        return self.protocol == "tcp" and self.model.kind != "rayleigh" and bool(np.all(self.model.concave_from() == 0))

    def cuts(self, x: np.ndarray, evaluator: CostEvaluator) -> tuple[np.ndarray, np.ndarray]:
        """Affine minorants ``J(x') >= r_k + g_k x'`` of the convex x -> J*_tcp(mu(top x)) at x and around it
        (the steps of ``ALLOCATION_CUT_STEPS``): the chain rule on `tangent`'s gradient, with the
        model's slope a supergradient of the concave mu_i; loosened for rounding as tangent_cuts does."""
        X = cut_points(x)
        P = X * self.top
        f, S = tangent(self.system, self.model.mu(P), evaluator)
        g = S * np.array([self.model.slope(p) for p in P]) * self.top
        r = f - np.sum(g * X, axis=1) - ALLOCATION_COST_RTOL * (np.abs(f) + np.abs(g).sum(axis=1))
        return g, r


def _setup(system: System, protocol: str, model: PowerModel, top: np.ndarray, constraints: Sequence[Constraint],
           cap: np.ndarray | None) -> _Setup:
    """`_Setup`, where rows no power up to ``top`` meets are a proof of infeasibility only when ``top`` is
    the caller's cap (or the budget); a box cut at the model's saturation proves nothing (a row may ask for more
    power than mu needs): then InputError naming ``max_power``."""
    try:
        return _Setup(system, protocol, model, top, constraints)
    except InfeasibleError as err:
        if cap is not None:
            raise
        raise InputError("max_power", f"the constraints ask some channel for more power than the model's saturation "
                         f"{np.round(top, 6).tolist()} (where mu is 1 to 1e-12 or more): give a cap per channel "
                         f"(max_power, --power-max) to search up to it ({err})") from None


def _scaled(constraints: Sequence[Constraint], top: np.ndarray) -> list:
    """Rows ``G P <= h`` (or callables on P) as rows on x = P / top."""
    out: list = []
    for item in constraints:
        if callable(item):
            out.append(lambda x, item=item: item(cp.multiply(top, x)))
        elif isinstance(item, (tuple, list)) and len(item) == 2:
            G = np.atleast_2d(np.asarray(item[0], dtype=float))
            out.append((G * top[None, :] if G.ndim == 2 and G.shape[-1] == len(top) else item[0], item[1]))
        else:
            out.append(item)
    return out


def _boxes(value: Any) -> int:
    """A positive count within the ``allocation_boxes`` budget (budgets.py), as allocate checks it."""
    count = check_count(value, "max_boxes")
    check("allocation_boxes", count, "max_boxes", f"{count_text(count)} boxes")
    return count


def _cap(value: Any, m: int) -> np.ndarray | None:
    if value is None:
        return None
    cap = np.atleast_1d(numeric_array(value, "max_power"))
    if cap.ndim != 1 or len(cap) not in (1, m) or np.any(~(cap > 0)):
        raise InputError("max_power", f"expected 1 or {m} positive numbers, found {cap.tolist()}")
    return np.broadcast_to(cap, (m,)).copy()


def _check(system: System, protocol: str, model: PowerModel) -> tuple[System, str]:
    system = check_system(system)
    protocol = check_protocol(protocol)
    if not isinstance(model, PowerModel):
        raise InputError("model", f"expected a PowerModel (power_model(...)), found {type(model).__name__}")
    if model.m != system.m:
        raise InputError("model", f"the model has {model.m} channels, the system {system.m}")
    return system, protocol


def _result(setup: _Setup, problem: str, x: np.ndarray, value: float, lower: float, status: str, method: str,
            boxes: int, limit: float, unit: float = 1.0, size: float | None = 1.0) -> PowerAllocation:
    """The result at x; ``value`` and ``lower`` in units of ``unit`` (the gap is taken there, the bound reported
    times it), the gap `reported_gap` with the search's ``size``."""
    P = setup.top * x
    mu = setup.model.mu(P)
    cost = float(CostEvaluator(setup.system, setup.protocol).cost(np.clip(mu, 0.0, 1.0)))
    total = float(np.sum(P))
    found = attainment(setup.system, setup.protocol, np.clip(mu, 0.0, 1.0), cost)      # what a loop attains at mu
    return PowerAllocation(protocol=setup.protocol, problem=problem, model=setup.model.to_dict(), power=P,
                           total_power=total, mu=mu, cost=cost, limit=limit, lower_bound=lower * unit,
                           gap=reported_gap(value, lower, size), status=status,
                           method=method, boxes=boxes, attainable_cost=found.cost, attainable_note=found.cost_note,
                           stabilisable=found.stabilisable, stability_note=found.stability_note)


def _search_cap(system: System, protocol: str, model: PowerModel, alpha: float, constraints: Sequence[Constraint],
                cap: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """The box [0, top] to search for the least power: the caller's cap or the model's saturation, cut down to
    the total of a feasible point (any better point spends less in total, so no channel more than that total).
    The point: the most a box [0, T]^m allows (an LP) where it meets alpha, T doubled from below until it does,
    then halved while it still does: top within 2 m of the least power's scale (else a table ending at 1e24 beside
    its action at 1 put the answer's x = P / top under the gap's absolute floor: "optimal", lower bound 0, 33 %
    above the least power). Returns top and the feasible point (in P) if found. O(log2(top / P*)) LPs, closed
    forms (no halving after a doubling: its first box is the one the doubling rejected last)."""
    sat = model.saturation() if cap is None else cap
    evaluator = CostEvaluator(system, protocol)

    def feasible(T: float) -> np.ndarray | None:
        box = np.minimum(np.full(system.m, T), sat)
        try:
            setup_poly = read_polytope(_scaled(constraints, box), system.m, 0.0, 1.0, name="P", scale=box)
            q, _ = box_lp(-np.ones(system.m), setup_poly, np.zeros(system.m), np.ones(system.m))
        except InfeasibleError:             # a row this box cannot meet (P1 >= 30 in [0, 1]^m): not a verdict
            return None
        if q is not None and evaluator.cost(np.clip(model.mu(box * q), 0.0, 1.0)) <= alpha:
            return box * q
        return None

    T = float(np.min(sat)) / 2 ** 10 if model.kind != "rayleigh" else float(np.min(model.scale))
    doubled = False
    while (P := feasible(T)) is None:
        if np.all(np.minimum(np.full(system.m, T), sat) >= sat):
            return sat, None
        T, doubled = T * 2.0, True
    # after a doubling, T / 2 is the box just found not to meet alpha (feasible is deterministic): no halving
    for _ in range(0 if doubled else SEARCH_HALVINGS):  # down to where half the box no longer meets alpha
        half = feasible(T / 2.0)
        if half is None or not np.any(half > 0):
            break
        T, P = T / 2.0, half
    return np.minimum(sat, max(float(np.sum(P)), float(np.max(P)))), P


@blas_limited
def least_power(system: System, protocol: str, model: PowerModel, alpha: float,
                constraints: Sequence[Constraint] = (), max_power: Any = None, gap: float = ALLOCATION_GAP_DEFAULT,
                max_boxes: int = 20000, time_limit: float | None = None,
                progress: bool | None = None) -> PowerAllocation:
    """The least total transmit power ``sum P`` with ``J*(mu(P)) <= alpha``, with a certificate.

    Parameters
    ----------
    system : System
        Stationary channel; its own mu is ignored.
    protocol : {"tcp", "udp"}
    model : PowerModel
        Delivery as a function of power (`power_model`, `load_power`).
    alpha : float
        Bound on the optimal expected cost, > 0.
    constraints : sequence
        Pairs ``(G, h)`` meaning ``G P <= h``, or callables ``f(P)`` returning affine cvxpy constraints.
    max_power : float or array_like or None
        A cap per channel (None: no cap; the search box is derived, see `_search_cap`).
    gap, max_boxes, time_limit, progress
        As for [`allocate`][packetloss_cvx.allocation.api.allocate].

    Returns
    -------
    PowerAllocation
        ``power`` feasible by the closed form (J*(mu(power)) <= alpha), ``lower_bound`` proven on the total
        power, ``status`` "optimal" or "gap_not_certified".

    Raises
    ------
    InputError
        A bad argument, named by its field.
    InfeasibleError
        Proven, never from the conic program's status (a Clarabel failure or infeasibility certificate hands the
        problem to the branch and bound): alpha below the constant cost C; J* at the saturated powers (mu at its
        largest) above alpha; a row no point of the box meets (grammar.read_polytope, without a solver); every
        box discarded (its upper corner above alpha by the checked closed form, or its LP empty).

    Notes
    -----
    TCP-like with a concave model: one conic program (O(N (n + m)) variables) and 6 m + 1 closed forms and
    one LP for the bound; otherwise the branch and bound of `udp_allocate` on x = P / top, each
    box an LP and O(m log(1/tol)) closed forms of O(N (n^3 + m^3)).

    Examples
    --------
    One step of x' = x + v u from x0 = 1: J*_tcp = 1/(1 + mu) <= 0.8 needs mu = 1/4, i.e. P = log(4/3) with
    mu = 1 - exp(-P):

    >>> from packetloss_cvx.allocation.delivery import power_model
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> a = least_power(s, "tcp", power_model("exponential", 1, scale=1.0), 0.8)
    >>> a.status, bool(np.log(4 / 3) <= a.total_power <= np.log(4 / 3) * (1 + 1e-4)), a.cost <= 0.8
    ('optimal', True, True)
    """
    system, protocol = _check(system, protocol, model)
    alpha = check_number(alpha, "alpha")
    if alpha <= 0:
        raise InputError("alpha", f"expected a positive bound on J*, found {alpha:g}")
    gap = check_gap(gap)
    max_boxes = _boxes(max_boxes)
    cap = _cap(max_power, system.m)
    C = constant_cost(system)
    if alpha < C:        # proof: C bounds J* below for every mu (tcp.constant_cost)
        raise InfeasibleError(f"alpha = {alpha:g} is below the cost no channel can reduce, C = {C:.6g}", None)
    top, found = _search_cap(system, protocol, model, alpha, constraints, cap)
    setup = _setup(system, protocol, model, top, constraints, cap)
    J = setup.cost.checked
    m = system.m
    corner = J(np.ones(m))
    if corner > alpha * (1 + ALLOCATION_COST_RTOL):     # proof: the checked closed form at the largest mu (Theorem 3)
        raise InfeasibleError(f"J*_{protocol} at the largest powers searched (mu = "
                              f"{np.round(setup.cost.mu(np.ones(m)), 12).tolist()}) is {corner:.6g} > alpha = "
                              f"{alpha:g}, and J* falls as any power rises", None)
    # the least total power the rows admit at all is a lower bound; where J* there already meets alpha (alpha
    # at or above the cost of silent channels, P = 0) it is the answer, and the conic program, whose scale
    # 1 / (alpha - C) then vanishes, is not asked (it failed with 'solver_error' at alpha = 1e9 on two_actuator)
    # the searches price x by top / max(top) and report in P: the relative gap and the branch and bound's split
    # weights then do not see the unit of power (at c = 1e-12 the absolute floors of both would decide)
    prices, unit = unit_prices(top)
    least, floor_lp = box_lp(prices.copy(), setup.poly, np.zeros(m), np.ones(m))
    if least is not None and J(np.clip(least, 0.0, 1.0)) <= alpha:
        x = np.clip(least, 0.0, 1.0)
        return _result(setup, "least-power", x, float(prices @ x), min(float(floor_lp), float(prices @ x)), "optimal",
                       "the least power the constraints admit (an LP) already meets alpha", 0, alpha, unit)
    incumbent = None if found is None else found / top
    floor, failed = -np.inf, ""
    tcp = setup if protocol == "tcp" else _Setup(system, "tcp", model, top, constraints)
    if tcp.convex():
        # the TCP-like convex program: for "tcp" the answer, for "udp" a lower bound (Theorem 2: J*_udp >= J*_tcp);
        # a solver failure (Clarabel's infeasibility certificate included) is no verdict: the branch and bound,
        # which proves infeasibility by discarding every box, answers alone
        try:
            x, floor = _convex_least_power(tcp, alpha, C, prices)
        except SolverError as err:
            failed = f"; the convex program failed ({err}), so the branch and bound answered alone"
        else:
            if protocol == "tcp" and J(x) <= alpha:
                incumbent = x
    elif model.kind == "rayleigh" and protocol == "tcp":    # (UDP-like: J*_tcp's floor sits far below J*_udp)
        x, floor, failed = _rayleigh_relaxation(tcp, constraints, "least-power", alpha, C, prices, gap)
        if x is not None:
            incumbent = x
    out = udp_allocate(system, setup.poly, alpha, prices, gap, floor, max_boxes, time_limit, progress,
                       cost=setup.cost, incumbent=incumbent, what=f"{protocol.upper()}-like least power")
    method = _method(protocol, tcp.convex() and not failed, model, out.boxes, out.note, failed)
    return _result(setup, "least-power", out.mu, out.value, out.lower_bound, out.status, method, out.boxes, alpha,
                   unit)


def _method(protocol: str, convex: bool, model: PowerModel, boxes: int, note: str, extra: str = "") -> str:
    """How the answer was found, in words; ``extra`` the rayleigh relaxation's note (or a conic failure's)."""
    if extra.startswith("; lower bound from") and boxes == 0:       # the rayleigh relaxation certified alone
        return extra[len("; lower bound from "):] + ", certified with no box of the branch and bound"
    program = ("convex program (Clarabel, " + ("exponential cone" if model.kind == "exponential" else
                                               "the table's linear pieces") + "), lower bound from tangent cuts in P")
    if protocol == "tcp" and convex:
        return program if boxes == 0 else f"{program}; confirmed by branch and bound on x = P / top: {note}"
    text = f"branch and bound on x = P / top: {note}"
    return text + ("; lower bound from the TCP-like convex program (Theorem 2)" if convex else "") + extra


def _rayleigh_relaxation(setup: _Setup, constraints: Sequence[Constraint], problem: str, alpha: float, C: float,
                         prices: np.ndarray | None, gap: float) -> tuple[np.ndarray | None, float, str]:
    """TCP-like rayleigh through conic programs: the problem with the curve replaced by
    `rayleigh_majorant` (a concave table above it, so its `J*_tcp` is lower at every P) is convex,
    and its certified bound (tangent cuts) bounds the rayleigh problem below. Its point, moved onto {`J*` <= alpha}
    by the true curve for the least power, is the incumbent. Each round adds the tangents at the point's powers
    (Kelley's cutting planes) until the incumbent is within ``gap`` of the bound: where the optimum has every
    P_i >= c_i (the majorant is exact there in the limit) the branch and bound then explores no box; elsewhere
    it starts from this floor. The gap is `gap_unit`'s, at the problem's size: 1 for the power at unit
    prices, `J*` at the box's lower corner (its largest cost) for the cost. Returns (incumbent or None, floor, the note
    for ``method``); a conic failure is no verdict (the bound found before is kept, the note says so).
    O(RAYLEIGH_ROUNDS) conic programs with O(K) table rows."""
    system, model, top = setup.system, setup.model, setup.top
    J = setup.cost.checked                                      # J*_tcp of the true curve
    size = 1.0 if problem == "least-power" else abs(J(setup.poly.lower()))
    at = list(np.geomspace(1.0, max(2.0, float(np.max(top / model.scale))), RAYLEIGH_TANGENTS))
    floor, best, best_value, done = -np.inf, None, np.inf, 0
    try:
        for done in range(1, RAYLEIGH_ROUNDS + 1):  # noqa: B007 - the count is reported
            relaxed = _Setup(system, "tcp", rayleigh_majorant(model, np.array(at)), top, constraints)
            if problem == "least-power":
                x, lower = _convex_least_power(relaxed, alpha, C, prices)
                cut = x
                if J(x) > alpha:                    # relaxed-feasible only: towards a maximal point by the true J
                    q, _ = box_lp(-np.ones(system.m), relaxed.poly, np.zeros(system.m), np.ones(system.m))
                    if q is None or J(q) > alpha:
                        x = None
                    else:
                        t = boundary(lambda a, x=x, q=q: J(x + a * (q - x)), alpha, 0.0, 1.0,
                                     ALLOCATION_INCUMBENT_SHARE * 1e-3)
                        x = x + t * (q - x)
                value = np.inf if x is None else float(prices @ x)
            else:
                x, lower = _convex_least_cost(relaxed)
                cut, value = x, J(x)
            stalled = bool(np.isfinite(floor)) and lower - floor <= 0.1 * gap * gap_unit(lower, size)
            floor = max(floor, lower)
            if value < best_value:
                best, best_value = x, value
            if best_value - floor <= gap * gap_unit(best_value, size):
                break
            # Kelley: cut at the relaxed optimum; a tangent within 1e-7 (relative) of one taken adds nothing but
            # near-parallel rows (J* moves by ~1e-14 there; Clarabel ended 'optimal_inaccurate' on such tables)
            new = [p for p in top * cut / model.scale if p > 1.0 and np.min(np.abs(np.array(at) - p)) > 1e-7 * p]
            if stalled or np.any(top * cut <= model.scale):   # a channel at P_i <= c_i, where the majorant is the
                break                  # line P / (e c) above f: no tangent closes that gap (measured: same boxes)
            if not new:
                break
            at.extend(new)
    except SolverError as err:
        return best, floor, f"; a rayleigh relaxation's convex program failed ({err}), so the branch and bound " \
                            f"answered from the bound found before"
    return best, floor, (f"; lower bound from {done} conic program(s) on a concave table of tangents above the "
                         f"rayleigh curve ({len(at)} tangents)")


def _convex_least_power(setup: _Setup, alpha: float, C: float, prices: np.ndarray) -> tuple[np.ndarray, float]:
    """The convex program's point moved onto {J* <= alpha} if it is just outside, and the tangent-cut bound on
    ``prices' x`` (prices = top / max(top))."""
    system, top, poly = setup.system, setup.top, setup.poly
    program = PowerProgram.of(system, setup.model, "power", poly.G.shape[0])
    G = poly.G / top[None, :]
    P = program.solve(system.x0, 1.0 / max(alpha - C, np.finfo(float).tiny), top, G, poly.h)
    x = np.clip(P / top, 0.0, 1.0)
    evaluator = setup.evaluator
    g, r = setup.cuts(x, evaluator)
    scale = np.max(np.abs(g), axis=1)
    keep = scale > 0
    rows = np.vstack([poly.G, g[keep] / scale[keep, None]])
    rhs = np.concatenate([poly.h, (alpha - r[keep]) / scale[keep]])
    point, lower = small_lp(prices, rows, rhs, np.zeros(system.m), np.ones(system.m))
    lower = -np.inf if point is None else lower         # the cuts admit every feasible point: not expected
    J = setup.cost.checked
    if J(x) > alpha:                      # solver tolerance: towards a maximal point until the closed form agrees
        q, _ = box_lp(-np.ones(system.m), poly, np.zeros(system.m), np.ones(system.m))
        if q is not None and J(q) <= alpha:
            t = boundary(lambda a: J(x + a * (q - x)), alpha, 0.0, 1.0, ALLOCATION_INCUMBENT_SHARE * 1e-3)
            x = x + t * (q - x)
    return x, lower


@blas_limited
def least_cost_within_power(system: System, protocol: str, model: PowerModel, budget: float,
                            constraints: Sequence[Constraint] = (), max_power: Any = None,
                            gap: float = ALLOCATION_GAP_DEFAULT, max_boxes: int = 20000,
                            time_limit: float | None = None) -> PowerAllocation:
    """The least optimal cost ``J*(mu(P))`` with ``sum P <= budget`` (and the constraints), certified to a
    relative ``gap`` (as [`least_power`][packetloss_cvx.allocation.power.least_power]'s; the branch and bound's corner
    bounds lose a first-order term where the optimum lies inside the budget's face, so the boxes grow like gap^-1/2:
    two_actuator, UDP-like, exponential c = (1, 2), B = 3: 766 boxes at 1e-4, 2366 at 1e-5, 7043 at 1e-6).

    Raises
    ------
    InputError
        A negative or non-finite budget (field ``budget``), or another bad argument.
    InfeasibleError
        The constraints admit no power within the budget: a row no point of the box meets (without a solver), or
        the LP over x = P / top in [0, 1]^m (HiGHS, scale-free data) finds no point; never from Clarabel.

    Notes
    -----
    TCP-like with a concave model: one conic program, 6 m + 1 closed forms and one LP (its bound); otherwise
    (and to confirm) the branch and bound of `udp_min_cost` on x = P / top, top = min(budget, cap,
    the model's saturation), two LPs and two closed forms per box.

    Examples
    --------
    Two decoupled copies of x' = x + v u (N = 1), J*_tcp = sum 1/(1 + mu_i), mu_i = 1 - exp(-P_i): a budget of
    2 is best split evenly (symmetry and convexity), mu = 1 - e^-1 each:

    >>> from packetloss_cvx.allocation.delivery import power_model
    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> best = least_cost_within_power(t, "tcp", power_model("exponential", 2, scale=1.0), 2.0)
    >>> bool(np.allclose(best.power, 1.0, atol=1e-3)), bool(np.isclose(best.cost, 2 / (2 - np.exp(-1)), rtol=1e-6))
    (True, True)
    """
    system, protocol = _check(system, protocol, model)
    budget = check_number(budget, "budget")
    if budget < 0:
        raise InputError("budget", f"expected a total power >= 0, found {budget:g}")
    gap = check_gap(gap)
    max_boxes = _boxes(max_boxes)
    cap = _cap(max_power, system.m)
    m = system.m
    top = model.saturation() if cap is None else cap
    if budget == 0:              # no power at all: the only point, if the constraints admit it
        setup = _setup(system, protocol, model, top, constraints, top)    # a row no box point meets misses P = 0
        if np.any(setup.poly.h < 0):                                      # proof: G 0 = 0 > h
            raise InfeasibleError("the constraints admit no power within a budget of 0", None)
        x = np.zeros(m)
        value = setup.cost.checked(x)
        return _result(setup, "least-cost", x, value, value, "optimal", "a budget of 0: every channel silent", 0, 0.0)
    top = np.minimum(top, budget)
    rows = [*constraints, (np.ones((1, m)), np.array([budget]))]
    try:
        cut = cap is None and bool(np.any(top < budget))        # cut at saturation: rows beyond it prove nothing
        setup = _setup(system, protocol, model, top, rows, None if cut else top)
    except InfeasibleError as err:
        raise InfeasibleError(f"no power within the budget meets the constraints: {err}", None) from None
    if box_lp(-np.ones(m), setup.poly, np.zeros(m), np.ones(m))[0] is None:     # proof: HiGHS on the scale-free LP
        raise InfeasibleError("no power within the budget meets the constraints (an LP over x = P / top in [0, 1]^m "
                              "finds no point)", None)
    floor, incumbent, failed = -np.inf, None, ""
    tcp = setup if protocol == "tcp" else _Setup(system, "tcp", model, top, rows)
    if tcp.convex():
        try:                # a solver failure is no verdict: the branch and bound then answers alone
            x, floor = _convex_least_cost(tcp)
        except SolverError as err:
            failed = f"; the convex program failed ({err}), so the branch and bound answered alone"
        else:
            if protocol == "tcp":
                incumbent = x
    elif model.kind == "rayleigh" and protocol == "tcp":
        incumbent, floor, failed = _rayleigh_relaxation(tcp, rows, "least-cost", 0.0, constant_cost(system), None, gap)
    out = udp_min_cost(system, setup.poly, max_boxes, time_limit, cost=setup.cost, incumbent=incumbent, floor=floor,
                       what=f"{protocol.upper()}-like least cost within the power budget", gap=gap)
    method = _method(protocol, tcp.convex() and not failed, model, out.boxes, out.note, failed)
    # the search's verdict and the unit of its gap's floor (J* at the box's lower corner, its largest cost)
    return _result(setup, "least-cost", out.mu, out.value, out.lower_bound, out.status, method, out.boxes, budget,
                   size=out.scale)


def _convex_least_cost(setup: _Setup) -> tuple[np.ndarray, float]:
    """The convex program's point and the tangent-cut bound ``min t s.t. t >= r_k + g_k x`` over the polytope."""
    system, top, poly = setup.system, setup.top, setup.poly
    m = system.m
    C = constant_cost(system)
    reference = setup.cost.checked(np.ones(m)) - C
    program = PowerProgram.of(system, setup.model, "cost", poly.G.shape[0])
    P = program.solve(system.x0, 1.0 / max(reference, np.finfo(float).tiny), top, poly.G / top[None, :], poly.h)
    x = np.clip(P / top, 0.0, 1.0)
    g, r = setup.cuts(x, setup.evaluator)
    scale = np.maximum(np.max(np.abs(g), axis=1), 1.0)
    G = np.vstack([np.hstack([poly.G, np.zeros((poly.G.shape[0], 1))]), np.hstack([g, -np.ones((len(r), 1))])
                   / scale[:, None]])
    h = np.concatenate([poly.h, -r / scale])
    c = np.zeros(m + 1)
    c[-1] = 1.0
    ceiling = max(setup.cost.checked(x), C)
    _, lower = small_lp(c, G, h, np.append(np.zeros(m), C), np.append(np.ones(m), ceiling))
    return x, max(lower, C) if np.isfinite(lower) else C


def power_pareto(system: System, protocol: str, model: PowerModel, budgets: Sequence[float],
                 constraints: Sequence[Constraint] = (), max_power: Any = None,
                 gap: float = ALLOCATION_GAP_DEFAULT) -> list[PowerAllocation]:
    """The power-cost trade-off: [`least_cost_within_power`][packetloss_cvx.allocation.power.least_cost_within_power] at
    each budget (ascending), each point certified. O(len(budgets)) times one problem.

    Examples
    --------
    >>> from packetloss_cvx.allocation.delivery import power_model
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> curve = power_pareto(s, "tcp", power_model("exponential", 1, scale=1.0), [0.0, 1.0, 3.0])
    >>> [round(p.cost, 6) for p in curve] == [round(1 / (2 - np.exp(-b)), 6) for b in (0.0, 1.0, 3.0)]
    True
    """
    values = [check_number(b, "budgets") for b in budgets]
    return [least_cost_within_power(system, protocol, model, b, constraints, max_power, gap) for b in sorted(values)]
