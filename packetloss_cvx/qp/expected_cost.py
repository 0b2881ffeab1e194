"""The expected-cost minimisation as cvxpy QPs solved with Clarabel (the solver twin), and its cross-check.

One class, [`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP], and two backends that solve the same
problem in the mean delivered input ``Z = Vbar U``, both DPP and re-solved by assigning new values to their
``cp.Parameter``s, without recompiling:

* `CondensedBackend`: variables Z only; ``sum_squares(L Phi x + L Gamma Z)`` with every
  datum a Parameter: one compiled problem per padded shape serves every system (`.shared`).
  Dense data of size (N n)×(N m): build O((N n)^2 N m), solve O((N m)^3).
* `SparseBackend`: mean states and Z as variables, the dynamics
  ``xhat_{t+1} = A xhat_t + B z_t`` as equality constraints (`sparse_dynamics`); Parameters: the state x and, for a
  stationary channel, ``1/mu`` and ``1/mu - 1`` per channel. No Parameter multiplies a Variable, so
  the canonicalisation is linear in N (``multiply(v, U)`` kept an (N m)×(N m) map:
  docs/performance.md); every constant is block-sparse, so build and solve are O(N (n + m)^3),
  memory O(N (n + m)^2).

``ExpectedCostQP(system, protocol, formulation)`` holds the backend the function `choose_backend` picks
("auto": condensed up to ``AUTO_CONDENSED_MAX`` decision variables) as ``.backend``. The class owns what both
share: validation, the weights, the rescaling of tiny minima, the forward self-check, the gain and
the cross-check against the closed form ([`compare`][packetloss_cvx.qp.expected_cost.compare]); a backend owns its data,
its problems, and four steps (select, minimise, open-loop value, rescale). `CondensedExpectedCostQP` and
`SparseExpectedCostQP` are the class with its formulation fixed.

The input terms of eq:opt-lqg-simplest with Lemma 1, ``U' Vbar Psi U + [UDP] U' Vbar Omega_d
(I - Vbar) U``, are ``sum (psi + [UDP] diag(Omega_g)(1 - mu)) z^2 / mu``; the diagonal of Omega_g
comes from the backward Lyapunov sum (`udp_variance_weights`). Channels with mu <=
``QP_PIN_MU`` have z pinned to zero; their input U is reported as 0.
"""

from __future__ import annotations

import time

import cvxpy as cp
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..budgets import check, duration_text, estimated_seconds, gib_text, qp_bytes, qp_work
from ..errors import CrossCheckError, InputError, NumericalError, SolverError
from ..linalg import psd_factor
from ..lq.costs import closed_form, refuse_correlated
from ..lq.prediction import prediction
from ..lq.recursion import plan_cost, udp_variance_weights
from ..model.protocols import check_protocol
from ..model.system import System, check_system
from ..results import CrossCheck, Solution
from ..threads import blas_limited
from ..tolerances import (
    ACCEPTED_STATUSES,
    CLARABEL_TIGHT,
    CROSS_CHECK_COST_RTOL,
    CROSS_CHECK_FLOOR,
    CROSS_CHECK_INPUT_ATOL,
    PLAN_COST_RTOL,
    QP_PIN_MU,
    QP_RESCALE_BELOW,
)
from .convex import solve_problem
from .shared import condensed_problem

__all__ = [
    "AUTO_CONDENSED_MAX", "CLARABEL_SETTINGS", "CondensedBackend", "CondensedExpectedCostQP", "ExpectedCostQP",
    "SparseBackend", "SparseExpectedCostQP", "choose_backend", "compare", "condensed_data", "qp_memory_estimate",
    "solve_qp", "sparse_dynamics",
]

#: Tightened Clarabel tolerances (tolerances.CLARABEL_TIGHT): the cross-check promises inputs to 1e-6.
CLARABEL_SETTINGS = CLARABEL_TIGHT

#: Above this many decision variables N*m, ``formulation="auto"`` uses the sparse form
#: (measured crossover between N*m = 40 and 80 for n = 4: docs/performance.md).
AUTO_CONDENSED_MAX = 60

#: At most this many re-solves rescaled by the previous value (``tolerances.QP_RESCALE_BELOW``): one brings a
#: resolved minimum to O(1); a first value that was mostly gap (1e-10 for a minimum of 1e-20) takes two.
QP_RESCALE_PASSES = 2


