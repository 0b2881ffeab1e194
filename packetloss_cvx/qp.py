"""The expected-cost minimisation as cvxpy QPs solved with Clarabel (the solver twin).

Two formulations of the same problem, both in the mean delivered input ``Z = Vbar U``, both DPP
and re-solved by assigning new values to their ``cp.Parameter``s, without recompiling.

* ``"condensed"``: variables Z only; ``sum_squares(L Phi x + L Gamma Z)`` with every datum a
  Parameter: one compiled problem per padded shape serves every system (:mod:`.qp_shared`).
  Dense data of size (N n)×(N m): build O((N n)^2 N m), solve O((N m)^3).
* ``"sparse"``: mean states and Z as variables, the dynamics ``xhat_{t+1} = A xhat_t + B z_t`` as
  equality constraints; Parameters: the state x and, for a stationary channel, ``1/mu`` and
  ``1/mu - 1`` per channel. No Parameter multiplies a Variable, so the canonicalisation is linear in N
  (``multiply(v, U)`` kept an (N m)×(N m) map: docs/performance.md); every constant is block-sparse,
  so build and solve are O(N (n + m)^3), memory O(N (n + m)^2).

The input terms of eq:opt-lqg-simplest with Lemma 1, ``U' Vbar Psi U + [UDP] U' Vbar Omega_d
(I - Vbar) U``, are ``sum (psi + [UDP] diag(Omega_g)(1 - mu)) z^2 / mu``; the diagonal of Omega_g
comes from the backward Lyapunov sum (:func:`udp_variance_weights`). Channels with mu <=
``QP_PIN_MU`` have z pinned to zero; their input U is reported as 0.
"""

from __future__ import annotations

import time

import cvxpy as cp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .convex import solve_problem
from .costs import closed_form, refuse_correlated
from .crosscheck import compare
from .errors import InputError, NumericalError, ResourceError, SolverError
from .linalg import power_growth
from .model import System, check_system
from .protocols import check_protocol
from .qp_shared import condensed_data, solve_condensed
from .qp_sparse import qp_memory_estimate, sparse_dynamics
from .recursion import recursion_cost, udp_variance_weights
from .results import Solution
from .threads import blas_limited
from .tolerances import (
    ACCEPTED_STATUSES,
    CLARABEL_TIGHT,
    CROSS_CHECK_COST_RTOL,
    MEMORY_BUDGET_BYTES,
    PLAN_CHECK_MAX_GROWTH,
    QP_PIN_MU,
    QP_RESCALE_BELOW,
)

__all__ = [
    "CLARABEL_SETTINGS", "ExpectedCostQP", "compare", "qp_memory_estimate", "solve_qp", "sparse_dynamics",
]

#: Tightened Clarabel tolerances (tolerances.CLARABEL_TIGHT): the cross-check promises inputs to 1e-6.
CLARABEL_SETTINGS = CLARABEL_TIGHT

#: Above this many decision variables N*m, ``formulation="auto"`` uses the sparse form
#: (measured crossover between N*m = 40 and 80 for n = 4: docs/performance.md).
AUTO_CONDENSED_MAX = 60

#: At most this many re-solves rescaled by the previous value (``tolerances.QP_RESCALE_BELOW``): one brings a
#: resolved minimum to O(1); a first value that was mostly gap (1e-10 for a minimum of 1e-20) takes two.
QP_RESCALE_PASSES = 2


def _pick(system: System, formulation: str) -> str:
    if formulation == "auto":
        return "condensed" if system.horizon * system.m <= AUTO_CONDENSED_MAX else "sparse"
    if formulation not in ("condensed", "sparse"):
        raise InputError(
            "formulation", f"expected 'condensed', 'sparse' or 'auto', found {formulation!r}"
        )
    return formulation


