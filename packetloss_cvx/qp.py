"""The expected-cost minimisation as cvxpy QPs solved with Clarabel (the solver twin).

Two formulations of the same problem, both DPP: they are built once from
``cp.Parameter``s (the channel ``v``, the state ``x`` and two derived weight
vectors) and re-solved by assigning new values, without recompiling.

* ``"condensed"``: variables U only; ``sum_squares(L Phi x + L Gamma (v∘U))``.
  Dense constants of size (N n)×(N m): build O((N n)^2 N m), solve O((N m)^3).
* ``"sparse"``: mean states and inputs as variables, the dynamics
  ``xhat_{t+1} = A xhat_t + B (v_t∘u_t)`` as equality constraints; every
  constant is block-sparse, so build and solve are O(N (n + m)^3).

The UDP-like term ``U' Vbar Omega_d (I - Vbar) U`` enters as
``sum_squares(w∘U)`` with ``w = sqrt(v (1 - v) diag(Omega_g))``; the diagonal of
Omega_g comes from the backward Lyapunov sum (:func:`udp_variance_weights`).
"""

from __future__ import annotations

import time

import cvxpy as cp
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .convex import require_optimal, solve_problem
from .errors import InputError
from .linalg import psd_factor
from .model import System
from .protocols import check_protocol
from .recursion import udp_variance_weights
from .results import CrossCheck, Solution
from .tolerances import CLARABEL_TIGHT

__all__ = ["CLARABEL_SETTINGS", "ExpectedCostQP", "solve_qp", "sparse_dynamics"]

#: Tightened Clarabel tolerances (tolerances.CLARABEL_TIGHT): the cross-check promises inputs to 1e-6.
CLARABEL_SETTINGS = CLARABEL_TIGHT

#: Above this many decision variables N*m, ``formulation="auto"`` uses the sparse form
#: (measured crossover between N*m = 40 and 80 for n = 4: docs/performance.md).
AUTO_CONDENSED_MAX = 60


