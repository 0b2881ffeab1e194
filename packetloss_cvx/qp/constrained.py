"""The expected-cost QP with constraints: input, rate and expected-state bounds and chance constraints (an SOCP).

`ConstrainedQP` poses one protocol's expected cost (eq:opt-lqg-simplest with Lemma 1) in the commanded
inputs ``U`` (N×m) under a `Constraints` (docs/mathematics.md §7) and keeps
everything a cvxpy user reaches for public: ``problem`` (DPP), the variable ``U``, the expected states ``states``
(an (N, n) expression, row k-1 is E[x_k]), and the Parameters ``x0`` and ``mu`` (an (N, m) schedule). Two
formulations give the same problem: "condensed" (E[X] = Phi x0 + Gamma (mu ∘ U) as an expression) and "sparse"
(the mean states as variables, the dynamics as equality constraints). ``solver=`` takes any installed cvxpy
solver (Clarabel by default, under `solve_problem`'s policy). Behind a Markov channel the program is the plug-in
one (Bernoulli losses at the chain's predicted mu_t) but for its chance rows, whose variance is the exact one under
the chain (the deliveries' covariance, one Parameter per channel set from the belief on each solve).

Every solve is checked without cvxpy: the plan's expected cost J(U) on the state's mean by its forward recursion
(`plan_moments`; the solver's objective must agree with it), and the KKT conditions (stationarity, primal and dual
feasibility, complementarity) from the solver's multipliers, the constraints evaluated on the moments of x_k by
their own forward recursion (`plan_moments`) rather than from the matrices the problem was built with. A
residual beyond ``CONSTRAINED_KKT_RTOL`` raises; a proven infeasibility (the solver's certificate verified by
`ConstrainedQP.certificate`) raises [`InfeasibleError`][packetloss_cvx.errors.InfeasibleError] with the solver's
status, an unproven one `SolverError` with the certificate's reason, never a fallback.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.linalg
import scipy.sparse as sp
from cvxpy.reductions.solution import Solution

from ..budgets import chain_states, check_constrained
from ..errors import DimensionError, InfeasibleError, InputError, NumericalError, SolverError
from ..linalg import psd_factor
from ..lq.costs import expected_cost
from ..lq.moments import Moments, plan_moments
from ..lq.policy import refuse_correlated
from ..lq.prediction import prediction
from ..lq.recursion import udp_variance_weights
from ..model.chain import delivery_factor, stacked_moments
from ..model.constraints import Constraints, cantelli_factor, check_constraints
from ..model.protocols import check_protocol
from ..model.system import System, check_system
from ..results.base import Frozen, finite_or_none
from ..tolerances import (
    ACCEPTED_STATUSES,
    CLARABEL_DEFAULT,
    CLARABEL_LINEAR_SOLVER,
    CLARABEL_TIGHT,
    CONSTRAINED_ACTIVE_RTOL,
    CONSTRAINED_ATTEMPTS,
    CONSTRAINED_KKT_RTOL,
    CROSS_CHECK_COST_RTOL,
    CROSS_CHECK_FLOOR,
)
from .convex import PROVEN_INFEASIBLE, ClarabelProgram, solve_problem

__all__ = ["CHAIN_ROWS", "ConstrainedQP", "ConstrainedSolution", "solve_constrained"]

#: ``ConstrainedSolution.chance_rows`` behind a Markov channel: the rows' variance from the deliveries' covariance.
CHAIN_ROWS = "exact under the chain"

#: Above this many decision variables N*m, ``formulation="auto"`` takes the sparse form (as ExpectedCostQP does).
AUTO_CONDENSED_MAX = 60

#: At most this many Newton steps polish a solver's answer on its active set (linear rows: one step; the chance rows'
#: norms: quadratic convergence from the solver's ~1e-5 accurate point).
POLISH_MAX_STEPS = 20
#: ... and the active set is corrected (a violated row joins, a negative multiplier leaves) at most this many times.
POLISH_MAX_ROUNDS = 10
#: ... and Newton stops where its steps, below this (relative to max|U|), stop shrinking: the rounding of a degenerate
#: active set (dependent rows, e.g. an input bound and the rate bound beside it), whose KKT matrix is singular.
POLISH_STALL = 1e-9
#: A row is taken as active (or a soft row as violated) for the polish's first round where it is within this of its
#: bound (relative to max(1, |b|)): the solver's plan is accurate to about the square root of its gap, 1e-4 at
#: Clarabel's default 1e-8 (a chance-constrained problem the tight 1e-10 stalls on). Rows wrongly taken leave by
#: their multipliers' signs.
POLISH_IDENTIFY = 1e-4


@dataclass(frozen=True)
class ConstrainedSolution(Frozen):
    """A constrained plan and what bound it.

    Attributes
    ----------
    protocol : {"tcp", "udp"}
    status : str
        The solver's status ("optimal"; anything else raised).
    cost : float
        The plan's expected cost J(U) on E[x_k] by their forward recursion (penalties of soft constraints not
        included).
    inputs : ndarray (N, m)
        The commanded inputs.
    states : ndarray (N, n)
        E[x_k], k = 1..N, under the plan.
    binding : tuple of str
        The constraints active at the plan ("u_max[0] at t=2", "chance[1] at k=5", ...).
    violations : tuple of (str, float)
        Soft constraints violated at the plan and by how much (the slack); empty for a hard problem.
    kkt_residual : float or None
        The largest relative KKT residual (`ConstrainedQP.kkt`), None where user constraints were added.
    formulation, solver : str
    solve_time : float
        Seconds in the solver call.
    solver_kkt_residual : float or None
        The KKT residual of the solver's own answer, before the polish.
    polished : bool
        Whether the plan is the solver's answer refined by Newton's method on its active set
        (`ConstrainedQP._polish`), kept only where its KKT residual is no larger than the solver's.
    chance_rows : str
        ``"exact under the chain"`` behind a Markov channel (the chance rows' variance from the deliveries'
        covariance), ``""`` under Bernoulli losses.
    basis : str
        What ``cost`` is (docs/design.md, "Cost bases"): ``"paper"`` for the TCP-like program (the paper's
        first-moment J_tcp(U), which leaves out the loss variance a plan applied whatever the losses pays),
        ``"realised"`` for the UDP-like one (J_udp(U) is the plan's exact expected cost).
    plan_expected_cost : float or None
        The plan's exact expected realised cost, J_udp(U) (`expected_cost`): ``cost`` itself for UDP-like, above it
        for TCP-like by the loss variance; None where it is not resolved in double precision.
    """

    protocol: str
    status: str
    cost: float
    inputs: np.ndarray
    states: np.ndarray
    binding: tuple[str, ...]
    violations: tuple[tuple[str, float], ...]
    kkt_residual: float | None
    formulation: str
    solver: str
    solve_time: float
    solver_kkt_residual: float | None = None
    polished: bool = False
    basis: str = ""
    plan_expected_cost: float | None = None
    chance_rows: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The JSON entry of ``solve --json`` ("constrained"; ``terminal_state`` is E[x_N] under the plan;
        ``chance_rows`` behind a chain only)."""
        extra = {"chance_rows": self.chance_rows} if self.chance_rows else {}
        return {"status": self.status, "cost": self.cost, "basis": self.basis,
                "plan_expected_cost": finite_or_none(self.plan_expected_cost), "inputs": self.inputs.tolist(),
                "terminal_state": self.states[-1].tolist(), "binding": list(self.binding),
                "violations": [{"constraint": c, "by": v} for c, v in self.violations],
                "kkt_residual": finite_or_none(self.kkt_residual),
                "solver_kkt_residual": finite_or_none(self.solver_kkt_residual),
                "polished": self.polished, "formulation": self.formulation, "solver": self.solver, **extra}


def _step_major(expr: cp.Expression, rows: int, cols: int) -> cp.Expression:
    """An (rows, cols) expression as a vector, row after row (U's flat layout: step-major)."""
    return cp.reshape(expr, (rows * cols,), order="C")


class ConstrainedQP:
    """One protocol's expected-cost minimisation under constraints, compiled once, re-solvable for new x0 or mu.

    .. math:: \\min_U J(U)\\ \\text{s.t.}\\ u_{min} \\le u_t \\le u_{max},\\ |u_t - u_{t-1}| \\le du_{max},\\
              x_{min} \\le E[x_k] \\le x_{max},\\ F E[x_k] \\le g,\\
              a'E[x_k] + \\sqrt{(1-\\epsilon)/\\epsilon}\\,\\|\\Sigma_k^{1/2} a\\| \\le b

    Parameters
    ----------
    system : System
        Bernoulli losses (a stationary channel or a schedule), or a Markov channel: then the program is the plug-in
        one (its cost the protocol's on the chain's predicted mu_t, basis "paper, prior-mean rates") with its chance
        rows exact under the chain, their variance ``c_k' C_k c_k + a'S_k a`` from the deliveries' covariance
        (`delivery_factor`; docs/mathematics.md §7, "Behind a chain"), set from the belief on each `solve`.
    protocol : {"tcp", "udp"}
    constraints : Constraints or mapping (the ``[constraints]`` table)
    formulation : {"condensed", "sparse", "auto"}
    solver : str, optional
        Any installed cvxpy solver (``cp.installed_solvers()``); default Clarabel with tight tolerances.
    solver_options : dict, optional
        Passed to ``problem.solve`` (one solve with them, in place of the default's tight-then-default attempts).
        With Clarabel they are merged onto the linear-solver pin, ``direct_solve_method =
        tolerances.CLARABEL_LINEAR_SOLVER`` (QDLDL, the same answers whatever the BLAS kernel and the KKT
        system's size): the caller's keys win, so the pin holds unless they set ``direct_solve_method``.
    u_prev : bool
        Link the first input to the previous command: ``|u_0 - u_prev| <= du_max`` (rows "du_max[i] at t=0 (up)",
        "(down)"), ``u_prev`` a Parameter that `solve` sets (a receding-horizon loop's last command; zero, the
        actuator at rest, where not given). Without ``du_max`` it adds no row.

    Attributes
    ----------
    problem : cvxpy.Problem
        DPP; its objective is J(U) less its constant terms, divided by the largest weight.
    U : cvxpy.Variable (N, m)
        After `solve` its value is the solver's own answer; the returned plan is that answer polished
        (``ConstrainedSolution.polished``).
    states : cvxpy.Expression (N, n)
        E[x_1..x_N] under the plan.
    x0, mu : cvxpy.Parameter
        n and (N, m); `solve` sets them (and the Parameters derived from mu; behind a chain the per-channel
        innovations factors of the deliveries' covariance, K × N K and N per channel, from the belief).
    u_prev : cvxpy.Parameter or None
        m, with ``u_prev=True``; `solve` sets it.

    Examples
    --------
    One step of x' = x + v u from x0 = 1, mu = 1/2, Q = R = 1: the TCP-like optimum u = -2/3 (closed form) is cut
    to u_min = -1/2, where E[x_1] = 3/4 and J = (3/4)^2 + mu R u^2 = 9/16 + 1/8 by hand.

    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> qp = ConstrainedQP(s, "tcp", Constraints(u_min=[-0.5]))
    >>> sol = qp.solve()
    >>> bool(np.isclose(sol.inputs[0, 0], -0.5)), bool(np.isclose(sol.cost, 9 / 16 + 1 / 8)), sol.binding
    (True, True, ('u_min[0] at t=0',))
    >>> qp.problem.is_dpp()
    True
    """

    def __init__(self, system: System, protocol: str, constraints: Constraints | Any, formulation: str = "auto",
                 solver: str | None = None, solver_options: dict | None = None, u_prev: bool = False) -> None:
        system = check_system(system)
        self.protocol = check_protocol(protocol)
        #: behind a Markov channel, the system with its chain: the chance rows' delivery covariance (`solve` moves
        #: its belief); ``system`` is then its plug-in twin, Bernoulli losses at the chain's predicted mu_t
        self.chain: System | None = system if system.channel is not None else None
        if self.chain is not None:
            system = system.with_mu(system.mu_schedule)
        refuse_correlated(system, self.protocol)
        self.system = system
        N, n, m = system.horizon, system.n, system.m
        self.constraints = check_constraints(constraints, n, m)
        # the program's size priced before cvxpy sees it (budgets.py): the dense KKT work grows as N^3
        # (behind a chain its chance rows priced as the chain's: denser cones)
        check_constrained(N, n, m, self.constraints.program_rows(N), len(self.constraints.chance), "horizon",
                          instead="use a shorter horizon",
                          states=chain_states(None if self.chain is None else self.chain.channel))
        if formulation == "auto":
            formulation = "condensed" if N * m <= AUTO_CONDENSED_MAX else "sparse"
        if formulation not in ("condensed", "sparse"):
            raise InputError("formulation", f"expected 'condensed', 'sparse' or 'auto', found {formulation!r}")
        self.formulation = formulation
        if solver is not None and solver not in cp.installed_solvers():
            raise InputError("solver", f"expected an installed cvxpy solver ({', '.join(cp.installed_solvers())}), "
                                       f"found {solver!r}")
        self.solver = solver or cp.CLARABEL
        self.solver_options = dict(solver_options or {})
        if not isinstance(u_prev, bool | np.bool_):
            raise InputError("u_prev", f"expected true or false (whether the first input is linked to the previous "
                                       f"command), found {u_prev!r}")
        self.u_prev = cp.Parameter(system.m, name="u_prev") if u_prev else None
        self._d, self._noise = udp_variance_weights(system)
        if not (np.all(np.isfinite(self._d)) and np.isfinite(self._noise)):
            raise NumericalError("the QP's loss-variance weights diag(Omega_g) exceed the double-precision range")
        #: the objective's scale: J's variable part divided by the largest weight
        self.scale = max(float(system.input_weights.max()), float(np.linalg.eigvalsh(system.state_weights).max()))
        self._user_constraints = False
        #: the problem compiled for Clarabel (`ClarabelProgram`), on the first solve with the default solver
        self._program: ClarabelProgram | None = None
        #: why a default-solver solve goes through ``problem.solve`` instead ("" while the compiled program serves)
        self.fast_path_refused = ""
        #: (the system last asked for, its mu's key, the moments of the plan U = 0 under that mu, its x0's key, the
        #: free means A^k x0)
        self._base: tuple[System, bytes, Moments, bytes, np.ndarray] | None = None
        #: the belief whose delivery covariance the chance rows hold (behind a chain)
        self._chain_key: bytes | None = None
        self._build()

    # ------------------------------------------------------------------------------------------------ building
    def _build(self) -> None:
        system, c = self.system, self.constraints
        N, n, m = system.horizon, system.n, system.m
        s = self.scale
        self.x0 = cp.Parameter(n, name="x0")
        self.mu = cp.Parameter((N, m), nonneg=True, name="mu")
        self._w = cp.Parameter((N, m), nonneg=True, name="input_weight_over_scale")   # (psi mu + [UDP] d mu(1-mu))/s
        self._sigma = cp.Parameter((N, m), nonneg=True, name="loss_std")             # sqrt(mu (1 - mu))
        # behind a chain: per channel the belief's part of the innovations factor of its deliveries' covariance
        # (`DeliveryFactor`): G_s as a (K, N K) Parameter, [a, s K + b] = G_s[a, b], and sqrt(gamma_t) as an N one; the
        # chain's part, the responses e_L, is constant
        self._factors = None
        if self.chain is not None and c.chance:
            K = max(self.chain.channel.sizes)
            self._response = delivery_factor(self.chain).response          # (m, N, K): no belief in it
            self._factors = [(cp.Parameter((K, N * K), name=f"delivery_innovation_{i}"),
                              cp.Parameter(N, nonneg=True, name=f"delivery_spread_{i}")) for i in range(m)]
        self.U = cp.Variable((N, m), name="U")
        u = _step_major(self.U, N, m)
        y = _step_major(cp.multiply(self.mu, self.U), N, m)        # the mean delivered inputs Vbar U
        constraints: list[cp.Constraint] = []
        if self.formulation == "condensed":
            pred = prediction(system)
            X = pred.Phi @ self.x0 + pred.Gamma @ y
        else:
            E = sp.eye(N * n, format="csr") - sp.kron(sp.eye(N, k=-1), system.A, format="csr")
            first = sp.csr_matrix(np.vstack([system.A, np.zeros(((N - 1) * n, n))]))
            X = cp.Variable(N * n, name="xhat")
            constraints.append(E @ X - sp.kron(sp.eye(N), system.B, format="csr") @ y == first @ self.x0)
        self.states = cp.reshape(X, (N, n), order="C")
        L = sp.block_diag([psd_factor(W) for W in system.state_weights], format="csr") / np.sqrt(s)
        terms = [cp.sum(cp.multiply(self._w, cp.square(self.U)))]
        if L.shape[0]:
            terms.append(cp.sum_squares(L @ X))
        penalty = []
        self._groups: list[_Group] = []
        # inputs and rates: hard (U = u_prev at every step satisfies them, u_prev within the input bounds; U = 0
        # without u_prev); the rows of u_0 against u_prev have the bound hu + Su u_prev
        Gu, hu, Su, labels = _input_rows(c, N, m, self.u_prev is not None)
        if labels:
            con = Gu @ u <= (hu + Su @ self.u_prev if Su.nnz else hu)
            constraints.append(con)
            self._groups.append(_Group("inputs", con, labels, hu, None, P=Gu, offset=Su if Su.nnz else None))
        # expected state: box and polyhedron, rows P E[X] <= q
        P, q, labels = _state_rows(c, N, n)
        if labels:
            slack = cp.Variable(len(labels), nonneg=True, name="state_slack") if c.soft else None
            con = P @ X <= q + (slack if slack is not None else 0)
            constraints.append(con)
            self._groups.append(_Group("states", con, labels, q, slack, P=P))
            if slack is not None:
                penalty.append(cp.sum(slack))
        # chance constraints, one SOC per row and step
        if c.chance:
            W = _step_major(cp.multiply(self._sigma, self.U), N, m)
            for i, (a, b, eps) in enumerate(c.chance):
                H, noise = _chance_data(system, a)
                kappa = cantelli_factor(eps)
                slack = cp.Variable(N, nonneg=True, name=f"chance_{i}_slack") if c.soft else None
                cons = []
                for k in range(1, N + 1):
                    nz = np.flatnonzero(H[k - 1])
                    if self._factors is None:           # independent losses: diag(sqrt(mu (1 - mu)))
                        parts = [cp.multiply(H[k - 1, nz], W[nz])] if nz.size else []
                    else:                               # || F_k' (h_k ∘ u) ||, one term per channel
                        parts = []
                        for ch, (innovation, spread) in enumerate(self._factors):
                            h = H[k - 1, ch::m]
                            last = int(np.flatnonzero(h).max(initial=-1)) + 1     # F's rows t < last, columns s <= t
                            if last:
                                parts += _chain_terms(self._response[ch], innovation, spread,
                                                      cp.multiply(h[:last], self.U[:last, ch]), last)
                    if noise[k - 1] > 0:
                        parts.append(np.array([np.sqrt(noise[k - 1])]))
                    lhs = a @ self.states[k - 1]
                    if parts:
                        lhs = lhs + kappa * cp.norm(cp.hstack(parts) if len(parts) > 1 else parts[0], 2)
                    cons.append(lhs <= b + (slack[k - 1] if slack is not None else 0))
                constraints += cons
                self._groups.append(_Group("chance", cons, [f"chance[{i}] at k={k}" for k in range(1, N + 1)],
                                           np.full(N, b), slack, chance=(a, b, kappa)))
                if slack is not None:
                    penalty.append(cp.sum(slack))
        self._penalty = cp.sum(cp.hstack(penalty)) if penalty else None
        objective = cp.sum(cp.hstack(terms))
        if self._penalty is not None:
            objective = objective + (c.soft_weight / s) * self._penalty
        self.problem = cp.Problem(cp.Minimize(objective), constraints)
        if not self.problem.is_dpp():  # pragma: no cover - construction guarantees it
            raise RuntimeError("the constrained expected-cost QP is not DPP")

    def add_constraints(self, constraints: list[cp.Constraint]) -> None:
        """Add the user's own cvxpy constraints (on ``U``, ``states``, ...) to ``problem``. The KKT check then covers
        only the package's constraints, so it is skipped (``kkt_residual`` None). O(1) (compiled on the next solve).
        """
        self.problem = cp.Problem(self.problem.objective, [*self.problem.constraints, *constraints])
        self._user_constraints = True
        self._program, self.fast_path_refused = None, ""          # compiled again, with them, on the next solve

    # ------------------------------------------------------------------------------------------------ solving
    def _assign(self, system: System, chain: System | None = None) -> None:
        """The Parameters' values for ``system`` (and behind a chain ``chain``, whose deliveries' covariance the
        chance rows take: `delivery_factor`, kept while the belief is the same). They come from a validated System
        (x0 finite, mu in [0, 1], the weights nonnegative) as float arrays of the Parameters' shapes, nonnegative
        where a Parameter is declared so, and are saved as cvxpy's ``value`` setter saves them after its validation
        (``Leaf.save_value``), which would repeat what System checked (0.07 ms of a two_actuator re-solve of about
        2.5)."""
        if self._factors is not None:
            key = chain.channel.initial_belief.tobytes()
            if self._chain_key != key:
                factor, (_, cov) = delivery_factor(chain), stacked_moments(chain)
                for (innovation, spread), G, root in zip(self._factors, factor.innovation, factor.spread, strict=True):
                    innovation.save_value(G.transpose(1, 0, 2).reshape(innovation.shape))
                    spread.save_value(root)
                for group in self._groups:
                    if group.kind == "chance":
                        group.loss_cov = cov
                self._chain_key = key
        mu = system.mu_schedule
        d = self._d * (1.0 - mu) if self.protocol == "udp" else 0.0
        for parameter, value in ((self.x0, system.x0), (self.mu, mu), (self._w, (system.input_weights + d) * mu
                                                                       / self.scale),
                                 (self._sigma, np.sqrt(mu * (1.0 - mu)))):
            parameter.save_value(np.array(value, dtype=float).reshape(parameter.shape))

    def _link(self, u_prev: Any) -> None:
        """Set ``u_prev`` (Parameter and the rows' bounds) for a solve, checked: m finite numbers. O(m + rows)."""
        if self.u_prev is None:
            if u_prev is not None:
                raise InputError("u_prev", "this program has no previous command: build it with "
                                           "ConstrainedQP(..., u_prev=True)")
            return
        m = self.system.m
        try:
            value = np.zeros(m) if u_prev is None else np.asarray(u_prev, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError("u_prev", f"expected {m} numbers, found {u_prev!r}"[:200]) from None
        if value.shape != (m,):
            raise DimensionError("u_prev", f"expected {m} numbers (m = {m}) but found shape {value.shape}")
        if not np.all(np.isfinite(value)):
            raise InputError("u_prev", "expected finite numbers")
        self.u_prev.save_value(value)
        for group in self._groups:
            group.link(value)

    def _run_solver(self, what: str) -> str:
        if self.solver == cp.CLARABEL and not self.solver_options:
            program = self._compiled()
            if program is not None:
                return self._run_compiled(program, what)
            return solve_problem(self.problem, what, attempts=(CLARABEL_TIGHT, CLARABEL_DEFAULT))
        options = self.solver_options
        if self.solver == cp.CLARABEL:      # the pin under the caller's options: theirs win where they set it
            options = {"direct_solve_method": CLARABEL_LINEAR_SOLVER, **options}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                self.problem.solve(solver=self.solver, **options)
            except cp.error.SolverError as err:
                raise SolverError("solver_error", f"{what} ({self.solver}): {err}") from None
        return str(self.problem.status)

    def _compiled(self) -> ClarabelProgram | None:
        """The problem compiled once for Clarabel (`ClarabelProgram`: each solve maps the Parameters onto the cone
        program and runs ``CONSTRAINED_ATTEMPTS``, the unequilibrated ones on a kept solver given the new data), or
        None, with the reason in ``fast_path_refused``, where cvxpy's compilation cannot be driven directly (then
        ``problem.solve`` runs, as for any other solver)."""
        if self._program is None and not self.fast_path_refused:
            try:
                program = ClarabelProgram(self.problem, duals=True)
            except (ValueError, cp.error.DCPError, cp.error.SolverError) as err:
                self.fast_path_refused = f"the compiled Clarabel program is refused ({err}): problem.solve runs"
                return None
            self._program, self._parameters = program, self.problem.parameters()
        return self._program

    def _run_compiled(self, program: ClarabelProgram, what: str) -> str:
        """One solve on the compiled program under `solve_problem`'s policy, unpacked into ``problem`` as
        ``problem.solve`` would (variables, multipliers, ``problem.value`` and ``problem.status``). O(nnz) plus
        Clarabel's iterations."""
        values = {p: p.value for p in self._parameters}
        status, point = program.solve(values, what, attempts=CONSTRAINED_ATTEMPTS)
        duals = program.duals(point)
        if status in cp.settings.SOLUTION_PRESENT:
            solution = Solution(status, point.value, program.primals(point), duals, {})
        elif status in cp.settings.INF_OR_UNB:
            solution = Solution(status, np.inf, {}, duals, {})
        else:
            return status
        self.problem.unpack(solution)
        return status

    def solve(self, mu=None, x0=None, *, belief=None, u_prev=None, check: bool = True) -> ConstrainedSolution:
        """Solve for the system's (or the given) ``mu`` (m-vector or N×m schedule) and ``x0``, validated through
        [`System`][packetloss_cvx.model.system.System], and (built with ``u_prev=True``) the previous command
        ``u_prev`` (m finite numbers; zero where not given). Behind a Markov channel the schedule is the chain's
        prediction from its ``belief`` ((m, K), the state distribution at the plan's first step; default the
        channel's own), which also sets the chance rows' delivery covariance; ``mu`` is then refused.

        Raises
        ------
        InfeasibleError
            The solver proved the constraints infeasible with a certificate that `certificate` verifies
            (``status`` carries its status, ``certificate`` the check); with ``soft`` only the
            input and rate bounds are hard, and U = 0 (U = u_prev at every step, with ``u_prev`` inside the input
            bounds) satisfies them, so this cannot happen.
        SolverError
            Any other status than "optimal" (``optimal_inaccurate`` and ``infeasible_inaccurate`` included), and
            "infeasible" whose certificate is undecided (chance rows, unbounded inputs, a margin within rounding):
            ``certificate`` then carries the verdict and its reason.
        NumericalError
            With ``check``, a plan whose forward cost disagrees with the solver's objective beyond
            ``CROSS_CHECK_COST_RTOL``, or whose KKT residual (`kkt`) exceeds ``CONSTRAINED_KKT_RTOL``.
        """
        system, chain = self.system, self.chain
        if chain is None and belief is not None:
            raise InputError("belief", "a belief moves a Markov channel's prediction: this program has Bernoulli "
                                       "losses (give mu)")
        if chain is not None:
            if mu is not None:
                raise InputError("mu", "behind a Markov channel the delivery probabilities are the chain's "
                                       "prediction: give its belief (belief=[...]) instead")
            if belief is not None:
                chain = chain.with_channel(chain.channel.with_belief(chain.channel.check_belief(belief)))
                system = system.with_mu(chain.mu_schedule)
        if mu is not None:
            system = system.with_mu(mu)
        if x0 is not None:
            system = system.with_x0(x0)
        self._link(u_prev)
        self._assign(system, chain)
        what = f"the constrained {self.protocol}-like {self.formulation} QP"
        start = time.perf_counter()
        status = self._run_solver(what)
        solve_time = time.perf_counter() - start
        if status == PROVEN_INFEASIBLE:
            certificate = self.certificate(system)
            if certificate["verdict"] != "verified":     # the solver's word alone is not a proof
                raise SolverError(status, f"{what}: {self.solver} says infeasible but its certificate is undecided "
                                  f"({certificate['reason']}): no plan is proved or found for "
                                  f"{', '.join(self.constraints.kinds())} from this x0; make the state limits soft "
                                  "(soft = true) or relax them", certificate=certificate)
            raise InfeasibleError(f"{what} is infeasible ({self.solver} status {status!r}; certificate "
                                  f"{certificate['verdict']}): no plan meets {', '.join(self.constraints.kinds())} "
                                  "from this x0; make the state limits soft (soft = true) or relax them",
                                  status=status, certificate=certificate)
        if status not in ACCEPTED_STATUSES:
            raise SolverError(status, f"{what} ({self.solver}) gave no proven answer")
        N, m = system.horizon, system.m
        U = np.asarray(self.U.value, dtype=float).reshape(N, m)
        report = self.kkt(system, U)
        solver_kkt = report["residual"]
        # the solver's objective against the forward cost of its plan (the kkt report's J, on the plan's moments)
        cost = report["cost"]
        penalty = 0.0 if self._penalty is None else self.constraints.soft_weight * float(self._penalty.value)
        solver_cost = float(self.problem.value) * self.scale + self._constant(system) - penalty
        if check and not abs(solver_cost - cost) <= CROSS_CHECK_COST_RTOL * max(abs(cost), self.scale * 1e-9):
            raise NumericalError(f"{what}: the solver's objective {solver_cost:.10g} and the forward cost of its plan "
                                 f"{cost:.10g} disagree beyond {CROSS_CHECK_COST_RTOL:.0e} relative")
        polished = False
        if not self._user_constraints and self._groups:
            refined = self._polish(system, U, report)
            if refined is not None:
                better = self.kkt(system, *refined)
                if better["residual"] <= report["residual"]:
                    U, report, polished = refined[0], better, True
        cost = report["cost"]                          # J of the returned plan on its moments (the forward recursion)
        kkt = None if self._user_constraints else report["residual"]
        if check and kkt is not None and not kkt <= CONSTRAINED_KKT_RTOL:
            raise NumericalError(f"{what}: the KKT residual of the solver's answer is {kkt:.2e} ({report['worst']}), "
                                 f"beyond {CONSTRAINED_KKT_RTOL:.0e}: the answer is not trusted")
        if self.protocol == "udp":
            realised: float | None = float(cost)
        else:
            try:
                realised = expected_cost(system, U, "udp")
            except NumericalError:
                realised = None
        return ConstrainedSolution(
            protocol=self.protocol, status=status, cost=float(cost), inputs=U,
            basis="paper" if self.protocol == "tcp" else "realised", plan_expected_cost=realised,
            states=self._moments(system, U).mean[1:], binding=tuple(report["binding"]),
            violations=tuple(report["violations"]), kkt_residual=kkt, formulation=self.formulation,
            solver=self.solver, solve_time=solve_time, solver_kkt_residual=None if self._user_constraints
            else solver_kkt, polished=polished, chance_rows="" if self.chain is None else CHAIN_ROWS)

    def certificate(self, system: System) -> dict[str, Any]:
        """The solver's infeasibility certificate (cvxpy's multipliers after an "infeasible" status), checked without
        the solver. For linear rows ``G u <= h`` (input, rate and expected-state limits, evaluated on
        `plan_moments`), multipliers ``y >= 0`` with ``-y'h > ||G'y||_1 max|u|`` prove that no plan exists:
        ``y'(G u - h) <= 0`` would fail for every u within the input bounds, which every plan meets. Returns
        ``{"verdict", "reason", "margin", "multipliers"}``: verdict "verified" (the inequality holds with the
        rounding of the sums bounded), else "undecided" with the reason (chance rows, whose cone multipliers cvxpy
        does not hand back whole; unbounded inputs; a margin within rounding). O(rows N m).
        """
        try:
            multipliers = [np.asarray(group.multipliers(), dtype=float) for group in self._groups]
        except (TypeError, ValueError):
            multipliers = None
        out: dict[str, Any] = {"verdict": "undecided", "reason": "", "margin": None,
                               "multipliers": None if multipliers is None else [y.tolist() for y in multipliers]}
        if multipliers is None or any(not np.all(np.isfinite(y)) for y in multipliers):
            out["reason"] = "the solver gave no multipliers"
            return out
        if any(group.kind == "chance" for group in self._groups) or self.constraints.soft:
            out["reason"] = "chance rows: a certificate needs their cone multipliers, which cvxpy does not return whole"
            return out
        c = self.constraints
        if c.u_min is None or c.u_max is None or not (np.all(np.isfinite(c.u_min)) and np.all(np.isfinite(c.u_max))):
            out["reason"] = "the inputs are not bounded on every channel: the certificate's rounding cannot be bounded"
            return out
        N, m = system.horizon, system.m
        mom = plan_moments(system, np.zeros((N, m)))
        combo, value, size = np.zeros(N * m), 0.0, 0.0
        for group, y in zip(self._groups, multipliers, strict=True):
            if np.any(y < 0):                           # a certificate's multipliers are nonnegative
                out["reason"] = f"a negative multiplier ({float(y.min()):.3g}) on the {group.kind} rows"
                return out
            g, jac, _ = group.evaluate(mom, np.zeros(N * m), system)   # g(0) = -h (the rows at u = 0), jac = G
            combo += jac.T @ y
            value += float(y @ g)                       # y'(G 0 - h) = -y'h
            size += float(np.abs(y) @ (np.abs(g) + np.abs(jac).sum(axis=1)))
        reach = float(np.max(np.maximum(np.abs(c.u_min), np.abs(c.u_max))))
        margin = value - float(np.abs(combo).sum()) * reach      # min over the input box of y'(G u - h) >= margin
        rounding = 8 * N * m * np.finfo(float).eps * size * max(1.0, reach)
        out["margin"] = margin
        if margin > rounding:
            out["verdict"], out["reason"] = "verified", f"y'(G u - h) >= {margin:.3g} > 0 on the input box"
        else:
            out["reason"] = f"the margin {margin:.3g} does not exceed its rounding {rounding:.1e}"
        return out

    def _polish(self, system: System, U: np.ndarray, report: dict[str, Any]
                ) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]] | None:
        """Newton's method on the KKT equations of the active set the solver's answer shows, from its plan and
        multipliers: rows active (within ``CONSTRAINED_ACTIVE_RTOL``) held as equalities with their multipliers, soft
        rows with a positive slack entering J with the weight rho, the rest left out; a row the step violates joins
        the active set, an active row whose multiplier turns negative (or, soft, beyond rho) leaves it, and Newton
        runs again, at most ``POLISH_MAX_ROUNDS`` times. An interior-point answer is accurate to about the square root
        of its absolute gap in U; the active set's equations, quadratic but for the chance rows' norms, are solved to
        rounding. Returns ``(U, multipliers, slacks)`` per block, or None where no round settles; `solve` keeps
        it only where its own KKT residual is no larger than the solver's.
        O(rounds steps (N^2 n m (n + m) + (N m + rows)^3)).
        """
        N, m = system.horizon, system.m
        rho = self.constraints.soft_weight
        mu = system.mu_schedule
        w = ((system.input_weights + (self._d * (1.0 - mu) if self.protocol == "udp" else 0.0)) * mu).ravel()
        mom = self._moments(system, U)
        H_J = 2.0 * np.diag(w) + 2.0 * _weighted_gram(mom.T[1:], system.state_weights)
        u0 = U.ravel().copy()
        sizes = [np.maximum(1.0, np.abs(group.bound)) for group in self._groups]
        soft = [group.slack is not None for group in self._groups]
        active, penalised, lam = [], [], []
        for group, size, is_soft, multiplier, slack in zip(self._groups, sizes, soft, report["multipliers"],
                                                           report["slacks"], strict=True):
            g, _, _ = group.evaluate(mom, u0, system)
            pen = (slack > POLISH_IDENTIFY * size) if is_soft else np.zeros(g.size, bool)
            active.append(~pen & (g - slack >= -POLISH_IDENTIFY * size))
            if any(active[-1][row] or pen[row] for row in group.kinks):
                return None        # a row at the norm's kink has no Newton equation: the solver's answer stands
            penalised.append(pen)
            lam.append(np.where(active[-1], multiplier, 0.0))

        def newton() -> np.ndarray | None:
            u, previous = u0.copy(), np.inf
            for _ in range(POLISH_MAX_STEPS):
                mom = self._moments(system, u)
                grad = 2.0 * w * u + 2.0 * _weighted_pull(mom.T[1:], system.state_weights, mom.mean[1:])
                H = H_J.copy()
                rows, values = [], []
                for group, act, pen, la in zip(self._groups, active, penalised, lam, strict=True):
                    weight = np.where(pen, rho, np.where(act, la, 0.0))        # each row's weight in the Lagrangian
                    g, jac, curvature = group.evaluate(mom, u, system, curvature=weight)
                    grad += rho * jac[pen].sum(axis=0) + jac[act].T @ la[act]
                    if curvature is not None:
                        H += curvature
                    rows.append(jac[act])
                    values.append(g[act])
                J_A = np.vstack(rows)
                K = np.zeros((u.size + J_A.shape[0],) * 2)
                K[:u.size, :u.size], K[:u.size, u.size:], K[u.size:, :u.size] = H, J_A.T, J_A
                # least squares of least norm (a degenerate active set's K is singular), by pivoted QR
                step = scipy.linalg.lstsq(K, -np.concatenate([grad, *values]), lapack_driver="gelsy",
                                          check_finite=False)[0]
                if not np.all(np.isfinite(step)):
                    return None
                u += step[:u.size]
                taken = u.size
                for act, la in zip(active, lam, strict=True):
                    count = int(act.sum())
                    la[act] += step[taken:taken + count]
                    taken += count
                size, floor = np.abs(step[:u.size]).max(initial=0.0), max(1.0, np.abs(u).max())
                if size <= 4 * np.finfo(float).eps * floor:
                    return u
                if size <= POLISH_STALL * floor and size > previous / 2:   # a degenerate active set's rounding
                    return u
                previous = size
            return None

        for _ in range(POLISH_MAX_ROUNDS):
            u = newton()
            if u is None:
                return None
            mom = self._moments(system, u)
            changed = False
            lam_max = max(float(np.max(np.abs(la), initial=0.0)) for la in lam) or 1.0
            for group, act, pen, la, size, is_soft in zip(self._groups, active, penalised, lam, sizes, soft,
                                                          strict=True):
                g, _, _ = group.evaluate(mom, u, system)
                joins = ~act & ~pen & (g > CONSTRAINED_ACTIVE_RTOL * size)      # violated: held as an equality
                if is_soft:
                    to_penalty = act & (la > rho * (1 + CONSTRAINED_ACTIVE_RTOL))
                    back = pen & (g < -CONSTRAINED_ACTIVE_RTOL * size)         # a penalised row now satisfied
                    pen[to_penalty], pen[back] = True, False
                    act[to_penalty] = False
                    joins &= ~to_penalty
                    changed |= bool(to_penalty.any() or back.any())
                leaves = act & (la < -CONSTRAINED_ACTIVE_RTOL * lam_max)
                act[leaves], la[leaves] = False, 0.0
                act[joins], la[joins] = True, 0.0
                changed |= bool(joins.any() or leaves.any())
            if not changed:
                break
        else:
            return None
        multipliers, slacks = [], []
        for group, act, pen, la in zip(self._groups, active, penalised, lam, strict=True):
            g, _, _ = group.evaluate(mom, u, system)
            multipliers.append(np.where(pen, rho, np.where(act, la, 0.0)))
            slacks.append(np.where(pen, np.maximum(g, 0.0), 0.0))
        return u.reshape(N, m), multipliers, slacks

    def _constant(self, system: System) -> float:
        """J's terms that no plan moves: ``x0' Omega_0 x0`` and the noise's."""
        return float(system.x0 @ system.initial_weight @ system.x0) + self._noise

    def _moments(self, system: System, U: np.ndarray) -> Moments:
        """``plan_moments(system, U)`` for the checks and the polish, which evaluate many plans of one (mu, x0): the
        forward recursion runs once per mu for the plan U = 0 (its ``T``, ``C``, ``S`` depend on neither the plan nor
        x0), the free means A^k x0 once per x0 by the same recursion without inputs, and a plan moves the mean by
        ``T U`` and the covariance by ``(C diag(u)) (C diag(u))'``, the recursion's own sums in closed form.
        O(N^2 n m (n + m)) for a new mu, O(N n^2) for a new x0, O(N^2 n m n) per plan."""
        if self._base is None or self._base[0] is not system:         # a System is immutable: its moments stay
            key = b"".join(np.ascontiguousarray(x, dtype=float).tobytes()
                           for x in (system.mu_schedule, system.A, system.B, system.noise_cov))
            if self._base is None or self._base[1] != key:
                base = plan_moments(system, np.zeros((system.horizon, system.m)))
                self._base = (system, key, base, system.x0.tobytes(), base.mean)
            if self._base[3] != system.x0.tobytes():
                free = np.empty_like(self._base[4])
                free[0] = system.x0
                for k in range(system.horizon):
                    free[k + 1] = system.A @ free[k]
                self._base = (system, *self._base[1:3], system.x0.tobytes(), free)
            self._base = (system, *self._base[1:])
        _, _, base, _, free = self._base
        u = np.asarray(U, dtype=float).ravel()
        spread = base.C * u
        return Moments(free + base.T @ u, spread @ spread.transpose(0, 2, 1) + base.S, base.T, base.C, base.S)

    def data_scale(self, system: System) -> tuple[float, float]:
        """``(size, weight)``: the size of the states and inputs the problem's data speak of, the largest of max|x0|,
        the noise's spread over the horizon ``sqrt(N ||Sigma_W||)``, every finite bound (a state row's ``|b| /
        ||a||``, an input's or a rate's ``|b|``), and its largest weight (state, initial or input). `kkt` floors its
        relative residuals at ``CROSS_CHECK_FLOOR`` of the cost ``weight size^2`` and of the slope ``weight size``
        (a multiplier's and a gradient's units): below that a term is rounding. Zero ``size`` only where nothing is
        bounded, x0 = 0 and there is no noise. O(n + m + rows).

        Examples
        --------
        >>> s = System(A=[[1]], B=[[1]], horizon=4, state_weight=[3], input_weight=[1], mu=[0.5], x0=[0])
        >>> ConstrainedQP(s, "tcp", Constraints(x_max=[2.0], u_min=[-0.5])).data_scale(s)
        (2.0, 3.0)
        """
        c = self.constraints
        sizes = [float(np.abs(system.x0).max(initial=0.0)),
                 float(np.sqrt(system.horizon * np.linalg.norm(system.noise_cov, 2)))]
        for values in (c.u_min, c.u_max, c.du_max, c.x_min, c.x_max, c.terminal_min, c.terminal_max):
            if values is not None:
                sizes.append(float(np.abs(values[np.isfinite(values)]).max(initial=0.0)))
        for F, g in ((c.F, c.g), (c.terminal_F, c.terminal_g)):
            if F is not None:
                rows = np.isfinite(g)
                sizes.append(float((np.abs(g[rows]) / np.linalg.norm(F[rows], axis=1)).max(initial=0.0)))
        sizes += [abs(b) / float(np.linalg.norm(a)) for a, b, _ in c.chance]
        weight = max(self.scale, float(np.linalg.eigvalsh(system.initial_weight).max(initial=0.0)))
        return max(sizes), weight

    # ------------------------------------------------------------------------------------------------ the check
    def kkt(self, system: System, U: np.ndarray, multipliers: list[np.ndarray] | None = None,
            slacks: list[np.ndarray] | None = None) -> dict[str, Any]:
        """The KKT conditions at the plan ``U`` with the last solve's multipliers (or ``multipliers``, ``slacks``: one
        array per constraint block, in the cost's units), every constraint and gradient evaluated on
        `plan_moments` (not on the matrices the problem was built from). Returns
        ``{"residual", "worst", "stationarity", "primal", "dual", "complementarity", "binding", "violations",
        "multipliers", "slacks", "cost"}`` (``cost``: J(U) on the plan's moments, the forward cost `solve` returns):

        * stationarity ``||grad J + sum lambda_i grad g_i||_inf`` over the largest of its terms' sizes: grad J's
          input, x0 and plan parts (which cancel at an interior optimum) and ``|lambda_i| ||grad g_i||_inf``; a chance
          row at its norm's kink (no noise, the plan zero where it spreads a'x_k) contributes the subgradient of its
          ball ``{kappa sqrt(D) z : ||z|| <= 1}`` that best cancels the rest;
        * primal ``max (g_i - s_i)_+ / max(1, |b_i|)`` (s_i the slack of a soft row);
        * dual ``max(-lambda_i, lambda_i - rho)_+ / max(lambda)`` (rho the soft weight on a soft row, inf on a hard
          one);
        * complementarity ``sum |lambda_i (g_i - s_i)|`` over the objective the solver minimised (J's variable part
          plus the penalty): the duality gap's own scale.

        O(N^2 n m (n + m)) for the moments plus O(rows N m).
        """
        mom = self._moments(system, U)
        u = U.ravel()
        mu = system.mu_schedule
        w = (system.input_weights + (self._d * (1.0 - mu) if self.protocol == "udp" else 0.0)) * mu
        grad_J = 2.0 * w.ravel() * u
        # grad J's terms in x0 and in U (they cancel at an interior optimum), step by step k = 1..N
        T, W, mean = mom.T[1:], system.state_weights, mom.mean[1:]
        moved = T @ u
        free_part = 2.0 * _weighted_pull(T, W, mean - moved)     # A^k x0
        plan_part = 2.0 * _weighted_pull(T, W, moved)
        J_var = float(np.sum(w.ravel() * u * u)) + float(np.einsum("ki,kij,kj->", mean, W, mean))
        grad_J += free_part + plan_part
        total = grad_J.copy()
        rho = self.constraints.soft_weight if self.constraints.soft else np.inf
        largest = max(float(np.abs(part).max(initial=0.0)) for part in (2.0 * w.ravel() * u, free_part, plan_part))
        primal = dual = comp = 0.0
        binding, violations, pairs = [], [], []
        lam_max = 0.0
        if multipliers is None:
            multipliers = [group.multipliers() * self.scale for group in self._groups]
            slacks = [group.slack_values() for group in self._groups]
        for group, lam, slack in zip(self._groups, multipliers, slacks, strict=True):
            g, jac, _ = group.evaluate(mom, u, system)
            lam_max = max(lam_max, float(np.max(np.abs(lam), initial=0.0)))
            total += jac.T @ lam
            largest = max(largest, float(np.max(np.abs(lam) * np.abs(jac).max(axis=1, initial=0.0), initial=0.0)))
            size = np.maximum(1.0, np.abs(group.bound))
            excess = g - slack
            primal = max(primal, float(np.max(np.maximum(excess, 0.0) / size, initial=0.0)))
            cap = rho if group.slack is not None else np.inf        # a soft row's multiplier is at most rho
            dual = max(dual, float(np.max(np.maximum(-lam, lam - cap), initial=0.0)))
            pairs.append((np.abs(lam), np.abs(excess)))
            binding += [group.labels[i] for i in np.flatnonzero(excess >= -CONSTRAINED_ACTIVE_RTOL * size)]
            violations += [(group.labels[i], float(slack[i])) for i in np.flatnonzero(slack > CONSTRAINED_ACTIVE_RTOL
                                                                                      * size)]
        for group, lam in zip(self._groups, multipliers, strict=True):     # a kink: the best subgradient
            for row, scale in group.kinks.items():
                if scale.ndim == 2:             # behind a chain: the ball {lam kappa F z}, z by least squares
                    G = max(float(lam[row]), 0.0) * scale
                    if not G.size or not np.any(G):
                        continue
                    z = -np.linalg.lstsq(G, total, rcond=None)[0]
                    z /= max(1.0, float(np.linalg.norm(z)))
                    total += G @ z
                    largest = max(largest, float(np.abs(G).max()))
                    continue
                weight = max(float(lam[row]), 0.0) * scale
                support = weight > 0
                if not support.any():
                    continue
                z = -total[support] / weight[support]
                z /= max(1.0, float(np.linalg.norm(z)))
                total[support] += weight[support] * z
                largest = max(largest, float(weight.max()))
        # the multipliers' work on the rows' excesses, over the objective the solver minimised (penalty included): the
        # scale of its duality gap, which no rescaling of a row changes
        objective = abs(J_var) + sum(self.constraints.soft_weight * float(np.sum(slack)) for slack in slacks)
        # each relative to its own size, floored at CROSS_CHECK_FLOOR of the problem's data (`data_scale`): at a state
        # near zero the optimum is U = 0 and every term is rounding
        size, weight = self.data_scale(system)
        cost_floor, slope_floor = CROSS_CHECK_FLOOR * weight * size * size, CROSS_CHECK_FLOOR * weight * size
        comp = sum(float(np.sum(lam_abs * excess_abs)) for lam_abs, excess_abs in pairs) / max(objective, cost_floor,
                                                                                                1e-300)
        stationarity = float(np.abs(total).max(initial=0.0)) / max(largest, slope_floor, 1e-300)
        dual = dual / max(lam_max, slope_floor, 1e-300)
        parts = {"stationarity": stationarity, "primal": primal, "dual": dual, "complementarity": comp}
        worst = max(parts, key=parts.get)
        return {"residual": parts[worst], "worst": worst, **parts, "binding": binding, "violations": violations,
                "multipliers": multipliers, "slacks": slacks, "cost": J_var + self._constant(system)}