# ---------------------------------------------------------------------------------------- the cross-check

def compare(inputs: np.ndarray, cost: float, reference: Solution, system: System,
            scale: tuple[float, float] = (0.0, 0.0)) -> CrossCheck:
    """Compare a plan and its cost with ``reference``; raise [`CrossCheckError`][packetloss_cvx.errors.CrossCheckError]
    naming both numbers unless the mean applied inputs agree, ``max|Vbar (U - U*)| <= CROSS_CHECK_INPUT_ATOL
    max(max|Vbar U*|, CROSS_CHECK_FLOOR s_x)``, and the costs agree relatively, ``|J - J*| <=
    CROSS_CHECK_COST_RTOL max(|J*|, CROSS_CHECK_FLOOR s_J)``. ``scale = (s_J, s_x)`` is the
    problem's own size (largest weight times max|x0|^2, and max|x0|): below a billionth of it
    a difference is rounding, and an exact zero on one side can only be matched that way.

    The mean applied input ``Vbar U`` is what the cost sees: an input over a channel that
    (almost) never delivers is (almost) free, so it is compared through its delivery probability.
    Used by [`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP] and `exact_qp`. O(N m).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ref = closed_form(s, "tcp")                     # min (1 + u/2)^2 + u^2/2: u = -2/3, J = 2/3
    >>> compare(np.array([[-2 / 3]]), 2 / 3, ref, s).cost_rel_diff < 1e-12
    True
    >>> compare(np.array([[-0.5]]), 0.75, ref, s)      # the UDP-like optimum is not the TCP-like one
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.CrossCheckError: the QP twin and the closed form disagree: J_qp = 0.75, ...
    """
    if not isinstance(reference, Solution):
        raise InputError("reference", f"expected a Solution (e.g. from closed_form), found {type(reference).__name__}")
    expected = np.asarray(reference.inputs)
    if expected.shape != inputs.shape:
        raise InputError("reference", f"expected a Solution of this system (inputs of shape {inputs.shape}), "
                                      f"found inputs of shape {expected.shape}")
    mu = system.mu_schedule
    diff = float(np.abs(mu * (inputs - expected)).max(initial=0.0))
    input_scale = max(float(np.abs(mu * expected).max(initial=0.0)), CROSS_CHECK_FLOOR * scale[1])
    delta = abs(cost - reference.cost)
    cost_scale = max(abs(reference.cost), CROSS_CHECK_FLOOR * scale[0])
    rel = delta / cost_scale if cost_scale > 0 else (0.0 if delta == 0 else float("inf"))
    if not (diff <= CROSS_CHECK_INPUT_ATOL * input_scale and rel <= CROSS_CHECK_COST_RTOL):
        raise CrossCheckError(
            f"the QP twin and the closed form disagree: J_qp = {cost:.10g}, J* = {reference.cost:.10g} "
            f"({reference.method}), rel dJ = {rel:.1e} (tolerance {CROSS_CHECK_COST_RTOL:.0e}), max|Vbar dU| = "
            f"{diff:.1e} (tolerance {CROSS_CHECK_INPUT_ATOL * input_scale:.1e})",
            {"qp": cost, reference.method: reference.cost})
    return CrossCheck(reference_method=reference.method, max_input_diff=diff, cost_rel_diff=rel)


# ---------------------------------------------------------------------------------------- the interface

def choose_backend(system: System, formulation: str) -> type[Backend]:
    """The backend class for ``formulation``: "condensed", "sparse", or "auto" (condensed while
    N m <= ``AUTO_CONDENSED_MAX``, the measured crossover). O(1).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=100, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> choose_backend(s, "auto").__name__, choose_backend(s, "condensed").formulation
    ('SparseBackend', 'condensed')
    """
    if formulation == "auto":
        formulation = "condensed" if system.horizon * system.m <= AUTO_CONDENSED_MAX else "sparse"
    backends = {cls.formulation: cls for cls in (CondensedBackend, SparseBackend)}
    if formulation not in backends:
        raise InputError("formulation", f"expected 'condensed', 'sparse' or 'auto', found {formulation!r}")
    return backends[formulation]