def sparse_dynamics(system: System) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """Block-sparse mean-state dynamics and state-weight factor for X = (xhat_1..xhat_N):
    ``E X - Bbig z = first x0`` encodes ``xhat_{t+1} = A xhat_t + B z_t``, and
    ``||L X||^2 = sum_t xhat_t' Omega_t xhat_t``. O(N (n^2 + n m)) nonzeros."""
    N, n = system.horizon, system.n
    E = sp.eye(N * n, format="csr") - sp.kron(sp.eye(N, k=-1), system.A, format="csr")
    Bbig = sp.kron(sp.eye(N), system.B, format="csr")
    first = sp.csr_matrix(np.vstack([system.A, np.zeros(((N - 1) * n, n))]))
    L = sp.block_diag([psd_factor(W) for W in system.state_weights], format="csr")
    return E, Bbig, first, L


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
        self.protocol = check_protocol(protocol)
        self.formulation = _pick(system, formulation)
        self.system = system
        N, n, m = system.horizon, system.n, system.m
        self._d, self._noise = udp_variance_weights(system)
        self.v = cp.Parameter(N * m, nonneg=True, name="v")
        self.x = cp.Parameter(n, name="x")
        self.r = cp.Parameter(N * m, nonneg=True, name="sqrt_v_psi")
        self.U = cp.Variable(N * m, name="U")
        terms = [cp.sum_squares(cp.multiply(self.r, self.U))]
        if self.protocol == "udp":
            self.w = cp.Parameter(N * m, nonneg=True, name="sqrt_udp_weight")
            terms.append(cp.sum_squares(cp.multiply(self.w, self.U)))
        vu = cp.multiply(self.v, self.U)
        constraints = []
        if self.formulation == "condensed":
            from .prediction import prediction

            pred = prediction(system)
            L = sla.block_diag(*[psd_factor(W) for W in system.state_weights])
            if L.shape[0]:  # all state weights zero: no state term at all
                terms.append(cp.sum_squares(L @ pred.Phi @ self.x + (L @ pred.Gamma) @ vu))
        else:
            X = cp.Variable(N * n, name="xhat")
            E, Bbig, first, L = sparse_dynamics(system)
            constraints.append(E @ X - Bbig @ vu == first @ self.x)
            if L.shape[0]:
                terms.append(cp.sum_squares(L @ X))
        self.problem = cp.Problem(cp.Minimize(cp.sum(terms)), constraints)
        if not self.problem.is_dpp():  # pragma: no cover - construction guarantees it
            raise RuntimeError("expected-cost QP is not DPP")

    def _assign(self, mu: np.ndarray, x: np.ndarray) -> None:
        v = mu.ravel()
        self.v.value = v
        self.x.value = x
        self.r.value = np.sqrt(v * self.system.input_weights.ravel())
        if self.protocol == "udp":
            weight = np.where(v < 1.0, self._d.ravel() * v * (1.0 - v), 0.0)
            self.w.value = np.sqrt(weight)

    def _solve_raw(self) -> tuple[np.ndarray, float, str]:
        what = f"{self.protocol}-like {self.formulation} QP"
        status = solve_problem(self.problem, what, attempts=(CLARABEL_SETTINGS,))
        require_optimal(status, what)
        return np.asarray(self.U.value), float(self.problem.value), status

    def solve(self, mu=None, x0=None, *, with_gain: bool = True, cross_check: bool = True) -> Solution:
        """Solve for the current (or the given) channel and state.

        ``mu`` is an m-vector or an N×m schedule; ``x0`` an n-vector. Both are validated
        through :class:`System`. With ``with_gain`` the gain K is recovered by n more
        solves at the unit states (U* is linear in x). With ``cross_check`` the answer is
        compared with :func:`closed_form` (method "auto").

        Raises
        ------
        SolverError
            Any status other than "optimal" (``optimal_inaccurate`` included), with the status.
        """
        system = self.system
        if mu is not None:
            system = system.with_mu(mu)
        if x0 is not None:
            system = system.with_x0(x0)
        N, n, m = system.horizon, system.n, system.m
        start = time.perf_counter()
        self._assign(system.mu_schedule, system.x0)
        u, value, status = self._solve_raw()
        solve_time = time.perf_counter() - start
        x = system.x0
        cost = value + float(x @ system.initial_weight @ x) + self._noise
        gain = None
        eigs = None
        if with_gain:
            columns = []
            for j in range(n):
                self.x.value = np.eye(n)[j]
                columns.append(-self._solve_raw()[0][:m])
            self.x.value = x
            gain = np.column_stack(columns)
            eigs = np.linalg.eigvals(system.A - system.B @ gain)
        check = None
        if cross_check:
            from .costs import closed_form

            ref = closed_form(system, self.protocol, method="auto")
            mask = system.mu_schedule.ravel() > 0
            diff = np.abs(u - ref.inputs.ravel())[mask]
            check = CrossCheck(
                reference_method=ref.method,
                max_input_diff=float(diff.max(initial=0.0)),
                cost_rel_diff=abs(cost - ref.cost) / max(1.0, abs(ref.cost)),
            )
        return Solution(
            protocol=self.protocol, cost=cost, inputs=u.reshape(N, m), gain=gain,
            closed_loop_eigenvalues=eigs, method=f"qp-{self.formulation}", status=status,
            solve_time=solve_time, cross_check=check,
        )


def solve_qp(system: System, protocol: str, formulation: str = "auto", **kwargs) -> Solution:
    """Minimise the protocol's expected cost with cvxpy + Clarabel.

    Builds an :class:`ExpectedCostQP` and solves it once; keep the object to re-solve
    for other mu or x0 without recompiling. Keyword arguments go to
    :meth:`ExpectedCostQP.solve`.
    """
    return ExpectedCostQP(system, protocol, formulation).solve(**kwargs)