class _Group:
    """A block of constraints of one kind: its cvxpy constraint(s), labels, bounds, slack, and its evaluation on the
    plan's moments (values g_i - b_i and their gradients)."""

    def __init__(self, kind: str, con: Any, labels: list[str], bound: np.ndarray, slack: cp.Variable | None,
                 P: sp.csr_matrix | None = None, chance: tuple | None = None,
                 offset: sp.csr_matrix | None = None) -> None:
        self.kind, self.con, self.labels, self.bound, self.slack = kind, con, labels, np.asarray(bound), slack
        #: rows whose bound moves with a Parameter (u_prev): ``bound = base + offset @ value``, set by `link`
        self.base, self.offset = self.bound, offset
        self.P, self.chance = P, chance
        self.dense: np.ndarray | None = None            # the input rows' P as an array, on first use
        #: a chance block's (C, (a'C_k)^2, a'S_k a, a'T_k) for the moments' C it was computed from (one mu)
        self.plan_free: tuple | None = None
        #: chance rows at the norm's kink at the last evaluate: row -> kappa sqrt(D) (the subdifferential's scale), or
        #: behind a chain a matrix kappa F_k (columns spanning the ball {kappa F_k z : ||z|| <= 1}, F_k F_k' = Q_k)
        self.kinks: dict[int, np.ndarray] = {}
        #: behind a chain: the deliveries' covariance (N m × N m, step-major) the chance rows take, set per belief
        self.loss_cov: np.ndarray | None = None

    def link(self, value: np.ndarray) -> None:
        """The bounds for the Parameter's ``value`` (rows ``g(u) = P u - base - offset value``). O(rows)."""
        if self.offset is not None:
            self.bound = self.base + self.offset @ value

    def multipliers(self) -> np.ndarray:
        if isinstance(self.con, list):
            return np.array([float(c.dual_value) for c in self.con])
        return np.asarray(self.con.dual_value, dtype=float).ravel()

    def slack_values(self) -> np.ndarray:
        return np.zeros(len(self.labels)) if self.slack is None else np.asarray(self.slack.value, dtype=float)

    def evaluate(self, mom: Moments, u: np.ndarray, system: System, curvature: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(g - b, dg/du, sum_i c_i d2g_i/du2 or None)`` of the block's rows at u: the chance rows' Hessians summed
        with the weights ``curvature`` (one per row: the polish's Lagrangian) only when asked; None for linear rows.
        """
        N = system.horizon
        if self.kind == "inputs":
            if self.dense is None:
                self.dense = self.P.toarray()
            return self.dense @ u - self.bound, self.dense, None
        if self.kind == "states":
            mean = mom.mean[1:].ravel()
            T = mom.T[1:].reshape(N * system.n, -1)
            return self.P @ mean - self.bound, np.asarray(self.P @ T), None
        if self.loss_cov is not None:
            return self._evaluate_chain(mom, u, system, curvature)
        a, b, kappa = self.chance
        if self.plan_free is None or self.plan_free[0] is not mom.C:      # what no plan moves, once per mu
            self.plan_free = (mom.C, np.einsum("i,kij->kj", a, mom.C[1:]) ** 2,     # (a' C_k)^2, k = 1..N
                              np.einsum("i,kij,j->k", a, mom.S[1:], a), np.einsum("i,kij->kj", a, mom.T[1:]))
        _, h2, noise, slope = self.plan_free
        std = np.sqrt(h2 @ (u * u) + noise)
        g = mom.mean[1:] @ a + kappa * std - b
        jac = slope.copy()
        reach = max(1.0, float(np.abs(u).max(initial=0.0)))
        # the norm's kink (no noise, the plan ~0 where it spreads a'x_k): no gradient, the subdifferential
        # {kappa sqrt(D) z : ||z|| <= 1}; kept for the KKT check (:meth:`ConstrainedQP.kkt`)
        kink = (noise == 0.0) & (std <= CONSTRAINED_ACTIVE_RTOL * np.sqrt(h2.sum(axis=1)) * reach)
        self.kinks = {int(k): kappa * np.sqrt(h2[k]) for k in np.flatnonzero(kink)}
        smooth = ~kink & (std > 0)          # kappa sqrt(u' D u + s), D = diag(h^2): gradient kappa D u / std
        Du = h2[smooth] * u
        jac[smooth] += kappa * Du / std[smooth, None]
        if curvature is None:
            return g, jac, None
        # the Hessian of row k: kappa (D_k / std_k - D_k u u' D_k / std_k^3), summed with the weights c_k
        c = curvature[smooth]
        total = -(Du.T * (c / std[smooth] ** 3)) @ Du
        total[np.diag_indices(u.size)] += (c / std[smooth]) @ h2[smooth]
        return g, jac, kappa * total

    def _evaluate_chain(self, mom: Moments, u: np.ndarray, system: System, curvature: np.ndarray | None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """`evaluate`'s chance rows behind a chain: ``Var(a'x_k) = u' Q_k u + a'S_k a``, ``Q_k = diag(h_k) C
        diag(h_k)``, C the deliveries' covariance (``loss_cov``) and ``h_k = a' dx_k / d(v u)`` the row's impulse
        responses with every packet delivered (by the forward recursion, not from the problem's matrices).
        O(N (N m)^2) per plan."""
        a, b, kappa = self.chance
        C = self.loss_cov
        if self.plan_free is None or self.plan_free[0] is not mom.C or self.plan_free[1] is not C:
            N, n, m = system.horizon, system.n, system.m
            reach, h = np.zeros((n, N * m)), np.zeros((N, N * m))
            for k in range(N):                   # h[k-1] = a' (A^{k-1-j} B) over the inputs j < k
                reach = system.A @ reach
                reach[:, k * m:(k + 1) * m] += system.B
                h[k] = a @ reach
            self.plan_free = (mom.C, C, h, np.einsum("i,kij,j->k", a, mom.S[1:], a),
                              np.einsum("i,kij->kj", a, mom.T[1:]), np.einsum("kj,jj,kj->k", h, C, h))
        _, _, h, noise, slope, trace = self.plan_free
        hu = h * u
        Qu = h * (hu @ C)                        # Q_k u, row k
        std = np.sqrt(np.maximum(np.sum(Qu * u, axis=1), 0.0) + noise)
        g = mom.mean[1:] @ a + kappa * std - b
        jac = slope.copy()
        reach = max(1.0, float(np.abs(u).max(initial=0.0)))
        kink = (noise == 0.0) & (std <= CONSTRAINED_ACTIVE_RTOL * np.sqrt(trace) * reach)
        self.kinks = {int(k): kappa * psd_factor(h[k][:, None] * C * h[k][None, :]).T for k in np.flatnonzero(kink)}
        smooth = ~kink & (std > 0)
        jac[smooth] += kappa * Qu[smooth] / std[smooth, None]
        if curvature is None:
            return g, jac, None
        # the Hessian of row k: kappa (Q_k / std_k - Q_k u u' Q_k / std_k^3), summed with the weights c_k
        c = curvature[smooth]
        hs = h[smooth]
        total = C * ((hs.T * (c / std[smooth])) @ hs) - (Qu[smooth].T * (c / std[smooth] ** 3)) @ Qu[smooth]
        return g, jac, kappa * total


def _chain_terms(response: np.ndarray, innovation: cp.Parameter, spread: cp.Parameter, c: cp.Expression,
                 last: int) -> list[cp.Expression]:
    """``F' c`` for the deliveries at steps ``t < last`` (`DeliveryFactor`), as the vectors whose stacked norm is
    ``||F' c||``: ``(F'c)_(N K + t) = sqrt(gamma_t) c_t`` and ``(F'c)_(s, b) = sum_a G_s[a, b] sum_{s <= t < last}
    e_{t-s}[a] c_t`` (one constant map per state a, whose entries are the responses ``e_L``, times the Parameter's
    row a, summed over a). A state whose responses are all zero (the first: e_L is centred on it) adds nothing, so a
    two-state channel has one term. O(last^2 K^2) entries."""
    K = response.shape[1]
    lag = np.subtract.outer(np.arange(last), np.arange(last))        # t - s at [t, s]
    states = []                                                       # the sum over a, one vector
    for a in range(K):
        if not np.any(response[:last, a]):
            continue
        E = np.where(lag >= 0, response[np.clip(lag, 0, None), a], 0.0).T        # [s, t] = e_{t-s}[a], t >= s
        states.append(cp.multiply(innovation[a, :last * K], np.repeat(E, K, axis=0) @ c))
    return [cp.multiply(spread[:last], c)] + ([cp.sum(states)] if len(states) > 1 else states)


def _weighted_gram(T: np.ndarray, W: np.ndarray) -> np.ndarray:
    """``sum_k T_k' W_k T_k`` for T (N, n, p) and W (N, n, n). O(N n p (n + p))."""
    return T.reshape(-1, T.shape[2]).T @ (W @ T).reshape(-1, T.shape[2])


def _weighted_pull(T: np.ndarray, W: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``sum_k T_k' W_k x_k`` for T (N, n, p), W (N, n, n), x (N, n). O(N n (n + p))."""
    return T.reshape(-1, T.shape[2]).T @ (W @ x[:, :, None]).ravel()


def _input_rows(c: Constraints, N: int, m: int, previous: bool = False
                ) -> tuple[sp.csr_matrix, np.ndarray, sp.csr_matrix, list[str]]:
    """Rows ``G u <= h + S u_prev`` (u step-major) of the input and rate bounds, with their labels; ``S`` is zero but
    on the rows of ``|u_0 - u_prev| <= du_max`` (``previous``)."""
    rows, rhs, labels, linked = [], [], [], []
    eye = sp.eye(N * m, format="csr")
    for name, sign, values in (("u_max", 1.0, c.u_max), ("u_min", -1.0, c.u_min)):
        if values is None:
            continue
        for t in range(N):
            for i in np.flatnonzero(np.isfinite(values)):
                rows.append(sign * eye[t * m + i])
                rhs.append(sign * values[i])
                labels.append(f"{name}[{i}] at t={t}")
    if c.du_max is not None:
        for t in range(0 if previous else 1, N):
            for i in np.flatnonzero(np.isfinite(c.du_max)):
                diff = eye[t * m + i] - eye[(t - 1) * m + i] if t else eye[i]
                if not t:                                 # u_0 - u_prev <= du, u_prev - u_0 <= du
                    linked += [(len(rows), i, 1.0), (len(rows) + 1, i, -1.0)]
                rows += [diff, -diff]
                rhs += [c.du_max[i], c.du_max[i]]
                labels += [f"du_max[{i}] at t={t} (up)", f"du_max[{i}] at t={t} (down)"]
    G = sp.vstack(rows, format="csr") if rows else sp.csr_matrix((0, N * m))
    S = sp.csr_matrix(([v for _, _, v in linked], ([r for r, _, _ in linked], [i for _, i, _ in linked])),
                      shape=(len(rows), m))
    return G, np.array(rhs), S, labels


def _state_rows(c: Constraints, N: int, n: int) -> tuple[sp.csr_matrix, np.ndarray, list[str]]:
    """Rows ``P E[X] <= q`` (E[X] = (E[x_1], ..., E[x_N])) of the state box and polyhedron and of the terminal set,
    with their labels."""
    rows, rhs, labels = [], [], []
    eye = sp.eye(N * n, format="csr")
    for name, sign, values in (("x_max", 1.0, c.x_max), ("x_min", -1.0, c.x_min)):
        if values is None:
            continue
        for k in range(1, N + 1):
            for j in np.flatnonzero(np.isfinite(values)):
                rows.append(sign * eye[(k - 1) * n + j])
                rhs.append(sign * values[j])
                labels.append(f"{name}[{j}] at k={k}")
    if c.F is not None:
        for k in range(1, N + 1):
            for r in np.flatnonzero(np.isfinite(c.g)):
                rows.append(sp.csr_matrix((c.F[r], (np.zeros(n, int), (k - 1) * n + np.arange(n))), shape=(1, N * n)))
                rhs.append(c.g[r])
                labels.append(f"F[{r}] at k={k}")
    # the terminal set, on E[x_N] only
    for name, sign, values in (("terminal_max", 1.0, c.terminal_max), ("terminal_min", -1.0, c.terminal_min)):
        for j in [] if values is None else np.flatnonzero(np.isfinite(values)):
            rows.append(sign * eye[(N - 1) * n + j])
            rhs.append(sign * values[j])
            labels.append(f"{name}[{j}] at k={N}")
    if c.terminal_F is not None:
        for r in np.flatnonzero(np.isfinite(c.terminal_g)):
            rows.append(sp.csr_matrix((c.terminal_F[r], (np.zeros(n, int), (N - 1) * n + np.arange(n))),
                                      shape=(1, N * n)))
            rhs.append(c.terminal_g[r])
            labels.append(f"terminal_F[{r}] at k={N}")
    P = sp.vstack(rows, format="csr") if rows else sp.csr_matrix((0, N * n))
    return P, np.array(rhs), labels


def _chance_data(system: System, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``H`` (N × N m) with ``H[k-1, j m + i] = a' A^{k-1-j} B e_i`` (j < k) and the noise variances ``a' S_k a``:
    ``Var(a' x_k) = sum_j sum_i H[k-1, j m + i]^2 mu(1 - mu) u^2 + a' S_k a``. By the backward products a' A^p,
    O(N^2 n (n + m))."""
    N, n, m = system.horizon, system.n, system.m
    A, B = system.A, system.B
    powers = np.zeros((N, n))            # a' A^p, p = 0..N-1
    powers[0] = a
    for p in range(1, N):
        powers[p] = powers[p - 1] @ A
    H = np.zeros((N, N * m))
    noise = np.zeros(N)
    for k in range(1, N + 1):
        for j in range(k):
            H[k - 1, j * m:(j + 1) * m] = powers[k - 1 - j] @ B
        noise[k - 1] = sum(float(powers[p] @ system.noise_cov @ powers[p]) for p in range(k))
    return H, noise


def solve_constrained(system: System, protocol: str, constraints: Constraints | Any, formulation: str = "auto",
                      solver: str | None = None, **kwargs) -> ConstrainedSolution:
    """Minimise the protocol's expected cost under ``constraints`` (`ConstrainedQP`, solved once; keep the
    object to re-solve for other x0 or mu without recompiling). Keyword arguments go to `ConstrainedQP.solve`.

    Examples
    --------
    With no constraint binding the answer is Theorem 1's (u = -2/3, J = 2/3 here):

    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> sol = solve_constrained(s, "tcp", Constraints(u_min=[-5.0], u_max=[5.0]))
    >>> bool(np.allclose([sol.inputs[0, 0], sol.cost], [-2 / 3, 2 / 3], atol=1e-8)), sol.binding
    (True, ())
    """
    return ConstrainedQP(system, protocol, constraints, formulation, solver).solve(**kwargs)