class ExpectedCostQP:
    """One protocol's expected-cost QP for one system, re-solvable for new mu or x0.

    The condensed form solves a problem compiled once per padded shape and shared with every other
    system of that shape in the process (:func:`.qp_shared.condensed_problem`, thread-safe); the
    sparse form compiles its own. An instance itself is not thread-safe (it keeps the current x, mu).

    Parameters
    ----------
    system : System
        Supplies A, B, weights and horizon (fixed) and the initial mu, x0 (parameters).
    protocol : {"tcp", "udp"}
    formulation : {"condensed", "sparse", "auto"}

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> qp = ExpectedCostQP(s, "udp", "sparse")
    >>> a, b = qp.solve(), qp.solve(mu=[0.9])      # the second re-uses the compiled problem
    >>> bool(b.cost < a.cost)
    True
    """

    def __init__(self, system: System, protocol: str, formulation: str = "auto") -> None:
        system = check_system(system)
        self.protocol = check_protocol(protocol)
        refuse_correlated(system, self.protocol)
        self.formulation = _pick(system, formulation)
        self.system = system
        N, n, m = system.horizon, system.n, system.m
        needed = qp_memory_estimate(system, self.formulation)
        if needed > MEMORY_BUDGET_BYTES:
            raise ResourceError(
                f"the {self.formulation} QP needs about {needed / 2**30:.1f} GiB for N = {N}, n = {n}, m = {m} (cvxpy "
                f"keeps ~260 N n^2 bytes of state terms); budget "
                f"{MEMORY_BUDGET_BYTES / 2**30:.1f} GiB", needed,
                MEMORY_BUDGET_BYTES)
        self._d, self._noise = udp_variance_weights(system)
        self._plan_checkable = power_growth(system.A, N, PLAN_CHECK_MAX_GROWTH) <= PLAN_CHECK_MAX_GROWTH
        if not (np.all(np.isfinite(self._d)) and np.isfinite(self._noise)):
            raise NumericalError(
                "the QP's loss-variance weights diag(Omega_g) (or its noise term) exceed the double-precision "
                "range: the open-loop prediction of an unstable plant over this horizon")
        # one common scale for every weight (the minimiser does not change; the value scales back),
        # so that Clarabel's absolute tolerances mean the same for weights of 1e-15 and of 1e6
        self._weight_scale = max(float(system.input_weights.max()),
                                 float(np.linalg.eigvalsh(system.state_weights).max()))
        self._scale = self._weight_scale      # times the rescaling of tiny minima (:meth:`_rescale`)
        #: how many solves of this object were re-solved rescaled (``tolerances.QP_RESCALE_BELOW``)
        self.rescaled = 0
        self.x = cp.Parameter(n, name="x")
        if self.formulation == "condensed":     # (L Phi, L Gamma) / sqrt(scale); None without state weight
            self._state = condensed_data(system, self._scale)
        else:
            E, Bbig, first, L = sparse_dynamics(system)
            self._state = (E, Bbig, first, L / np.sqrt(self._scale))
        self._problems: dict[tuple, tuple] = {}      # sparse: compiled per pinned set / schedule
        self._own: dict[tuple, object] = {}          # condensed beyond SHARED_MAX_ENTRIES: per shape
        self._assign(system.mu_schedule, system.x0, self.protocol)

    def _build(self, key: tuple, free: np.ndarray, weight: np.ndarray | None) -> None:
        """The sparse problem for the entries ``free`` (N×m, mu > QP_PIN_MU): built on first use, kept per key.

        Variables: the mean states and the mean delivered inputs ``Z = Vbar U`` on the free entries
        (the others pinned to zero, ``tolerances.QP_PIN_MU``); input terms ``sum (psi + [UDP] d (1 - mu))
        z^2 / mu`` (eq:opt-lqg-simplest with Lemma 1, d = diag(Omega_g)). A stationary channel
        (``weight`` None) enters through two Parameters per channel, ``1/mu`` and ``1/mu - 1``, each
        multiplying ``sum(W * square(Z), 0)``: no Parameter multiplies a Variable and the canonicalisation
        stays linear in N (docs/performance.md). A schedule's weights are constants (rebuilt per
        schedule). O(N (n^2 + n m)) nonzeros.
        """
        if key in self._problems:
            self.problem, self.Z, self._params, self._free = self._problems[key]
            return
        N, n, m = self.system.horizon, self.system.n, self.system.m
        flat = free.ravel()
        k = int(flat.sum())
        select = sp.csr_matrix((np.ones(k), (np.flatnonzero(flat), np.arange(k))), shape=(N * m, k))
        params = None
        terms = []
        if k and weight is None:                 # Z as N × (free channels); flat Z is step-major
            channels = np.flatnonzero(free[0])
            Z = cp.Variable((N, len(channels)), name="Z")
            flat_Z = cp.vec(Z.T, order="F")
            params = (cp.Parameter(len(channels), nonneg=True, name="inv_mu"),
                      cp.Parameter(len(channels), nonneg=True, name="inv_mu_minus_one"))
            psi, d = self.system.input_weights / self._scale, self._d / self._scale
            terms.append(params[0] @ cp.sum(cp.multiply(psi[:, channels], cp.square(Z)), axis=0))
            if key[1] == "udp":
                terms.append(params[1] @ cp.sum(cp.multiply(d[:, channels], cp.square(Z)), axis=0))
        else:
            Z = flat_Z = cp.Variable(k, name="Z")
            if k:
                terms.append(cp.sum_squares(cp.multiply(np.sqrt(weight.ravel()[flat]), Z)))
        E, Bbig, first, L = self._state
        X = cp.Variable(N * n, name="xhat")
        delivered = (Bbig @ select) @ flat_Z if k else 0.0
        constraints = [E @ X - delivered == first @ self.x]
        if L.shape[0]:
            terms.append(cp.sum_squares(L @ X))
        problem = cp.Problem(cp.Minimize(cp.sum(terms) if terms else 0), constraints)
        if not problem.is_dpp():  # pragma: no cover - construction guarantees it
            raise RuntimeError("expected-cost QP is not DPP")
        if weight is not None:
            self._problems = {k_: v_ for k_, v_ in self._problems.items() if k_[0] != "schedule"}
        self._problems[key] = (problem, Z, params, free)
        self.problem, self.Z, self._params, self._free = problem, Z, params, free

    def _weights(self, mu: np.ndarray, free: np.ndarray, protocol: str) -> np.ndarray:
        """The input terms' weights ``(psi + [UDP] d (1 - mu)) / (mu s)`` per entry (N×m; 1/s where pinned)."""
        d = np.where(mu < 1.0, self._d * (1.0 - mu), 0.0) if protocol == "udp" else 0.0
        return (self.system.input_weights + d) / (np.where(free, mu, 1.0) * self._scale)

    def _assign(self, mu: np.ndarray, x: np.ndarray, protocol: str) -> None:
        free = mu > QP_PIN_MU
        self._v = mu.ravel()
        if self.formulation == "condensed":    # the shared problem's data: its Parameters are set per solve
            flat = free.ravel()
            self._free = free
            self._G = self._state[1][:, flat] if self._state is not None else np.zeros((0, int(flat.sum())))
            self._r = np.sqrt(self._weights(mu, free, protocol).ravel()[flat])
        elif np.all(mu == mu[0]):     # one problem per protocol: a zero-weighted diag(Omega_g) term of an
            # unstable plant (1e70) made Clarabel fail the TCP-like QP it solved without the term
            self._build(("stationary", protocol, free[0].tobytes()), free, None)
            if self._params is not None:
                v = mu[0][free[0]]
                self._params[0].value = 1.0 / v
                self._params[1].value = np.where(v < 1.0, 1.0 / v - 1.0, 0.0)
        else:
            self._build(("schedule", protocol, mu.tobytes()), free, self._weights(mu, free, protocol))
        self.x.value = x

    def _solve_raw(self, protocol: str) -> tuple[np.ndarray, float, str]:
        what = f"{protocol}-like {self.formulation} QP"
        u = np.zeros(self._v.size)         # an input never delivered changes nothing: reported as 0
        flat = self._free.ravel()
        try:
            if self.formulation == "sparse":
                status = solve_problem(self.problem, what, attempts=(CLARABEL_SETTINGS,))
                z, value = (self.Z.value, self.problem.value)
            elif not flat.any():           # nothing delivered: the open-loop state cost
                return u, self._open_loop(), "optimal"
            else:                          # the problem shared by shape (this object's own beyond its sizes)
                z, value, status = solve_condensed(self._state, self._G, self._r, self.x.value, what, self._own)
        except SolverError as err:
            raise self._out_of_range(err.status, protocol) from None
        if status not in ACCEPTED_STATUSES:
            raise self._out_of_range(status, protocol)
        if flat.any():
            u[flat] = np.asarray(z).ravel() / self._v[flat]     # U = Vbar^{-1} Z where mu > QP_PIN_MU
        return u, float(value), status

    def _open_loop(self) -> float:
        """The scaled objective at z = 0 (no input delivered), an upper bound of the minimum that is zero exactly
        when the minimum is (no weighted state moves). O(N n^2) (a block-bidiagonal solve in the sparse form)."""
        if self.formulation == "condensed":
            return float(np.sum((self._state[0] @ self.x.value) ** 2)) if self._state is not None else 0.0
        E, _, first, L = self._state
        return float(np.sum((L @ spla.spsolve_triangular(E, first @ self.x.value)) ** 2)) if L.shape[0] else 0.0

    def _rescale(self, value: float) -> None:
        """Multiply the common scale by ``value`` (the last scaled minimum, positive): the condensed data
        (L Phi, L Gamma) / sqrt(scale) are rescaled in place (the shared problems take them as Parameters);
        the sparse problems, whose weights are constants, are dropped and rebuilt on their next use. O(N n (n + m))."""
        root = 1.0 / np.sqrt(value)
        if self.formulation == "condensed":
            self._state = None if self._state is None else (self._state[0] * root, self._state[1] * root)
        else:
            E, Bbig, first, L = self._state
            self._state = (E, Bbig, first, L * root)
            self._problems = {}
        self._scale *= value

    def _solve_scaled(self, mu: np.ndarray, x: np.ndarray, protocol: str) -> tuple[np.ndarray, float, str]:
        """Solve at the unit state ``x``; where the scaled minimum v is below ``QP_RESCALE_BELOW`` (Clarabel's
        absolute gap could then exceed CROSS_CHECK_COST_RTOL v), rescale by v and solve again, at most
        ``QP_RESCALE_PASSES`` times, keeping the new scale. Raises NumericalError if v stays below it while
        the minimum is not exactly zero (some weighted state moves). The minimiser does not depend on the scale."""
        def too_small(v: float) -> bool:      # below the threshold, with a minimum that is not exactly zero
            return v < QP_RESCALE_BELOW and self._free.any() and self._open_loop() > 0.0

        u, value, status = self._solve_raw(protocol)
        for _ in range(QP_RESCALE_PASSES):
            if value <= 0.0 or not too_small(value):
                break
            self._rescale(value)
            self._assign(mu, x, protocol)
            u, value, status = self._solve_raw(protocol)
            self.rescaled += 1
        if too_small(value):
            self._check_resolvable(value, protocol)
            raise NumericalError(
                f"the {protocol}-like {self.formulation} QP's minimum is {value:.3g} times its scale after "
                f"{QP_RESCALE_PASSES} rescaled re-solves, below {QP_RESCALE_BELOW:.0e}, where Clarabel's absolute "
                f"tolerance {CLARABEL_SETTINGS['tol_gap_abs']:.0e} exceeds {CROSS_CHECK_COST_RTOL:.0e} of it: the "
                "weights span more than the solver resolves; the closed form (method='recursion') is exact here")
        return u, value, status

    def _check_resolvable(self, value: float, protocol: str) -> None:
        """Raise when the condensed minimum v = ||c + G z||^2 + ||r z||^2 (c = L Phi x), a squared residual of
        terms of size ||c||, is below double precision's resolution at CROSS_CHECK_COST_RTOL (2 eps ||c|| /
        sqrt(v) relative): there Clarabel may say 'optimal' with v wrong in the third digit. O(N n)."""
        c = float(np.linalg.norm(self._state[0] @ self.x.value)) if self.formulation == "condensed" and \
            self._state is not None and self._free.any() else 0.0
        if not 2.0 * np.finfo(float).eps * c <= CROSS_CHECK_COST_RTOL * np.sqrt(max(value, 0.0)):
            raise NumericalError(
                f"the {protocol}-like condensed QP's minimum {value:.3g} is the square of a residual of terms of "
                f"size {c:.3g}, which double precision cannot resolve to {CROSS_CHECK_COST_RTOL:.0e}: the problem's "
                f"scale is beyond the solver's range (open-loop growth rho(A)^N = "
                f"{float(max(abs(np.linalg.eigvals(self.system.A)))):.3g}^{self.system.horizon}); the closed form "
                "(method='recursion') is exact here")

    def _out_of_range(self, status: str, protocol: str) -> NumericalError:
        """The QP is unconstrained and strictly convex: it always has one minimiser, so any status
        but optimal ('infeasible' included) means the solver lost the problem's scale."""
        rho = float(max(abs(np.linalg.eigvals(self.system.A))))
        return NumericalError(
            f"Clarabel ended {status!r} on the {protocol}-like {self.formulation} QP, which is unconstrained "
            f"and always has a unique minimiser: the problem's scale is beyond the solver's range (open-loop "
            f"growth rho(A)^N = {rho:.3g}^{self.system.horizon}); the closed form (method='recursion') is exact here")

    @blas_limited
    def solve(self, mu=None, x0=None, *, with_gain: bool = True, cross_check: bool = True,
              reference: Solution | None = None, protocol: str | None = None) -> Solution:
        """Solve for the current (or the given) channel and state.

        ``protocol`` (default: the one given at construction) may name the other protocol: one
        ExpectedCostQP then keeps a system's two compiled problems.

        ``mu`` is an m-vector or an N×m schedule; ``x0`` an n-vector. Both are validated
        through :class:`System`. With ``with_gain`` the gain K is recovered by n more
        solves at the unit states (U* is linear in x). The solver's objective is checked
        against the forward cost of its own plan (while the open-loop growth max_t ||A^t||
        is at most ``PLAN_CHECK_MAX_GROWTH``; beyond it a fixed plan's cost amplifies rounding).
        With ``cross_check`` the answer is compared with ``reference`` (default:
        :func:`closed_form`, method "auto"), and a disagreement beyond
        ``CROSS_CHECK_INPUT_ATOL`` / ``CROSS_CHECK_COST_RTOL`` raises.

        Raises
        ------
        NumericalError
            Any solver status other than "optimal" (this QP always has a unique minimiser, so
            'infeasible' or 'optimal_inaccurate' mean lost scale), or an objective that disagrees
            with the forward cost of the plan, or a scaled minimum still below ``QP_RESCALE_BELOW`` after
            ``QP_RESCALE_PASSES`` re-solves rescaled by it (Clarabel's absolute tolerance would then bind).
        CrossCheckError
            The QP and the reference disagree beyond the tolerances; both numbers are named.
        """
        protocol = self.protocol if protocol is None else check_protocol(protocol)
        system = self.system
        if mu is not None:
            system = system.with_mu(mu)
        if x0 is not None:
            system = system.with_x0(x0)
        N, n, m = system.horizon, system.n, system.m
        start = time.perf_counter()
        x = system.x0
        size = float(np.abs(x).max())
        self._assign(system.mu_schedule, x / size if size > 0 else x, protocol)
        if size > 0:   # the variable part is homogeneous of degree 2 in x: solve at unit size, scale back
            u, value, status = self._solve_scaled(system.mu_schedule, x / size, protocol)
            self._check_resolvable(value, protocol)
            u, value = u * size, value * self._scale * size**2
        else:          # x = 0: the plan is zero and so is the variable part, exactly
            u, value, status = np.zeros(N * m), 0.0, "optimal"
        solve_time = time.perf_counter() - start
        cost = value + float(x @ system.initial_weight @ x) + self._noise
        forward = recursion_cost(system, u.reshape(N, m), protocol, (self._d, self._noise))
        if self._plan_checkable and not abs(cost - forward) <= CROSS_CHECK_COST_RTOL * forward:
            raise NumericalError(
                f"the {protocol}-like {self.formulation} QP reports J = {cost:.10g} but the forward cost of its "
                f"own plan is {forward:.10g}: the solver lost the problem's scale (weights spanning many orders "
                "of magnitude, or an unstable plant over a long horizon)")
        gain = None
        eigs = None
        if with_gain:
            columns = []
            for j in range(n):
                self.x.value = np.eye(n)[j]
                columns.append(-self._solve_raw(protocol)[0][:m])
            gain = np.column_stack(columns)
            eigs = np.linalg.eigvals(system.A - system.B @ gain)
        check = None
        if cross_check:
            ref = reference if reference is not None else closed_form(system, protocol, method="auto")
            check = compare(u.reshape(N, m), cost, ref, system, scale=(self._weight_scale * size**2, size))
        return Solution(
            protocol=protocol, cost=cost, inputs=u.reshape(N, m), gain=gain,
            closed_loop_eigenvalues=eigs, method=f"qp-{self.formulation}", status=status,
            solve_time=solve_time, cross_check=check,
        )


def solve_qp(system: System, protocol: str, formulation: str = "auto", **kwargs) -> Solution:
    """Minimise the protocol's expected cost with cvxpy + Clarabel (the minimisation of eq:opt-lqg).

    Builds an :class:`ExpectedCostQP` and solves it once; keep the object to re-solve
    for other mu or x0 without recompiling. Keyword arguments go to
    :meth:`ExpectedCostQP.solve`.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> sol = solve_qp(s, "tcp")                        # min (1 + u/2)^2 + u^2/2: u = -2/3, J = 2/3
    >>> bool(np.allclose([sol.inputs[0, 0], sol.cost], [-2 / 3, 2 / 3], atol=1e-7))
    True
    """
    return ExpectedCostQP(system, protocol, formulation).solve(**kwargs)