def qp_memory_estimate(system: System, formulation: str) -> float:
    """Bytes the chosen backend's QP needs at its peak, known before building it: linear in N
    (`Backend.memory_estimate`).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> qp_memory_estimate(s, "sparse")                 # 260 + 400 + 650 + 1e7
    10001310.0
    >>> qp_memory_estimate(s, "condensed") - qp_memory_estimate(s, "sparse")   # one 1x1 dense block
    150.0
    """
    return choose_backend(check_system(system), formulation).memory_estimate(system)


class ExpectedCostQP:
    """One protocol's expected-cost QP for one system, re-solvable for new mu or x0.

    ``ExpectedCostQP(system, protocol, formulation)`` builds the backend the function `choose_backend` picks
    for ``formulation`` (`CondensedBackend` or `SparseBackend`) and keeps it as ``backend``.
    An instance is not thread-safe (it keeps the current x, mu); the condensed backend's compiled
    problems are shared by shape and thread-safe (`.shared`).

    Parameters
    ----------
    system : System
        Supplies A, B, weights and horizon (fixed) and the initial mu, x0 (parameters).
    protocol : {"tcp", "udp"}
    formulation : {"condensed", "sparse", "auto"}
    constraints : Constraints or mapping, optional
        Input, rate, expected-state and chance constraints:
        [`solve`][packetloss_cvx.qp.expected_cost.ExpectedCostQP.solve] then solves the constrained problem
        (`ConstrainedQP`, kept as ``constrained``) and returns its
        `ConstrainedSolution` (no gain, no closed form to compare with).
    solver : str, optional
        With ``constraints``: any installed cvxpy solver (default Clarabel).

    Raises
    ------
    BudgetError
        The QP's work (`qp_work`, its horizon) beyond the ``solve_work`` budget, under
        ``horizon``, before cvxpy sees it; its memory (`Backend.memory_estimate`) beyond the ``memory_bytes`` budget,
        under ``horizon`` too.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> qp = ExpectedCostQP(s, "udp", "sparse")
    >>> qp.formulation, type(qp.backend).__name__
    ('sparse', 'SparseBackend')
    >>> a, b = qp.solve(), qp.solve(mu=[0.9])      # the second re-uses the compiled problem
    >>> bool(b.cost < a.cost)
    True
    """

    def __init__(self, system: System, protocol: str, formulation: str = "auto", *, constraints=None,
                 solver: str | None = None) -> None:
        system = check_system(system)
        backend = choose_backend(system, formulation)
        #: with ``constraints``: the :class:`~packetloss_cvx.qp.constrained.ConstrainedQP` that :meth:`solve` runs
        #: (its ``problem``, ``U``, ``states``, ``x0``, ``mu`` public); None without
        self.constrained = None
        if constraints is not None or solver is not None:
            from .constrained import ConstrainedQP

            self.constrained = ConstrainedQP(system, protocol, {} if constraints is None else constraints,
                                             backend.formulation, solver)
        #: the backend's name ("condensed" or "sparse"), reported as ``Solution.method = "qp-<formulation>"``
        self.formulation = backend.formulation
        self.protocol = check_protocol(protocol)
        refuse_correlated(system, self.protocol)
        self.system = system
        N, n, m = system.horizon, system.n, system.m
        work = qp_work(N, n, m, self.formulation)       # the horizon priced before cvxpy sees it (budgets.py)
        check("solve_work", work, "horizon", f"the {self.formulation} QP of N = {N} (n = {n}, m = {m}), about "
                                             f"{duration_text(estimated_seconds('solve_work', work))}")
        needed = backend.memory_estimate(system)
        check("memory_bytes", needed, "horizon",
              f"the {self.formulation} QP of N = {N} (n = {n}, m = {m}; about {gib_text(needed)}: cvxpy keeps ~260 "
              f"N n^2 bytes of state terms)",
              instead="use the closed forms, which need no QP (closed_form; solve --no-qp), or a shorter horizon"
              + (" or formulation='sparse'" if self.formulation == "condensed" else ""))
        self._d, self._noise = udp_variance_weights(system)
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
        #: the formulation's data, problems and steps (:class:`Backend`), built at the current scale
        self.backend = backend(self)
        self._assign(system.mu_schedule, system.x0, self.protocol)

    # ------------------------------------------------------------------ shared by both backends
    def _weights(self, mu: np.ndarray, free: np.ndarray, protocol: str) -> np.ndarray:
        """The input terms' weights ``(psi + [UDP] d (1 - mu)) / (mu s)`` per entry (N×m; 1/s where pinned)."""
        d = np.where(mu < 1.0, self._d * (1.0 - mu), 0.0) if protocol == "udp" else 0.0
        return (self.system.input_weights + d) / (np.where(free, mu, 1.0) * self._scale)

    def _assign(self, mu: np.ndarray, x: np.ndarray, protocol: str) -> None:
        self._free = mu > QP_PIN_MU
        self._v = mu.ravel()
        self.backend.select(mu, self._free, protocol)
        # x is a System's validated state (x0, or x0 scaled): kept as cvxpy keeps a value (save_value), without the
        # value setter's validation of it again (a tenth of a condensed solve's Python time)
        self.x.save_value(x)

    def _solve_raw(self, protocol: str) -> tuple[np.ndarray, float, str]:
        what = f"{protocol}-like {self.formulation} QP"
        u = np.zeros(self._v.size)         # an input never delivered changes nothing: reported as 0
        flat = self._free.ravel()
        if not flat.any():                 # nothing delivered: the open-loop state cost
            return u, self.backend.open_loop(), "optimal"
        try:
            z, value, status = self.backend.minimise(what)
        except SolverError as err:
            raise self._out_of_range(err.status, protocol) from None
        if status not in ACCEPTED_STATUSES:
            raise self._out_of_range(status, protocol)
        u[flat] = np.asarray(z).ravel() / self._v[flat]     # U = Vbar^{-1} Z where mu > QP_PIN_MU
        return u, float(value), status

    def _rescale(self, value: float) -> None:
        """Multiply the common scale by ``value`` (the last scaled minimum, positive). O(N n (n + m))."""
        self.backend.rescale_data(1.0 / np.sqrt(value))
        self._scale *= value

    def _solve_scaled(self, mu: np.ndarray, x: np.ndarray, protocol: str) -> tuple[np.ndarray, float, str]:
        """Solve at the unit state ``x``; where the scaled minimum v is below ``QP_RESCALE_BELOW`` (Clarabel's
        absolute gap could then exceed CROSS_CHECK_COST_RTOL v), rescale by v and solve again, at most
        ``QP_RESCALE_PASSES`` times, keeping the new scale. Raises NumericalError if v stays below it while
        the minimum is not exactly zero (some weighted state moves). The minimiser does not depend on the scale."""
        def too_small(v: float) -> bool:      # below the threshold, with a minimum that is not exactly zero
            return v < QP_RESCALE_BELOW and self._free.any() and self.backend.open_loop() > 0.0

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
        """Raise when the minimum v = ||c + G z||^2 + ||r z||^2 (c = L Phi x, `Backend.state_size`), a squared
        residual of terms of size ||c||, is below double precision's resolution at CROSS_CHECK_COST_RTOL (2 eps
        ||c|| / sqrt(v) relative): there Clarabel may say 'optimal' with v wrong in the third digit. O(N n)."""
        c = self.backend.state_size() if self._free.any() else 0.0
        if not 2.0 * np.finfo(float).eps * c <= CROSS_CHECK_COST_RTOL * np.sqrt(max(value, 0.0)):
            raise NumericalError(
                f"the {protocol}-like {self.formulation} QP's minimum {value:.3g} is the square of a residual of "
                f"terms of size {c:.3g}, which double precision cannot resolve to {CROSS_CHECK_COST_RTOL:.0e}: the "
                f"problem's scale is beyond the solver's range (open-loop growth rho(A)^N = "
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
        through [`System`][packetloss_cvx.model.system.System]. With ``with_gain`` the gain K is recovered by n more
        solves at the unit states (U* is linear in x). The solver's objective is checked
        against the forward cost of its own plan where that cost is resolved to ``PLAN_COST_RTOL``
        ([`plan_cost`][packetloss_cvx.lq.recursion.plan_cost]; an unstable plant over a long horizon amplifies a fixed
        plan's rounding beyond it, and there the cross-check binds).
        With ``cross_check`` the answer is compared with ``reference`` (default:
        [`closed_form`][packetloss_cvx.lq.costs.closed_form], method "auto") by
        [`compare`][packetloss_cvx.qp.expected_cost.compare], and a disagreement beyond ``CROSS_CHECK_INPUT_ATOL`` /
        ``CROSS_CHECK_COST_RTOL`` raises.

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
        if self.constrained is not None:
            if protocol != self.protocol:
                raise InputError("protocol", f"this QP's constraints were compiled for the {self.protocol}-like "
                                             f"protocol, found {protocol!r}: build another ExpectedCostQP")
            return self.constrained.solve(mu, x0)
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
        forward, bound = plan_cost(system, u.reshape(N, m), protocol, (self._d, self._noise))
        if bound <= PLAN_COST_RTOL * forward and not abs(cost - forward) <= CROSS_CHECK_COST_RTOL * forward:
            raise NumericalError(
                f"the {protocol}-like {self.formulation} QP reports J = {cost:.10g} but the forward cost of its "
                f"own plan is {forward:.10g}: the solver lost the problem's scale (weights spanning many orders "
                "of magnitude, or an unstable plant over a long horizon)")
        gain = None
        eigs = None
        if with_gain:
            columns = []
            for j in range(n):
                self.x.save_value(np.eye(n)[j])         # a unit state: nothing to validate
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


class CondensedExpectedCostQP(ExpectedCostQP):
    """[`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP] with the condensed formulation
        (`CondensedBackend`).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> sol = CondensedExpectedCostQP(s, "tcp").solve(cross_check=False)   # u = -2/3, J = 2/3
    >>> sol.method, bool(np.allclose([sol.inputs[0, 0], sol.cost], [-2 / 3, 2 / 3], atol=1e-7))
    ('qp-condensed', True)
    """

    def __init__(self, system: System, protocol: str, formulation: str = "condensed") -> None:
        _fixed("condensed", formulation)
        super().__init__(system, protocol, "condensed")


class SparseExpectedCostQP(ExpectedCostQP):
    """[`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP] with the sparse formulation (`SparseBackend`).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> sol = SparseExpectedCostQP(s, "tcp").solve(cross_check=False)      # u = -2/3, J = 2/3
    >>> sol.method, bool(np.allclose([sol.inputs[0, 0], sol.cost], [-2 / 3, 2 / 3], atol=1e-7))
    ('qp-sparse', True)
    """

    def __init__(self, system: System, protocol: str, formulation: str = "sparse") -> None:
        _fixed("sparse", formulation)
        super().__init__(system, protocol, "sparse")


def _fixed(own: str, formulation: str) -> None:
    if formulation not in ("auto", own):
        raise InputError("formulation", f"the {own} QP's backend is {own!r}, found {formulation!r}")


# ---------------------------------------------------------------------------------------- what a backend provides

class Backend:
    """One formulation of the expected-cost QP: its data, its compiled problems and four steps, run by the
    [`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP] ``qp`` that holds it (whose state ``qp.x``,
    weights and common scale ``qp._scale`` it reads). Built with the data at the current scale."""

    #: the formulation's name, reported as ``Solution.method = "qp-<formulation>"``
    formulation = ""

    def __init__(self, qp: ExpectedCostQP) -> None:
        self.qp = qp

    @classmethod
    def memory_estimate(cls, system: System) -> float:
        """Bytes this backend's QP needs at its peak (measured; docs/performance.md). O(1)."""
        raise NotImplementedError

    def select(self, mu: np.ndarray, free: np.ndarray, protocol: str) -> None:
        """Make the problem for ``mu`` (N×m) with the entries ``free`` current (``qp.x`` is set after)."""
        raise NotImplementedError

    def minimise(self, what: str) -> tuple[np.ndarray | None, float, str]:
        """``(z, value, status)`` of the current problem (some entry free): z on the free entries, the scaled
        minimum. Raises SolverError when cvxpy or Clarabel fails outright."""
        raise NotImplementedError

    def open_loop(self) -> float:
        """The scaled objective at z = 0 (no input delivered), an upper bound of the minimum that is zero exactly
        when the minimum is (no weighted state moves)."""
        raise NotImplementedError

    def rescale_data(self, root: float) -> None:
        """Multiply the backend's state-weight factor by ``root`` (the common scale grew by 1 / root^2)."""
        raise NotImplementedError

    def state_size(self) -> float:
        """||c|| for a backend whose minimum is the squared residual ``||c + G z||^2`` (0 when it is not)."""
        return 0.0


# ---------------------------------------------------------------------------------------- the condensed backend

def condensed_data(system: System, scale: float) -> tuple[np.ndarray, np.ndarray] | None:
    """``(L Phi, L Gamma) / sqrt(scale)`` with ``L'L = blockdiag(Omega_1..Omega_N)`` (zero directions
    dropped), or None without any state weight: the state term ``||L (Phi x + Gamma z)||^2 / scale``.
    O((N n)^2 N m) time, O((N n) N (n + m)) memory.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weight=[4], input_weight=[1], mu=[0.5], x0=[1])
    >>> LPhi, LGamma = condensed_data(s, 4.0)           # L = I / 1: xhat_1 = x + z_1, xhat_2 = x + z_1 + z_2
    >>> LPhi.ravel().tolist(), LGamma.tolist()
    ([1.0, 1.0], [[1.0, 0.0], [1.0, 1.0]])
    """
    pred = prediction(system)
    L = sla.block_diag(*[psd_factor(W) for W in system.state_weights]) / np.sqrt(scale)
    return (L @ pred.Phi, L @ pred.Gamma) if L.shape[0] else None


class CondensedBackend(Backend):
    """The condensed backend: ``min ||c + G z||^2 + ||r ∘ z||^2`` over the free entries z, with
    ``c = L Phi x / sqrt(s)``, ``G = (L Gamma / sqrt(s))[:, free]`` (`condensed_data`) and ``r`` the
    square roots of the input weights; solved by the problem compiled once per padded shape and shared
    with every other system of that shape in the process (`.shared.condensed_problem`), or,
    beyond ``SHARED_MAX_ENTRIES``, by this object's own problem of the exact shape. Dense data:
    build O((N n)^2 N m), solve O((N m)^3).

    Examples
    --------
    x' = x + z from x = 1 over two steps, weights 1, mu = 1/2 (input weight psi / mu = 2): z = 0 leaves
    x = 1, 1 (open loop 2); the minimum of (1 + z1)^2 + (1 + z1 + z2)^2 + 2 z1^2 + 2 z2^2 is 10/11 (by hand).

    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> backend = ExpectedCostQP(s, "tcp", "condensed").backend
    >>> z, value, status = backend.minimise("a demo")
    >>> backend.open_loop(), bool(np.isclose(value, 10 / 11, rtol=1e-8)), status
    (2.0, True, 'optimal')
    """

    formulation = "condensed"

    @classmethod
    def memory_estimate(cls, system: System) -> float:
        """The sparse form's bytes plus the dense (N n)×(N m) data, a Parameter since the problems are shared by
        shape (`qp_bytes`; 66-88 bytes an entry when they were constants:
        `.shared`). O(1)."""
        return qp_bytes(system.horizon, system.n, system.m, "condensed")

    def __init__(self, qp: ExpectedCostQP) -> None:
        super().__init__(qp)
        self._data = condensed_data(qp.system, qp._scale)        # (L Phi, L Gamma) / sqrt(scale), or None
        self._own: dict[tuple, object] = {}                      # beyond SHARED_MAX_ENTRIES: per shape

    def select(self, mu: np.ndarray, free: np.ndarray, protocol: str) -> None:
        flat = free.ravel()           # the shared problem's data: its Parameters are set per solve
        self._G = self._data[1][:, flat] if self._data is not None else np.zeros((0, int(flat.sum())))
        self._r = np.sqrt(self.qp._weights(mu, free, protocol).ravel()[flat])

    def minimise(self, what: str) -> tuple[np.ndarray | None, float, str]:
        c = self._data[0] @ self.qp.x.value if self._data is not None else np.zeros(0)
        problem = self._own.get(self._G.shape) or condensed_problem(*self._G.shape)
        if not problem.shared:
            self._own[self._G.shape] = problem
        return problem.solve(c, self._G, self._r, what)

    def open_loop(self) -> float:
        """O((N n) n)."""
        return float(np.sum((self._data[0] @ self.qp.x.value) ** 2)) if self._data is not None else 0.0

    def rescale_data(self, root: float) -> None:
        """The data are rescaled in place (the shared problems take them as Parameters)."""
        self._data = None if self._data is None else (self._data[0] * root, self._data[1] * root)

    def state_size(self) -> float:
        return float(np.linalg.norm(self._data[0] @ self.qp.x.value)) if self._data is not None else 0.0


# ---------------------------------------------------------------------------------------- the sparse backend

def sparse_dynamics(system: System) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """Block-sparse mean-state dynamics and state-weight factor for X = (xhat_1..xhat_N):
    ``E X - Bbig z = first x0`` encodes ``xhat_{t+1} = A xhat_t + B z_t``, and
    ``||L X||^2 = sum_t xhat_t' Omega_t xhat_t``. The sparse backend's constants (and the TCP-like
    allocation SOCP's, `tcp`). O(N (n^2 + n m)) nonzeros.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> E, Bbig, first, L = sparse_dynamics(s)          # z = (1, 2): xhat_1 = 1 + 1, xhat_2 = 2 + 2
    >>> np.linalg.solve(E.toarray(), Bbig @ [1.0, 2.0] + first @ s.x0).tolist()
    [2.0, 4.0]
    """
    N, n = system.horizon, system.n
    E = sp.eye(N * n, format="csr") - sp.kron(sp.eye(N, k=-1), system.A, format="csr")
    Bbig = sp.kron(sp.eye(N), system.B, format="csr")
    first = sp.csr_matrix(np.vstack([system.A, np.zeros(((N - 1) * n, n))]))
    L = sp.block_diag([psd_factor(W) for W in system.state_weights], format="csr")
    return E, Bbig, first, L


class SparseBackend(Backend):
    """The sparse backend: the mean states and ``Z = Vbar U`` (free entries) as variables, the dynamics
    as equality constraints (`sparse_dynamics`), compiled by this object per protocol and pinned set
    (stationary channel: ``1/mu``, ``1/mu - 1`` as Parameters) or per schedule (weights as constants).
    Build and solve O(N (n + m)^3), memory O(N (n + m)^2).

    Examples
    --------
    The case of `CondensedBackend`'s example: open loop 2, minimum 10/11 (by hand).

    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> backend = ExpectedCostQP(s, "tcp", "sparse").backend
    >>> z, value, status = backend.minimise("a demo")
    >>> backend.open_loop(), bool(np.isclose(value, 10 / 11, rtol=1e-8)), status
    (2.0, True, 'optimal')
    """

    formulation = "sparse"

    @classmethod
    def memory_estimate(cls, system: System) -> float:
        """Measured (`qp_bytes`): about 250 N n^2 bytes for the state terms, 350 N n m
        for the dynamics' input columns and 610 N m for the input terms, plus cvxpy's and Clarabel's fixed ~10 MB.
        O(1)."""
        return qp_bytes(system.horizon, system.n, system.m, "sparse")

    def __init__(self, qp: ExpectedCostQP) -> None:
        super().__init__(qp)
        E, Bbig, first, L = sparse_dynamics(qp.system)
        self._dynamics = (E, Bbig, first)
        self._L = L / np.sqrt(qp._scale)
        self._problems: dict[tuple, tuple] = {}      # compiled per pinned set / schedule

    def select(self, mu: np.ndarray, free: np.ndarray, protocol: str) -> None:
        if not free.any():            # nothing delivered: no problem to solve (:meth:`open_loop`)
            return
        if np.all(mu == mu[0]):       # one problem per protocol: a zero-weighted diag(Omega_g) term of an
            # unstable plant (1e70) made Clarabel fail the TCP-like QP it solved without the term
            self._build(("stationary", protocol, free[0].tobytes()), free, None)
            if self._params is not None:
                v = mu[0][free[0]]
                self._params[0].value = 1.0 / v
                self._params[1].value = np.where(v < 1.0, 1.0 / v - 1.0, 0.0)
        else:
            self._build(("schedule", protocol, mu.tobytes()), free, self.qp._weights(mu, free, protocol))

    def _build(self, key: tuple, free: np.ndarray, weight: np.ndarray | None) -> None:
        """The problem for the entries ``free`` (N×m, mu > QP_PIN_MU, at least one): built on first use, kept
        per key.

        Variables: the mean states and the mean delivered inputs ``Z = Vbar U`` on the free entries
        (the others pinned to zero, ``tolerances.QP_PIN_MU``); input terms ``sum (psi + [UDP] d (1 - mu))
        z^2 / mu`` (eq:opt-lqg-simplest with Lemma 1, d = diag(Omega_g)). A stationary channel
        (``weight`` None) enters through two Parameters per channel, ``1/mu`` and ``1/mu - 1``, each
        multiplying ``sum(W * square(Z), 0)``: no Parameter multiplies a Variable and the canonicalisation
        stays linear in N (docs/performance.md). A schedule's weights are constants (rebuilt per
        schedule). O(N (n^2 + n m)) nonzeros.
        """
        if key in self._problems:
            self.problem, self.Z, self._params = self._problems[key]
            return
        qp = self.qp
        N, n, m = qp.system.horizon, qp.system.n, qp.system.m
        flat = free.ravel()
        k = int(flat.sum())
        select = sp.csr_matrix((np.ones(k), (np.flatnonzero(flat), np.arange(k))), shape=(N * m, k))
        params = None
        terms = []
        if weight is None:            # Z as N × (free channels); flat Z is step-major
            channels = np.flatnonzero(free[0])
            Z = cp.Variable((N, len(channels)), name="Z")
            flat_Z = cp.vec(Z.T, order="F")
            params = (cp.Parameter(len(channels), nonneg=True, name="inv_mu"),
                      cp.Parameter(len(channels), nonneg=True, name="inv_mu_minus_one"))
            psi, d = qp.system.input_weights / qp._scale, qp._d / qp._scale
            terms.append(params[0] @ cp.sum(cp.multiply(psi[:, channels], cp.square(Z)), axis=0))
            if key[1] == "udp":
                terms.append(params[1] @ cp.sum(cp.multiply(d[:, channels], cp.square(Z)), axis=0))
        else:
            Z = flat_Z = cp.Variable(k, name="Z")
            terms.append(cp.sum_squares(cp.multiply(np.sqrt(weight.ravel()[flat]), Z)))
        E, Bbig, first = self._dynamics
        X = cp.Variable(N * n, name="xhat")
        constraints = [E @ X - (Bbig @ select) @ flat_Z == first @ qp.x]
        if self._L.shape[0]:
            terms.append(cp.sum_squares(self._L @ X))
        problem = cp.Problem(cp.Minimize(cp.sum(terms)), constraints)
        if not problem.is_dpp():  # pragma: no cover - construction guarantees it
            raise RuntimeError("expected-cost QP is not DPP")
        if weight is not None:
            self._problems = {k_: v_ for k_, v_ in self._problems.items() if k_[0] != "schedule"}
        self._problems[key] = (problem, Z, params)
        self.problem, self.Z, self._params = problem, Z, params

    def minimise(self, what: str) -> tuple[np.ndarray | None, float, str]:
        status = solve_problem(self.problem, what, attempts=(CLARABEL_SETTINGS,))
        return self.Z.value, self.problem.value, status

    def open_loop(self) -> float:
        """A block-bidiagonal solve, O(N n^2)."""
        E, _, first = self._dynamics
        return float(np.sum((self._L @ spla.spsolve_triangular(E, first @ self.qp.x.value)) ** 2)) \
            if self._L.shape[0] else 0.0

    def rescale_data(self, root: float) -> None:
        """The problems, whose weights are constants, are dropped and rebuilt on their next use."""
        self._L = self._L * root
        self._problems = {}


def solve_qp(system: System, protocol: str, formulation: str = "auto", **kwargs) -> Solution:
    """Minimise the protocol's expected cost with cvxpy + Clarabel (the minimisation of eq:opt-lqg).

    Builds an [`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP] and solves it once; keep the object to
    re-solve for other mu or x0 without recompiling. Keyword arguments go to
    [`ExpectedCostQP.solve`][packetloss_cvx.qp.expected_cost.ExpectedCostQP.solve].

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> sol = solve_qp(s, "tcp")                        # min (1 + u/2)^2 + u^2/2: u = -2/3, J = 2/3
    >>> bool(np.allclose([sol.inputs[0, 0], sol.cost], [-2 / 3, 2 / 3], atol=1e-7))
    True
    """
    return ExpectedCostQP(system, protocol, formulation).solve(**kwargs)
