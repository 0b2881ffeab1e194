"""The cases an audit checks: the paper's systems and seeded random ones, with a cache of
the solver runs that several claims share."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..closedloop.riccati import dp_riccati
from ..errors import NumericalError
from ..lq.evaluator import CostEvaluator
from ..model.files import load_example, system_from_dict
from ..model.protocols import check_protocol
from ..model.system import System
from ..results import Riccati, Solution

__all__ = ["Context", "interior", "loop_case", "paper_systems"]


@dataclass
class Context:
    """The cases: the paper's systems (by name) and seeded random systems.

    Attributes
    ----------
    paper : dict of str to System
        The paper's systems, by example name.
    random : list of System
        The caller's systems, then the seeded random ones.
    seed : int
        The audit's seed; each check derives its own generator from it.
    extra : int
        How many of ``random`` (at its start) are the caller's systems.
    cache : dict
        Solver answers shared between checks (see `qp`).
    problems, evaluators : dict
        QP twins per system ([`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP]: its data built once;
        the condensed problems it solves are compiled once per padded shape and shared by every case, `shared`)
        and cost evaluators per (system, protocol), keyed by ``id`` (the cases live as long as the context).
    riccati : dict
        The DP optimum per case (`dp`), or the NumericalError it raised, keyed by ``id``.
    simple : dict
        The simple systems the claims' shrinking tries, per seed (`.evaluate.simple_systems`): drawn
        once per audit, so their cached structure is shared by every claim that shrinks.
    """

    paper: dict[str, System]
    random: list[System]
    seed: int
    extra: int = 0
    cache: dict = field(default_factory=dict)
    problems: dict = field(default_factory=dict)
    evaluators: dict = field(default_factory=dict)
    riccati: dict = field(default_factory=dict)
    simple: dict = field(default_factory=dict)

    @property
    def cases(self) -> list[System]:
        """The paper's systems, then ``random``."""
        return list(self.paper.values()) + self.random

    def label(self, system: System) -> str:
        """How a report names a case: the paper's example name, ``system k (name)`` for the caller's
        k-th system (1-based, the order given; its name if it has one), ``random k`` for the k-th
        random one."""
        for name, paper_system in self.paper.items():
            if paper_system is system:
                return name
        for k, other in enumerate(self.random):
            if other is system and k < self.extra:
                return f"system {k + 1}" + (f" ({system.name})" if system.name else "")
            if other is system:
                return f"random {k + 1 - self.extra}"
        return system.name or "a system outside the audit's cases"

    def qp(self, system: System, protocol: str) -> Solution:
        """The QP twin's answer for ``system`` (solved once per audit). One
        [`ExpectedCostQP`][packetloss_cvx.qp.expected_cost.ExpectedCostQP] per system serves both protocols; the audit's
        200 random systems share 15 compiled condensed problems (one per padded shape, docs/performance.md, "Audit:
        compiled QPs shared across systems")."""
        from ..qp.expected_cost import ExpectedCostQP  # cvxpy (1.5 s to import) only where a QP is solved

        key = (id(system), protocol)
        if key not in self.cache:
            problem = self.problems.get(id(system))
            if problem is None:
                problem = self.problems[id(system)] = ExpectedCostQP(system, protocol)
            self.cache[key] = problem.solve(with_gain=False, cross_check=False, protocol=protocol)
        return self.cache[key]

    def dp(self, system: System) -> Riccati:
        """``dp_riccati(system)`` for one of the cases, solved once per audit (mpc-vs-dp and cost-split-sensor both
        need it); its NumericalError (no stabilising law) is raised again on every call. Any other system is solved
        afresh (``id`` is only unique among objects alive together: the cases are). O(1) after the first call.

        Examples
        --------
        >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
        >>> ctx = Context(paper={}, random=[s], seed=0)
        >>> ctx.dp(s) is ctx.dp(s), round(float(ctx.dp(s).cost_to_go[0, 0]), 12)     # P = 1 + sqrt 3
        (True, 2.732050807569)
        """
        if not any(system is case for case in self.cases):
            return dp_riccati(system)
        key = id(system)
        if key not in self.riccati:
            try:
                self.riccati[key] = dp_riccati(system)
            except NumericalError as err:
                self.riccati[key] = err
        found = self.riccati[key]
        if isinstance(found, Exception):
            raise found
        return found

    def evaluator(self, system: System, protocol: str) -> CostEvaluator:
        """The cached [`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator] of ``system`` (its structure built
        once per audit, shared by both protocols:
        [`CostEvaluator.with_protocol`][packetloss_cvx.lq.evaluator.CostEvaluator.with_protocol]). The evaluator holds
        the system, so its ``id`` stays unique while cached."""
        protocol = check_protocol(protocol)
        key = (id(system), protocol)
        if key not in self.evaluators:
            other = self.evaluators.get((id(system), "udp" if protocol == "tcp" else "tcp"))
            self.evaluators[key] = CostEvaluator(system, protocol) if other is None else other.with_protocol(protocol)
        return self.evaluators[key]


def paper_systems() -> dict[str, System]:
    """The paper's two systems, from the packaged examples (§V-A, §V-B).

    Examples
    --------
    >>> systems = paper_systems()
    >>> sorted(systems), systems["pendulum"].n, systems["two_actuator"].m     # §V-A: 4 states; §V-B: 2 actuators
    (['pendulum', 'two_actuator'], 4, 2)
    """
    return {"pendulum": load_example("pendulum"), "two_actuator": load_example("two_actuator")}


def loop_case(system: System) -> System:
    """The case as the loop claims price its loop: with its first stage's weights as the loop's one stage weight. A
    case's time-varying weights (the random cases draw some) speak of its plan's steps; the loop's cost needs one
    weight (model.system.loop_weights refuses the others), and the loop claims state which one they take. The case
    itself where it has one weight. O(N (n^2 + m)).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weights=[[2], [3]], input_weight=[1], mu=[0.5], x0=[1])
    >>> loop_case(s).state_weights.ravel().tolist(), loop_case(s).horizon
    ([2.0, 2.0], 2)
    """
    if np.all(system.state_weights == system.state_weights[0]) and np.all(system.input_weights ==
                                                                         system.input_weights[0]):
        return system
    data = system.to_dict()
    cost = data["cost"]
    for name in ("state", "input"):
        if f"{name}_weights" in cost:
            cost[f"{name}_weight"] = cost.pop(f"{name}_weights")[0]      # the first step's, in the file's encoding
    return system_from_dict(data)


def interior(system: System) -> bool:
    """Whether every delivery probability lies strictly between 0 and 1.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> interior(s), interior(s.with_mu([1.0])), interior(s.with_mu([0.0]))
    (True, False, False)
    """
    mu = system.mu_schedule
    return bool(np.all((mu > 0) & (mu < 1)))
