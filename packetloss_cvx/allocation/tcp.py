"""TCP-like allocation: an exact convex program, with a lower bound proved after the solve.

With ``Z = Vbar U`` the TCP-like expected cost

.. math:: J(Z, \\mu) = C + \\|L \\hat x\\|^2 + \\sum_i \\sum_t \\psi_{t,i} z_{t,i}^2 / \\mu_i

(mean states ``xhat`` tied to ``Z`` by the dynamics) is jointly convex in (Z, mu), so the
optimal cost ``J*_tcp(mu) = min_Z J`` is convex in mu and the allocation (eq:channel-opt)
is an SOCP. Each quad-over-lin term gets its own epigraph variable ``t_i`` and the cost is
divided by ``alpha - C``: with the terms summed in one constraint, Clarabel ended
``optimal_inaccurate`` on 36 of 200 test problems (typically when an optimal mu_i is 0, the
cone's apex); in this form on none
(``tolerances.ALLOCATION_CLARABEL_ATTEMPTS``; the program here runs ``ALLOCATION_TCP_ATTEMPTS``).

The solver's point is not taken on trust:

* its cost is re-evaluated by the closed form, and if above alpha the point is moved towards
  a maximal point of the constraint set until the closed form says ``J* <= alpha``;
* the lower bound comes from tangents of the convex function J*_tcp at and around the
  solver's point, ``J*(mu) >= J*(p) + s'(mu - p)`` with ``s_i = -sum_t psi_{t,i} u_{t,i}^2``
  (the envelope theorem; ``u`` the optimal commanded inputs at ``p``): every feasible mu meets
  the cuts, so the LP over the constraint set and the cuts is a relaxation, and its dual
  bound (`dual_bound`) is a lower bound on the optimum
  that does not depend on the solver's tolerances.
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np

from ..budgets import program_bytes
from ..display import apart
from ..errors import InfeasibleError, NumericalError, SolverError
from ..lq.evaluator import CostEvaluator
from ..lq.recursion import udp_variance_weights
from ..model.system import CacheKey, StructureStore, System
from ..qp.convex import PROVEN_INFEASIBLE, ClarabelProgram, require_optimal
from ..qp.expected_cost import sparse_dynamics
from ..tolerances import (
    ALLOCATION_COST_RTOL,
    ALLOCATION_CUT_STEPS,
    ALLOCATION_INCUMBENT_SHARE,
    ALLOCATION_LP_FEASIBILITY,
    ALLOCATION_TCP_ATTEMPTS,
    MIN_COST_RTOL,
)
from .boxes import (
    Outcome,
    boundary,
    box_lp,
    check_in_polytope,
    cost_function,
    polytope_excess,
    reported_gap,
    small_lp,
)
from .grammar import Polytope

__all__ = [
    "TCPProgram", "constant_cost", "cost_epigraph", "cut_points", "interval", "least_feasible", "require_answer",
    "tangent", "tangent_cuts", "tcp_allocate", "tcp_min_cost",
]


def constant_cost(system: System) -> float:
    """C = x0' Q x0 + tr(Omega_l Sigma_W): the part of J no choice of mu or U changes, a lower
    bound on J*(mu) for every mu (the other terms are nonnegative). O(N n^3).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0],
    ...            initial_weight=[2.0])
    >>> constant_cost(s), constant_cost(s) <= float(CostEvaluator(s, "tcp").cost(np.array([1.0])))   # 2 + 1/2
    (2.0, True)
    """
    x0 = system.x0
    return float(x0 @ system.initial_weight @ x0) + udp_variance_weights(system)[1]


#: the system's compiled TCP-like programs, one per (kind, number of constraint rows): everything in them but the
#: Parameters (x0, bounds, rows, prices, scale) depends on these fields only
PROGRAMS_KEY = CacheKey("allocation.tcp.programs", ("A", "B", "horizon", "state_weights", "input_weights"))
_PROGRAMS = StructureStore(PROGRAMS_KEY)


def cost_epigraph(system: System, mu: cp.Variable, x0: cp.Parameter, root: cp.Parameter
                  ) -> tuple[list, cp.Expression, np.ndarray]:
    """The TCP-like cost as cvxpy constraints in ``mu`` (the one place the SOCP's algebra is written).

    Variables: the mean states ``xhat`` and ``Z = Vbar U`` (the dynamics ``xhat_{t+1} = A xhat_t +
    B z_t`` as equality constraints, sparse in the horizon), the epigraph ``r >= s ||L xhat||^2`` and
    ``t_i >= s sum_t psi_{t,i} z_{t,i}^2 / mu_i``, s = root^2 the cost scale. Returns the constraints, the
    expression ``r + sum t`` (>= s (J*_tcp(mu) - C), with equality at the optimum over the other variables)
    and the program's constant data as one read-only vector (what tests/lq/test_cache_keys.py compares).
    O(N (n + m)) variables, O(N (n^2 + n m)) nonzeros. Used by `TCPProgram` and
    [`.power`][packetloss_cvx.allocation.power].

    Examples
    --------
    J*_tcp(mu) - C = 1/(1 + mu) (one step of x' = x + v u from x0 = 1): at mu = 1/2 the least of the expression
    is 2/3.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> mu, x0, root = cp.Variable(1), cp.Parameter(1, value=[1.0]), cp.Parameter(nonneg=True, value=1.0)
    >>> cons, scaled, _ = cost_epigraph(s, mu, x0, root)
    >>> problem = cp.Problem(cp.Minimize(scaled), [*cons, mu == 0.5])
    >>> bool(np.isclose(problem.solve(solver=cp.CLARABEL), 2 / 3, atol=1e-6))
    True
    """
    N, n, m = system.horizon, system.n, system.m
    Z = cp.Variable((N, m), name="Z")
    X = cp.Variable(N * n, name="xhat")
    t = cp.Variable(m, name="t")
    r = cp.Variable(name="r")
    E, Bbig, first, L = sparse_dynamics(system)
    w = np.sqrt(system.input_weights)
    constants = np.concatenate([M.toarray().ravel() if M is first else M.data for M in (E, Bbig, first, L)]
                               + [w.ravel()])
    constants.flags.writeable = False
    cons = [E @ X - Bbig @ cp.vec(Z.T, order="F") == first @ x0,
            cp.sum_squares(root * (L @ X)) <= r if L.shape[0] else r >= 0]
    cons += [cp.quad_over_lin(root * cp.multiply(w[:, i], Z[:, i]), mu[i]) <= t[i] for i in range(m)]
    return cons, r + cp.sum(t), constants


class TCPProgram:
    """The TCP-like allocation SOCP of one system, compiled once (DPP) and re-solved for each call.

    Variables: mu, the mean states ``xhat`` and ``Z = Vbar U`` (the dynamics ``xhat_{t+1} = A xhat_t +
    B z_t`` as equality constraints, sparse in the horizon), the epigraph ``r >= s ||L xhat||^2`` and
    ``t_i >= s sum_t psi_{t,i} z_{t,i}^2 / mu_i``, s the cost scale. Everything about the system but x0
    is a constant; ``cp.Parameter``s hold what changes between calls: x0, sqrt(s), the bounds lo and hi,
    the k rows ``G mu <= h``, and the prices beta. ``kind`` "allocate" minimises ``beta'mu`` subject
    to ``r + sum t <= 1`` (s = 1 / (alpha - C)); "min_cost" minimises ``r + sum t``.

    One program per (system structure, kind, k), kept here (a `StructureStore`,
    shared by a system's ``with_mu`` / ``with_x0`` copies), compiled once to Clarabel's data
    (`ClarabelProgram`) and solved under ``ALLOCATION_TCP_ATTEMPTS``: the
    tight settings without equilibration on a solver kept per thread and updated with each call's data (a
    function of its own data: without an equilibration nothing of the previous data is carried over,
    whereas a warm equilibrated Clarabel keeps the Ruiz scaling of the first data it saw, answers up to
    42 % off across calls), then Clarabel's defaults on a new equilibrated solver. The Parameters are
    never assigned (their values go straight into the data map), so calls from several threads share a
    program without a lock. Size O(N (n + m)) variables, O(N (n^2 + n m)) nonzeros; compiled in
    O(N (n + m)^2), then each solve maps the Parameters (O(nnz)) and runs Clarabel (on a kept solver: a new
    solver's set-up would add a fifth).

    Examples
    --------
    `J*_tcp(mu)` = 1/(1 + mu) (one step of x' = x + v u from x0 = 1, C = 0): the least mu with `J*` <= 0.8 is 0.25;
    the least `J*` over mu in [0, 0.5] is 1/(1 + 0.5):

    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> mu = TCPProgram.of(s, "allocate", 0).solve(s.x0, read_polytope([], 1, 0.0, 1.0), 1 / 0.8, np.ones(1))
    >>> bool(np.isclose(mu[0], 0.25, atol=1e-6))
    True
    >>> mu = TCPProgram.of(s, "min_cost", 0).solve(s.x0, read_polytope([], 1, 0.0, 0.5), 1.0)
    >>> bool(np.isclose(mu[0], 0.5, atol=1e-6))
    True
    """

    def __init__(self, system: System, kind: str, rows: int) -> None:
        n, m = system.n, system.m
        self.kind = kind
        self.mu = cp.Variable(m, name="mu")
        self.x0 = cp.Parameter(n, name="x0")
        self.root = cp.Parameter(nonneg=True, name="sqrt_scale")
        self.lo, self.hi = cp.Parameter(m, name="lo"), cp.Parameter(m, name="hi")
        self.rows = (cp.Parameter((rows, m), name="G"), cp.Parameter(rows, name="h")) if rows else None
        self.beta = cp.Parameter(m, name="beta")
        epigraph, scaled, self.constants = cost_epigraph(system, self.mu, self.x0, self.root)
        cons = [*epigraph, self.mu >= self.lo, self.mu <= self.hi]
        if self.rows is not None:
            cons.append(self.rows[0] @ self.mu <= self.rows[1])
        if kind == "allocate":
            self.problem = cp.Problem(cp.Minimize(self.beta @ self.mu), [*cons, scaled <= 1.0])
        else:
            self.problem = cp.Problem(cp.Minimize(scaled), cons)
        if not self.problem.is_dpp():  # pragma: no cover - construction guarantees it
            raise RuntimeError("the TCP-like allocation SOCP is not DPP")
        self.compiled = ClarabelProgram(self.problem)

    @classmethod
    def of(cls, system: System, kind: str, rows: int) -> TCPProgram:
        """The system's program of this kind and number of rows: built on first use and kept with the
        system's structure (beyond ``STRUCTURE_CACHE_MAX_BYTES`` estimated, built per call). O(1) when kept."""
        N, n, m = system.horizon, system.n, system.m
        programs = _PROGRAMS.get(system)
        if programs is None:
            programs = _PROGRAMS.put(system, {}, nbytes=program_bytes(N, n, m))
        program = programs.get((kind, rows))
        if program is None:          # two threads may both build one; setdefault keeps the first
            program = programs.setdefault((kind, rows), cls(system, kind, rows))
        return program

    def solve(self, x0: np.ndarray, poly: Polytope, scale: float, beta: np.ndarray | None = None,
              no_mu: str | None = None) -> np.ndarray:
        """The solver's mu for the state ``x0``, the polytope (of this program's number of rows), the
        cost scale and (kind "allocate") the prices, Clarabel run cold on the compiled data under
        `require_answer`'s status policy. Raises as `require_answer`."""
        what = "TCP-like allocation SOCP" if self.kind == "allocate" else "TCP-like minimum-cost SOCP"
        values = {self.x0: x0, self.root: np.sqrt(scale), self.lo: poly.lower(), self.hi: poly.upper()}
        if self.kind == "allocate":
            values[self.beta] = beta
        if self.rows is not None:
            values.update({self.rows[0]: poly.G, self.rows[1]: poly.h})
        status, point = self.compiled.solve(values, what, ALLOCATION_TCP_ATTEMPTS)
        require_answer(status, what, no_mu)
        return np.array(point(self.mu), dtype=float)


def tangent(system: System, mu: np.ndarray, evaluator: CostEvaluator | None = None) -> tuple[float, np.ndarray]:
    """J*_tcp(mu) and its gradient ``s_i = -sum_t psi_{t,i} u_{t,i}^2`` (one closed form).

    By the envelope theorem on ``J(Z, mu)``, at the optimal ``Z = Vbar U*`` the gradient of
    J*_tcp is the partial derivative of J in mu; it stays finite at mu_i = 0, where the closed
    form's inputs are the limit of the optimal law. O(N (n^3 + m^3)). Points may also be a
    batch (points, m): then costs (points,) and gradients (points, m) from one batched evaluation (``evaluator``,
    a TCP-like [`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator] of ``system``, reused when given).

    Examples
    --------
    `J*_tcp(mu)` = 1/(1 + mu) for one step of x' = x + v u from x0 = 1, so `dJ*`/dmu = -1/(1 + mu)^2.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> cost, grad = tangent(s, np.array([0.5]))
    >>> bool(np.isclose(cost, 2 / 3) and np.isclose(grad[0], -4 / 9))
    True
    """
    evaluator = CostEvaluator(system, "tcp") if evaluator is None else evaluator
    points = np.clip(np.asarray(mu, dtype=float), 0.0, 1.0)
    sol = evaluator.solve(points.reshape(-1, system.m))
    grads = -np.sum(system.input_weights * sol.inputs ** 2, axis=1)
    if points.ndim == 1:
        return float(sol.costs[0]), grads[0]
    return sol.costs, grads


def cut_points(center: np.ndarray, also: tuple[np.ndarray, ...] = ()) -> np.ndarray:
    """Where the tangent cuts touch: ``center``, the points ``also``, and ``center +- step e_i`` for each step of
    ``ALLOCATION_CUT_STEPS`` clipped into [0, 1] (a clipped point equal to the centre is left out). O(m steps).

    Examples
    --------
    >>> cut_points(np.array([1.0])).shape[0] == 1 + len(ALLOCATION_CUT_STEPS)     # only the steps down
    True
    """
    points = [center, *also]
    for step in ALLOCATION_CUT_STEPS:
        for i in range(center.size):
            for sign in (-1.0, 1.0):
                p = center.copy()
                p[i] = np.clip(p[i] + sign * step, 0.0, 1.0)
                if p[i] != center[i]:
                    points.append(p)
    return np.array(points)


def tangent_cuts(system: System, mubar: np.ndarray, evaluator: CostEvaluator | None = None,
                 also: tuple[np.ndarray, ...] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Affine minorants of J*_tcp: rows with ``J*(mu) >= r_k + S_k mu`` for every mu in [0, 1]^m.

    Tangents at ``mubar`` and at ``mubar +- step e_i`` for each step of
    ``ALLOCATION_CUT_STEPS`` (clipped into [0, 1]), so that their maximum brackets the
    optimum on whichever side the solver's point errs; each loosened by
    ``ALLOCATION_COST_RTOL (|J*| + ||grad||_1)`` for the closed form's rounding. Tangents at the
    points ``also`` are added (one channel: the infeasible end of the final bracket).
    O(m len(steps)) closed forms, evaluated as one batch.

    Examples
    --------
    Minorants of the convex J*_tcp(mu) = 1/(1 + mu) (one step of x' = x + v u from x0 = 1):

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> S, r = tangent_cuts(s, np.array([0.5]))
    >>> grid = np.linspace(0, 1, 11)
    >>> bool(np.all(r[:, None] + S @ grid[None] <= 1 / (1 + grid))), bool(np.isclose(S[0, 0], -4 / 9))
    (True, True)
    """
    S, r, _ = _cuts(system, mubar, evaluator, also)
    return S, r


def _cuts(system: System, mubar: np.ndarray, evaluator: CostEvaluator | None,
          also: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray, float]:
    """`tangent_cuts`, and J*_tcp at ``mubar`` (clipped into [0, 1]), the first of its batch. O(m len(steps))
    closed forms, as one batch."""
    points = cut_points(mubar, also)
    with np.errstate(over="ignore", invalid="ignore"):      # checked below: a cut of nan or inf raises, typed
        f, S = tangent(system, points, evaluator)
        r = f - np.sum(S * points, axis=1) - ALLOCATION_COST_RTOL * (np.abs(f) + np.abs(S).sum(axis=1))
    if not (np.all(np.isfinite(S)) and np.all(np.isfinite(r))):    # a cut of nan or inf proves nothing
        raise NumericalError(f"TCP-like allocation: J*_tcp or its gradient is not finite at a tangent point near mu = "
                             f"{np.round(mubar, 6).tolist()} (weights of very different scales?): no cut can be made")
    return S, r, float(f[0])


def require_answer(status: str, what: str, no_mu: str | None) -> None:
    """The allocation SOCPs' status policy on the final status of
    `ClarabelProgram.solve`: "optimal" passes,
    Clarabel's infeasibility certificate raises InfeasibleError(no_mu) (SolverError when ``no_mu`` is
    None: infeasibility is then known to be impossible), anything else SolverError. O(1).

    Examples
    --------
    >>> require_answer("optimal", "an LP", None) is None
    True
    >>> require_answer("infeasible", "an LP", "no mu fits")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InfeasibleError: no mu fits
    >>> require_answer("infeasible_inaccurate", "an LP", "no mu fits")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.SolverError: solver status 'infeasible_inaccurate': an LP
    """
    if status == PROVEN_INFEASIBLE:
        if no_mu is None:
            raise SolverError("inconsistent", f"{what}: Clarabel reports infeasible, but the LP found a point")
        raise InfeasibleError(no_mu, None)
    require_optimal(status, what)


def interval(poly: Polytope) -> tuple[float, float]:
    """One channel (m = 1): the polytope as the interval [a, b] of mu (a > b when empty). O(r).

    Examples
    --------
    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> interval(read_polytope([([[1.0]], [0.5]), ([[-2.0]], [-0.2])], 1, 0.0, 1.0))     # 0.1 <= mu <= 0.5
    (0.1, 0.5)
    """
    g, h = poly.G[:, 0], poly.h
    a = max([float(poly.lo), *(h[g < 0] / g[g < 0]).tolist()])
    b = min([float(poly.hi), *(h[g > 0] / g[g > 0]).tolist()])
    return (a, -np.inf) if np.any((g == 0) & (h < 0)) else (a, b)


def least_feasible(system: System, evaluator: CostEvaluator, a: float, b: float, alpha: float, tol: float
                   ) -> tuple[float, float, float, int]:
    """One channel: the least mu in [a, b] with `J*_tcp(mu)` <= alpha, given `J*(b)` <= alpha, to within a
    relative width ``tol`` on the feasible side; returns it, `J*` there, the infeasible end of the final
    bracket (its tangent proves the bound: `tangent_cuts`' ``also``) and the number of batches.

    `J*_tcp` is convex and falling in mu: a Newton step from the infeasible end lands short of the
    crossing (the tangent lies below `J*`), the chord from it to the feasible end beyond it (the chord
    lies above), so each batch of those two closed forms (`tangent`) shrinks the bracket, the
    Newton side quadratically; a step that would leave the bracket is replaced by its midpoint. Every
    decision is the closed form's `J*` <= alpha at a point, so the answer is feasible whatever the
    steps. O(log log(1/tol)) batches in practice (at most 200), each O(N (n^3 + m^3)).

    Examples
    --------
    `J*_tcp(mu)` = 1/(1 + mu) (one step of x' = x + v u from x0 = 1): `J*` <= 0.8 from mu = 0.25 on.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> mu, cost, short, batches = least_feasible(s, CostEvaluator(s, "tcp"), 0.0, 1.0, 0.8, 1e-9)
    >>> bool(short < 0.25 <= mu <= 0.25 * (1 + 1e-9)), bool(cost <= 0.8), batches
    (True, True, 5)
    """
    f, g = tangent(system, np.array([[a], [b]]), evaluator)
    if f[0] <= alpha:
        return a, f[0], a, 1
    lo, f_lo, g_lo, hi, f_hi = a, f[0], g[0, 0], b, f[1]
    batches = 1
    while hi - lo > tol * hi and batches < 200:
        steps = []
        if g_lo < 0:
            steps.append(lo + (alpha - f_lo) / g_lo)
        if f_hi < f_lo:
            steps.append(lo + (alpha - f_lo) * (hi - lo) / (f_hi - f_lo))
        points = sorted({x if lo < x < hi else 0.5 * (lo + hi) for x in steps} | ({0.5 * (lo + hi)} if len(steps) < 2
                                                                                else set()))
        points = [x for x in points if lo < x < hi]
        if not points:                  # adjacent floats
            break
        f, g = tangent(system, np.array(points)[:, None], evaluator)
        batches += 1
        for x, fx, gx in zip(points, f, g[:, 0], strict=True):
            if fx <= alpha:
                if x < hi:
                    hi, f_hi = x, fx
            elif x > lo:
                lo, f_lo, g_lo = x, fx, gx
    return hi, f_hi, lo, batches


def tcp_allocate(system: System, poly: Polytope, alpha: float, beta: np.ndarray, gap: float) -> Outcome:
    """min beta'mu over the polytope with J*_tcp(mu) <= alpha, ``beta`` at unit prices (largest 1:
    `unit_prices`).

    Returns
    -------
    Outcome
        ``mu`` with `J*_tcp(mu)` <= alpha by the closed form; ``lower_bound`` proved by the
        tangent cuts at and around the solver's point (`tangent_cuts`, computed before
        mu is moved): every mu of the polytope with `J*_tcp(mu)` <= alpha meets every cut, so
        no such mu has ``beta'mu < lower_bound``. Status "optimal" when the gap
        (`reported_gap` at scale 1) is within ``gap``, else
        "gap_not_certified"; ``cost`` `J*_tcp(mu)`
        (`cost_function`, each point evaluated once).

    Raises
    ------
    InfeasibleError
        alpha < C (no mu can help), `J*_tcp` at the upper corner of the bounds above alpha
        (`J*` falls in every mu_i), or Clarabel's infeasibility certificate for the SOCP
        (status ``infeasible``; ``infeasible_inaccurate`` is not a proof and raises SolverError).
    SolverError
        Any status but optimal after Clarabel's tight then default settings
        (``convex.solve_problem``), or a solver point that cannot be made feasible.

    Notes
    -----
    One SOCP with O(N (n + m)) variables (interior point, about 10-30 iterations of a sparse
    factorisation), 6 m + 1 closed forms and one LP for the bound, and O(log(1/gap)) closed
    forms for the move onto the feasible set, each O(N (n^3 + m^3)).

    Examples
    --------
    J*_tcp(mu) = 1/(1 + mu) <= 0.8 from mu = 0.25 on (one step of x' = x + v u from x0 = 1):

    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> out = tcp_allocate(s, read_polytope([], 1, 0.0, 1.0), 0.8, np.array([1.0]), 1e-3)
    >>> out.status, bool(out.lower_bound <= 0.25 <= out.value <= 0.25 * (1 + 1e-3))
    ('optimal', True)
    """
    C = constant_cost(system)
    if alpha < C:
        raise InfeasibleError(f"alpha = {alpha:g} is below the cost no channel can reduce, C = {C:.6g}", None)
    cost, evaluator = cost_function(system, "tcp")
    known: dict[bytes, float] = {}

    def J(mu: np.ndarray) -> float:          # the closed form, once per point (the answer's cost is reported)
        key = np.asarray(mu, dtype=float).tobytes()
        if key not in known:
            known[key] = cost(mu)
        return known[key]

    corner = J(poly.upper())
    if corner > alpha * (1 + ALLOCATION_COST_RTOL):
        shown_corner, shown_alpha = apart(corner, alpha)
        raise InfeasibleError(f"J*_tcp at the upper corner of the bounds, {shown_corner}, exceeds alpha = "
                              f"{shown_alpha}, and J* falls in every mu_i", None)
    no_mu = f"no mu within the bounds and constraints reaches J*_tcp <= alpha = {alpha:g}"
    note = "convex SOCP (Clarabel), lower bound from tangent cuts at its point"
    if system.m == 1:           # an interval and a convex falling J*: its crossing of alpha, no SOCP
        a, b = interval(poly)
        if a > b:
            raise InfeasibleError(f"{no_mu}: the constraints admit no mu", None)
        end = J(np.array([b]))
        if end > alpha * (1 + ALLOCATION_COST_RTOL):
            raise InfeasibleError(f"{no_mu}: J*_tcp at the largest admissible mu, {b:.6g}, is {end:.6g} "
                                  "and J* falls in mu", None)
        if end > alpha:
            raise SolverError("inconsistent", f"TCP-like allocation: J*_tcp at the largest admissible mu is within "
                              f"the closed form's accuracy of alpha = {alpha:g}, above it")
        found, at, short, batches = least_feasible(system, evaluator, a, b, alpha, ALLOCATION_INCUMBENT_SHARE * gap)
        mubar, also = np.array([found]), (np.array([short]),)
        known[mubar.tobytes()] = at          # the closed form's J* there (batched: equal to rounding)
        note = (f"one channel: J* <= alpha from mu = {found:.6g} on (Newton and chord steps on the closed form, "
                f"{batches} batches), lower bound from tangent cuts at that point")
    else:
        program = TCPProgram.of(system, "allocate", poly.G.shape[0])
        mubar = np.clip(program.solve(system.x0, poly, 1.0 / max(alpha - C, np.finfo(float).tiny), beta,
                                      f"{no_mu} (Clarabel certificate)"), poly.lo, poly.hi)
        also = ()

    S, r, at_mubar = _cuts(system, mubar, evaluator, also)     # the lower bound, before any move
    known.setdefault(mubar.tobytes(), at_mubar)              # J* there (clipped), checked in the batch
    scale = np.max(np.abs(S), axis=1)
    if np.any((scale == 0) & (r > alpha)):
        raise SolverError("inconsistent", "TCP-like allocation: J*_tcp does not depend on mu and exceeds alpha, "
                          "yet the SOCP reported a solution")
    keep = scale > 0
    G = np.vstack([poly.G, S[keep] / scale[keep, None]])
    point, lower = small_lp(beta, G, np.concatenate([poly.h, (alpha - r[keep]) / scale[keep]]), poly.lower(),
                            poly.upper())
    if point is None:
        raise SolverError("inconsistent", "TCP-like allocation: the tangent cuts near the SOCP's point exclude "
                          "every mu, yet the SOCP reported a solution")
    lower = max(lower, float(beta @ poly.lower()))

    mu = mubar
    missed = polytope_excess(mubar, poly)
    if missed > ALLOCATION_LP_FEASIBILITY:
        # Clarabel meets the rows to its own feasibility tolerance, scaled by the problem (seen: 1.4e-9 on the row
        # mu2 >= mu1 + 0.05 of a two-mass spring at N = 5), not to the LP's: the cut LP's point is in the polytope
        # (as tcp_min_cost takes it), and the move below keeps to the polytope from there
        mu, note = point, note + f"; its point missed a row by {missed:.1e}, the cut LP's point taken"
    if beta @ point < beta @ mu and J(point) <= alpha:
        mu, note = point, note + "; the LP's point is feasible and attains the bound"
    elif J(mu) > alpha:           # solver tolerance: move onto the feasible set
        q, _ = box_lp(-np.ones(system.m), poly, poly.lower(), poly.upper())
        if q is None or J(q) > alpha:
            raise SolverError("inconsistent", "TCP-like allocation: the SOCP's point is infeasible and so is "
                              "the maximal point of the constraint set")
        tol = ALLOCATION_INCUMBENT_SHARE * gap
        start = mu
        t = boundary(lambda a: J(start + a * (q - start)), alpha, 0.0, 1.0, tol)
        mu = start + t * (q - start)
        note += f"; moved {t:.1e} of the way to a maximal point to meet J* <= alpha"
    mu = check_in_polytope(np.clip(mu, poly.lo, poly.hi), poly, "TCP-like allocation")
    value = float(beta @ mu)
    lower = min(lower, value)
    reached = reported_gap(value, lower, 1.0)           # beta at unit prices (boxes.unit_prices)
    status = "optimal" if reached <= gap else "gap_not_certified"
    return Outcome(mu, value, lower, status, 0, note, J(mu), scale=1.0)


def tcp_min_cost(system: System, poly: Polytope) -> Outcome:
    """min `J*_tcp(mu)` over the polytope: the SOCP, then the closed form at its point (a
    reachable cost) and the LP ``min t`` over the polytope with ``t >= r_k + S_k mu`` for the
    tangent cuts around it (a proven lower bound: the cuts are minorants of `J*_tcp`).

    Raises
    ------
    InfeasibleError
        The constraints admit no mu (HiGHS on the LP, or Clarabel's certificate).
    SolverError
        Any status but optimal.

    Notes
    -----
    One SOCP with O(N (n + m)) variables, two LPs and 6 m + 2 closed forms of
    O(N (n^3 + m^3)).

    Examples
    --------
    Two decoupled copies of x' = x + v u (N = 1): J*_tcp = sum 1/(1 + mu_i); with mu1 + mu2 <= 1
    the least is 4/3, at (1/2, 1/2).

    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> out = tcp_min_cost(t, read_polytope([([[1.0, 1.0]], [1.0])], 2, 0.0, 1.0))
    >>> bool(np.allclose(out.mu, 0.5, atol=1e-4)), bool(out.lower_bound <= 4 / 3 <= out.value + 1e-9)
    (True, True)
    """
    q, _ = small_lp(-np.ones(system.m), poly.G, poly.h, poly.lower(), poly.upper())
    if q is None:
        raise InfeasibleError("the linear constraints and bounds admit no mu", None)
    C = constant_cost(system)
    J, evaluator = cost_function(system, "tcp")
    reference = J(poly.upper()) - C       # the least J* - C over the box
    if system.m == 1:           # J* falls in mu: the least is at the interval's upper end
        mu = np.array([min(interval(poly)[1], float(q[0]))])
        note = "one channel: J* falls in mu, least at the largest admissible mu; lower bound from tangent cuts there"
    else:
        program = TCPProgram.of(system, "min_cost", poly.G.shape[0])
        mu = np.clip(program.solve(system.x0, poly, 1.0 / max(reference, np.finfo(float).tiny)), poly.lo, poly.hi)
        note = "convex SOCP (Clarabel), lower bound from tangent cuts at its point"
    f = J(mu)
    missed = polytope_excess(mu, poly)
    ceiling = max(f, C) if missed <= ALLOCATION_LP_FEASIBILITY else max(f, J(q), C)   # J(q): q is in the polytope
    S, r = tangent_cuts(system, mu, evaluator)                   # min t  s.t.  t >= r_k + S_k mu, mu in the polytope
    size = abs(J(poly.lower()))           # the problem's own size: J* at the box's lower corner, its largest cost
    unit = size if size > 0 else 1.0      # t in units of it: the LP does not see the weights' scale
    S, r = S / unit, r / unit
    m = system.m
    scale = np.maximum(np.max(np.abs(S), axis=1), 1.0)
    G = np.vstack([np.hstack([poly.G, np.zeros((poly.G.shape[0], 1))]),
                   np.hstack([S, -np.ones((len(r), 1))]) / scale[:, None]])
    h = np.concatenate([poly.h, -r / scale])
    c = np.zeros(m + 1)
    c[-1] = 1.0
    point, lower = small_lp(c, G, h, np.append(poly.lower(), C / unit), np.append(poly.upper(), ceiling / unit))
    lower *= unit
    if missed > ALLOCATION_LP_FEASIBILITY:
        # the SOCP's point misses a row by more than the LP tolerance (seen: 3.2e-9): the cut LP's point is in
        # the polytope and, the cuts being tangents at the SOCP's point, as good to second order
        if point is None:
            raise SolverError("inconsistent", "TCP-like minimum cost: the polytope admits q but the cut LP no point")
        mu = check_in_polytope(np.clip(point[:m], poly.lo, poly.hi), poly, "TCP-like minimum cost")
        f = J(mu)
        note += f"; its point missed a row by {missed:.1e}, the cut LP's point taken"
    if point is None:           # (mu, ceiling) meets every cut: an 'infeasible' cut LP failed and proves nothing
        lower = C
        note += "; the cut LP failed, so the lower bound is the constant cost C"
    lower = min(max(lower, C), f)
    reached = reported_gap(f, lower, size)
    status = "optimal" if reached <= MIN_COST_RTOL else "gap_not_certified"
    return Outcome(mu, f, lower, status, 0, note, scale=size)
