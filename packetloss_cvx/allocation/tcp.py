"""TCP-like allocation: with ``Z = Vbar U`` the expected cost is jointly convex in (Z, mu), so
the cost-sublevel set is convex and the allocation is an SOCP (eq:channel-opt)."""

from __future__ import annotations

import cvxpy as cp
import numpy as np

from ..costs import closed_form
from ..errors import InfeasibleError, SolverError
from ..model import System
from ..qp import sparse_dynamics
from ..recursion import udp_variance_weights
from .boxes import solve_clarabel
from .grammar import base_constraints

__all__ = ["TCPProgram", "tcp_allocate", "tcp_min_cost"]


class TCPProgram:
    """J_tcp(Z, mu) in cvxpy, sparse in the horizon; mu is a variable."""

    def __init__(self, system: System) -> None:
        N, n, m = system.horizon, system.n, system.m
        self.system = system
        self.mu = cp.Variable(m, name="mu")
        Zv = cp.Variable((N, m), name="Z")
        X = cp.Variable(N * n, name="xhat")
        E, Bbig, first, L = sparse_dynamics(system)
        psi = system.input_weights
        terms = [cp.sum_squares(L @ X)] if L.shape[0] else []
        for i in range(m):
            terms.append(cp.quad_over_lin(cp.multiply(np.sqrt(psi[:, i]), Zv[:, i]), self.mu[i]))
        x0 = system.x0
        self.constant = float(x0 @ system.initial_weight @ x0) + udp_variance_weights(system)[1]  # + noise
        self.cost = cp.sum(terms) + self.constant
        self.dynamics = [E @ X - Bbig @ cp.vec(Zv.T, order="F") == first @ system.x0]


def tcp_min_cost(system: System, lo, hi, G, h, calls) -> float:
    prog = TCPProgram(system)
    problem = cp.Problem(cp.Minimize(prog.cost), prog.dynamics + base_constraints(prog.mu, lo, hi, G, h, calls))
    solve_clarabel(problem, "TCP-like minimum cost")
    if problem.status == cp.INFEASIBLE:
        raise InfeasibleError("the linear constraints and bounds admit no mu", None)
    if problem.status != cp.OPTIMAL:
        raise SolverError(problem.status, "TCP-like minimum cost")
    return closed_form(system.with_mu(np.clip(prog.mu.value, 0, 1)), "tcp", "auto").cost


def tcp_allocate(system, alpha, beta, lo, hi, G, h, calls) -> tuple[np.ndarray, str]:
    prog = TCPProgram(system)
    cons = prog.dynamics + [prog.cost <= alpha] + base_constraints(prog.mu, lo, hi, G, h, calls)
    problem = cp.Problem(cp.Minimize(beta @ prog.mu), cons)
    solve_clarabel(problem, "TCP-like allocation")
    if problem.status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        return None, problem.status
    if problem.status != cp.OPTIMAL:
        raise SolverError(problem.status, "TCP-like allocation")
    return np.clip(prog.mu.value, lo, hi), problem.status
