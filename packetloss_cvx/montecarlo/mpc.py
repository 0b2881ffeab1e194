"""The constrained receding-horizon loop over lossy links, sampled: model predictive control re-solved from each
realised state, the plan sent through the link (a lost packet applies zero, or, with ``actuator=``, the actuator
holds its last input or plays the next entry of the last plan it received), under Bernoulli or chain losses and
process noise.

Three controllers run on the same sample paths (deliveries, chain states, noise):

* ``"clipped"``: the protocol's unconstrained receding-horizon law ``u = -K x`` (Theorem 1's first block; behind a
  chain, the plug-in law at the controller's belief, as `markov_loop`'s) clipped to the input bounds and to
  ``u_prev +- du_max`` (the usual saturation and rate-limiter heuristic);
* ``"certainty-equivalent"``: the constrained program of `ConstrainedQP` planned as if every packet arrived
  (mu = 1 in the model: the TCP-like and UDP-like programs coincide, so one run serves both protocols);
* ``"expected-cost"``: the constrained expected-cost program of the protocol with the controller's delivery
  probabilities.

Information: TCP-like controllers filter their belief about a chain by every acknowledged outcome (the HMM
filter), UDP-like ones propagate the prior; under Bernoulli losses both plan with the channel's mu. Behind a
chain the expected-cost program is the plug-in one (the Bernoulli model of the predicted mu_t) but for its chance
rows, posed with the deliveries' covariance under the chain from the controller's belief (`ConstrainedQP`'s
``belief``). Both know the inputs they commanded:
the rate bound links the first input of a plan to the previous command (the actuator at rest, zero, before the
first): the program's own ``u_prev`` Parameter (``ConstrainedQP(..., u_prev=True)``), covered by its KKT check and
polish like every other row.

The actuator on a loss (``actuator``, `packetloss_cvx.closedloop.actuator.parse_actuator`): "zero" is the paper's
model (the input and rate rows bound the commands, the rate links to the last command). Under
"hold", "buffer:L" and "buffer:L:hold" each actuator keeps the last packet it received, the plan's first L inputs
(the clipped law's rolled out on the nominal prediction, every input delivered: the programs' own plans are the
packet), plays its next entry on a loss and, once exhausted, zero or its last applied input ("hold" is
"buffer:1:hold"); the rows then bound the inputs applied. A TCP-like controller knows from the acknowledgements which
entry each actuator played, hence the input applied last, and links its plan's rate bound to it, so a plan played
in order and held once exhausted keeps both bounds on every path; a UDP-like one knows neither and links it to its
last command, as if delivered (certainty-equivalent MPC, which plans alike for both protocols under zero, then runs
once per protocol). The programs keep the paper's expected cost, a loss modelled as zero.

Infeasible programs: the expected-state limits and chance rows of the hard program can have no plan from a
realised state (a loss leaves the state where no plan brings its expectation back inside). The controller then
does what a predictive-control engineer expects of a deployed controller: it solves the soft program (the same
rows as exact penalties of weight ``soft_weight``, input and rate bounds hard, always feasible) and applies its
first input; the step counts as infeasible and as a fallback. Where no program gives a trusted answer (a
`SolverError` or `NumericalError`: never read as a verdict) it plays the rest of its last plan (zero past its end)
and counts the step as failed.

Draws: ``SeedSequence(seed).spawn(2)[1]``, one child per block of `BLOCK` runs, each spawning the losses' and the
noise's streams (`simulate`'s closed loop: on the same seed the unconstrained loop sees the same paths). The paths
are drawn first; the runs then go in chunks of `CHUNK` (serially, on threads or as Dask tasks), each run's numbers
depending on its own paths only, so every way of spreading them gives the same floats.

The terminal set constrains the prediction only: the loop counts no realised violation of it.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from typing import Any

import numpy as np
from scipy import stats

from ..budgets import (
    chain_states,
    check,
    check_constrained,
    count_text,
    gib_text,
    mpc_bytes,
    mpc_loop_solves,
)
from ..closedloop.actuator import Actuator, parse_actuator
from ..closedloop.moments import stationary_channel
from ..errors import InfeasibleError, InputError, NumericalError, SolverError
from ..lq.costs import closed_form
from ..model.chain import attach_channel, filter_belief
from ..model.constraints import Constraints, check_constraints
from ..model.files import system_from_dict
from ..model.system import System, check_system, loop_weights
from ..progress import progress_bar
from ..qp.constrained import ConstrainedQP
from ..qp.convex import PROVEN_INFEASIBLE
from ..results.mpc import ControllerRun, Frequency, MPCSimulation
from ..tolerances import CONSTRAINED_ACTIVE_RTOL
from .channels import sample_delivery_paths, sample_noise_paths
from .markov_channels import sample_markov_paths
from .markov_loop import BeliefGains
from .runs import check_count, run_blocks, sample_stats

__all__ = ["CHUNK", "CONFIDENCE", "CONTROLLERS", "INFEASIBLE_ACTION", "TASK_CHUNKS", "check_loop_budgets",
           "loop_jobs", "loop_paths", "loop_task", "simulate_mpc", "wilson_interval"]

#: The controllers compared, in the order they are reported.
CONTROLLERS = ("clipped", "certainty-equivalent", "expected-cost")
#: Runs per chunk: the unit a thread or a Dask task runs, cut by the run count alone, so that every way of spreading
#: the runs computes the same floats (a chunk's arrays are the same whoever runs it).
CHUNK = 8
#: Chunks per Dask task (one compilation of the controller's programs per task: about 0.2 s at n = 2, N = 8).
TASK_CHUNKS = 8
#: The level of every confidence interval.
CONFIDENCE = 0.95
#: What a controller does when its hard program is infeasible (ControllerRun.action).
INFEASIBLE_ACTION = ("solve the soft program (state limits and chance rows as exact penalties, input and rate bounds "
                     "hard) and apply its first input; where no program gives a trusted answer, play the rest of the "
                     "last plan")


def wilson_interval(count: int, trials: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (scipy.stats.binomtest). O(1).

    Examples
    --------
    >>> lo, hi = wilson_interval(0, 20)                     # no event in 20 trials: [0, z^2 / (20 + z^2)]
    >>> lo, round(hi, 4)
    (0.0, 0.1611)
    """
    ci = stats.binomtest(int(count), int(trials)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def frequency(name: str, flags: np.ndarray, allowed: float = 0.0) -> Frequency:
    """The `Frequency` of an event flagged (runs, steps). O(runs steps).

    Examples
    --------
    >>> f = frequency("x", np.array([[True, False], [True, True], [False, False]]))
    >>> f.count, f.worst_step, f.worst_frequency, f.runs_with, f.step_counts.tolist()
    (3, 0, 0.6666666666666666, 2, [2, 1])
    """
    runs, steps = flags.shape
    per_step = flags.sum(axis=0)
    worst = int(np.argmax(per_step))
    hit = int(flags.any(axis=1).sum())
    return Frequency(name=name, allowed=float(allowed), step_counts=per_step, runs=runs, count=int(flags.sum()),
                     frequency=float(flags.mean()), worst_step=worst, worst_frequency=float(per_step[worst] / runs),
                     worst_ci=wilson_interval(per_step[worst], runs), runs_with=hit,
                     runs_ci=wilson_interval(hit, runs), confidence=CONFIDENCE)


def loop_paths(system: System, samples: int, steps: int, seed: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Deliveries (steps, samples, m) and noise (steps, samples, n) or None of the loop's runs: `simulate`'s
    closed-loop streams (`BLOCK` runs per child of ``SeedSequence(seed).spawn(2)[1]``, each spawning losses then
    noise), the chain sampled per run behind a Markov channel (`sample_markov_paths`). O(samples steps (n + m))."""
    blocks = run_blocks(samples)
    streams = np.random.SeedSequence(seed).spawn(2)[1].spawn(len(blocks))
    V, W = [], []
    for size, stream in zip(blocks, streams, strict=True):
        losses, noise = (np.random.default_rng(child) for child in stream.spawn(2))
        if system.channel is None:
            V.append(sample_delivery_paths(system, steps, size, losses))
        else:
            V.append(sample_markov_paths(system.channel, steps, size, losses)[1].swapaxes(0, 1))
        W.append(sample_noise_paths(system, steps, size, noise))
    return np.concatenate(V, axis=1), None if W[0] is None else np.concatenate(W, axis=1)


class _Program:
    """One compiled constrained program (and, on the first infeasibility, its soft twin), with the rate bound
    linked to the previous command."""

    def __init__(self, twin: System, protocol: str, constraints: Constraints) -> None:
        self.twin, self.protocol, self.constraints = twin, protocol, constraints
        self.hard = self._compile(constraints)
        self.soft = self.hard if constraints.soft else None

    def _compile(self, constraints: Constraints) -> ConstrainedQP:
        return ConstrainedQP(self.twin, self.protocol, constraints, u_prev=True)

    def _solve(self, program: ConstrainedQP, mu: np.ndarray | None, x: np.ndarray, previous: np.ndarray,
               belief: np.ndarray | None = None) -> Any:
        if program.chain is not None:              # behind a chain: the belief sets mu_t and the rows' covariance
            return program.solve(x0=x, belief=belief, u_prev=previous)
        return program.solve(mu=mu, x0=x, u_prev=previous)

    def plan(self, mu: np.ndarray | None, x: np.ndarray, previous: np.ndarray, belief: np.ndarray | None = None
             ) -> tuple[np.ndarray | None, str, bool]:
        """``(plan or None, outcome, slack used)``; outcome "ok", "fallback" (hard infeasible, soft solved),
        "failed". Behind a chain the program plans from ``belief`` (``mu`` is its prediction)."""
        try:
            sol = self._solve(self.hard, mu, x, previous, belief)
            return sol.inputs, "ok", bool(sol.violations)
        except (InfeasibleError, SolverError) as err:
            # the soft twin also where the solver says infeasible without a verified certificate (chance rows)
            if not isinstance(err, InfeasibleError) and err.status != PROVEN_INFEASIBLE:
                return None, "failed", False
            if self.soft is None:
                soft = Constraints(**{**self.constraints.to_dict(), "soft": True})
                self.soft = self._compile(soft)
            try:
                sol = self._solve(self.soft, mu, x, previous, belief)
            except (SolverError, NumericalError, InfeasibleError):
                return None, "infeasible-failed", False
            return sol.inputs, "fallback", bool(sol.violations)
        except NumericalError:
            return None, "failed", False


def _rows(c: Constraints, n: int, m: int) -> list[tuple[str, str, Any, float]]:
    """The rows checked in the loop: (name, kind, data, allowed frequency)."""
    rows = []
    for name in ("u_max", "u_min", "du_max"):
        values = getattr(c, name)
        if values is not None:
            rows += [(f"{name}[{i}]", name, (i, float(values[i])), 0.0) for i in np.flatnonzero(np.isfinite(values))]
    for name in ("x_max", "x_min"):
        values = getattr(c, name)
        if values is not None:
            rows += [(f"{name}[{j}]", name, (j, float(values[j])), 0.0) for j in np.flatnonzero(np.isfinite(values))]
    if c.F is not None:
        rows += [(f"F[{r}]", "F", (c.F[r], float(c.g[r])), 0.0) for r in np.flatnonzero(np.isfinite(c.g))]
    rows += [(f"chance[{i}]", "chance", (a, b), eps) for i, (a, b, eps) in enumerate(c.chance)]
    return rows


def _violated(kind: str, data: Any, u: np.ndarray, du: np.ndarray, x_next: np.ndarray) -> np.ndarray:
    """Each run's violation of one row at one step (beyond CONSTRAINED_ACTIVE_RTOL max(1, |bound|), the solver's
    feasibility with a margin)."""
    if kind in ("F", "chance"):
        a, b = data
        value, bound = x_next @ a, b
    else:
        i, bound = data
        value = {"u_max": u, "u_min": -u, "du_max": np.abs(du), "x_max": x_next, "x_min": -x_next}[kind][:, i]
        bound = -bound if kind in ("u_min", "x_min") else bound
    return value - bound > CONSTRAINED_ACTIVE_RTOL * max(1.0, abs(bound))


class _Beliefs:
    """Each run's delivery schedule: the channel's mu (Bernoulli), or the predicted mu_t at the belief (a chain:
    TCP-like filtered by every outcome, UDP-like the prior propagated), cached per distinct belief."""

    def __init__(self, system: System, protocol: str, samples: int) -> None:
        self.system, self.protocol, self.channel = system, protocol, system.channel
        self.cache: dict[bytes, np.ndarray] = {}
        if self.channel is not None:
            self.belief = np.repeat(self.channel.initial_belief[None], samples, axis=0)

    def row(self, run: int) -> np.ndarray | None:
        """The run's belief as the schedules are cached by (rounded to 12 decimals), None under Bernoulli losses."""
        return None if self.channel is None else np.round(self.belief[run], 12)

    def schedule(self, run: int) -> np.ndarray | None:
        if self.channel is None:
            return None
        row = self.row(run)
        key = row.tobytes()
        if key not in self.cache:
            self.cache[key] = attach_channel(self.system, self.channel.with_belief(row)).mu_schedule
        return self.cache[key]

    def update(self, delivered: np.ndarray) -> None:
        if self.channel is None:
            return
        self.belief = (filter_belief(self.channel, self.belief, delivered) if self.protocol == "tcp"
                       else np.repeat(self.channel.propagate(self.belief[0])[None], len(self.belief), axis=0))


class _Controller:
    """One controller's compiled state, owned by one thread (a `ConstrainedQP` is not thread-safe): its program
    (`_Program`), or the clipped law's gains, and the actuator's strategy on a loss."""

    def __init__(self, system: System, twin: System, constraints: Constraints, controller: str,
                 protocol: str, actuator: str = "zero") -> None:
        self.name, self.protocol = controller, protocol
        self.strategy = parse_actuator(actuator, system.horizon)
        self.program: _Program | None = None
        self.gains: Any = None
        if controller == "clipped":
            self.gains = BeliefGains(system, protocol) if system.channel is not None else closed_form(twin,
                                                                                                      protocol).gain
        elif controller == "certainty-equivalent":
            self.program = _Program(twin.with_mu(np.ones(system.m)), "tcp", constraints)
        else:                 # behind a chain: the chain itself (the plug-in cost, the chance rows exact under it)
            self.program = _Program(twin if system.channel is None else system, protocol, constraints)


def _rolled(K: np.ndarray, X: np.ndarray, base: np.ndarray, lo: np.ndarray, hi: np.ndarray, rate: np.ndarray,
            A: np.ndarray, B: np.ndarray, length: int) -> np.ndarray:
    """The clipped law's plan (runs, length, m), rolled out on the nominal prediction (every input delivered, no
    noise): entry j is ``-K x_j`` clipped to the input bounds and within the rate bound of entry j - 1 (of ``base``
    for the first), ``x_{j+1} = A x_j + B u_j``. Entry 0 is the clipped law's command. O(runs length n (n + m))."""
    plan = np.empty((len(X), length, B.shape[1]))
    x, last = X, base
    for j in range(length):
        last = np.clip(-np.einsum("smn,sn->sm", K, x), np.maximum(lo, last - rate), np.minimum(hi, last + rate))
        plan[:, j] = last
        if j + 1 < length:
            x = x @ A.T + last @ B.T
    return plan


def _chunk(system: System, twin: System, constraints: Constraints, made: _Controller, V: np.ndarray,
           W: np.ndarray | None, keep: int = 0) -> dict[str, Any]:
    """One controller over the sampled paths of a chunk of runs (V: steps x runs x m): each run's stage costs,
    violation and infeasibility flags (runs x steps), the counts of fallbacks, failures and slack used, and the
    first ``keep`` runs' states, commands and (under hold or buffer) applied inputs. A run's numbers depend on its
    own paths only. Time O(runs steps) solves (none for "clipped")."""
    steps, samples, m = V.shape
    n = system.n
    (Omega, psi), A, B = loop_weights(system), system.A, system.B
    c, controller, program, gains = constraints, made.name, made.program, made.gains
    strategy = made.strategy
    zero, L = strategy.kind == "zero", strategy.length
    # what the rate bound links the next plan to: under zero, and for a UDP-like controller (no acknowledgement: it
    # assumes its last command arrived), the previous command; for a TCP-like one under hold or buffer, the input the
    # actuator applied (the acknowledgements tell it which entry the actuator played)
    from_applied = not zero and made.protocol == "tcp"
    keeps_last = strategy.kind == "hold" or strategy.exhausted == "hold"
    lo = np.full(m, -np.inf) if c.u_min is None else c.u_min
    hi = np.full(m, np.inf) if c.u_max is None else c.u_max
    rate = np.full(m, np.inf) if c.du_max is None else c.du_max
    rows = _rows(c, n, m)
    flags = {name: np.zeros((samples, steps), dtype=bool) for name, *_ in rows}
    infeasible = np.zeros((samples, steps), dtype=bool)
    fallback = failed = slack = 0
    beliefs = _Beliefs(system, "tcp" if controller == "certainty-equivalent" else made.protocol, samples)
    N = twin.horizon
    X = np.repeat(system.x0[None], samples, axis=0)
    previous = np.zeros((samples, m))
    plans, age = np.zeros((samples, N, m)), np.zeros(samples, dtype=int)
    # the actuator's memory: the last plan received (L entries per actuator), the entry it plays (L: exhausted, or
    # nothing received yet) and the input it applied last (zero before the first step)
    buffer, played, last = np.zeros((samples, L, m)), np.full((samples, m), L), np.zeros((samples, m))
    stage = np.empty((samples, steps))
    states, commands = np.empty((keep, steps + 1, n)), np.empty((keep, steps, m))
    applied_kept = None if zero else np.empty((keep, steps, m))
    states[:, 0] = X[:keep]
    # a run whose stage cost or state leaves the double range has diverged: a result, as simulate's loops report it
    # (inf cost, no warning), for every controller alike; its programs are not solved again
    diverged = np.zeros(samples, dtype=bool)
    state_rows = [name for name, kind, _, _ in rows if kind in ("x_max", "x_min", "F", "chance")]
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            base = last if from_applied else previous
            if controller == "clipped":
                K = gains.many(beliefs.belief) if system.channel is not None else np.broadcast_to(gains,
                                                                                                  (samples, m, n))
                packet = _rolled(K, X, base, lo, hi, rate, A, B, L)
                u = packet[:, 0]
            else:
                u, packet = np.zeros((samples, m)), np.zeros((samples, L, m))
                for s in np.flatnonzero(~diverged):
                    mu = None if controller == "certainty-equivalent" else beliefs.schedule(s)
                    plan, outcome, used = program.plan(mu, X[s], base[s], beliefs.row(s))
                    infeasible[s, t] = outcome in ("fallback", "infeasible-failed")
                    slack += used
                    if plan is None:
                        failed += 1
                        age[s] += 1
                        u[s] = plans[s, age[s]] if age[s] < N else 0.0
                        rest = plans[s, age[s]:age[s] + L]               # the rest of the last plan, zero past it
                        packet[s, :len(rest)] = rest
                    else:
                        fallback += outcome == "fallback"
                        plans[s], age[s] = plan, 0
                        u[s] = plan[0]
                        packet[s] = plan[:L]
            if zero:
                applied = V[t] * u
            else:                # hold is buffer:1:hold: the delivered packet's first entry, else the last input
                buffer = np.where(V[t][:, None, :], packet, buffer)
                played = np.where(V[t], 0, np.minimum(played + 1, L))
                entry = np.take_along_axis(buffer, np.minimum(played, L - 1)[:, None, :], axis=1)[:, 0]
                applied = np.where(played < L, entry, last if keeps_last else 0.0)
            stage[:, t] = np.einsum("si,ij,sj->s", X, Omega, X) + applied ** 2 @ psi
            X_next = X @ A.T + applied @ B.T
            if W is not None:
                X_next += W[t]
            diverged |= ~np.isfinite(stage[:, t]) | ~np.all(np.isfinite(X_next), axis=1)
            stage[diverged, t] = np.inf
            # the input and rate rows: zero's on the commands (a loss's zero is the channel's, v u), hold's and the
            # buffer's on the inputs the actuator applies
            shown, step = (u, u - previous) if zero else (applied, applied - last)
            for name, kind, data, _ in rows:
                flags[name][:, t] = _violated(kind, data, shown, step, X_next)
            for name in state_rows:                      # a diverged state has left every limit
                flags[name][diverged, t] = True
            states[:, t + 1], commands[:, t] = X_next[:keep], u[:keep]
            if applied_kept is not None:
                applied_kept[:, t] = applied[:keep]
            X, previous, last = X_next, u, applied
            beliefs.update(V[t])
    return {"stage": stage, "flags": flags, "infeasible": infeasible, "fallback": fallback, "failed": failed,
            "slack": slack, "diverged": diverged, "states": states, "inputs": commands, "applied": applied_kept}


def _assemble(constraints: Constraints, n: int, m: int, controller: str, protocol: str,
              parts: list[dict[str, Any]], keep: int = 0) -> ControllerRun:
    """The `ControllerRun` of a controller from its chunks' parts, in run order (the first ``keep`` runs'
    trajectories kept). O(samples steps)."""
    rows = _rows(constraints, n, m)
    stage = np.concatenate([part["stage"] for part in parts])
    with np.errstate(over="ignore", invalid="ignore"):       # a diverged run's cost is inf, as simulate's
        mean, stderr = sample_stats(stage.mean(axis=1))
        profile = stage.mean(axis=0)
    flags = {name: np.concatenate([part["flags"][name] for part in parts]) for name, *_ in rows}
    infeasible = np.concatenate([part["infeasible"] for part in parts])
    return ControllerRun(
        controller=controller, protocol=protocol, mean_stage_cost=mean, stderr=stderr,
        stage_cost_mean=profile,
        violations=tuple(frequency(name, flags[name], allowed) for name, _, _, allowed in rows),
        infeasible=None if controller == "clipped" else frequency("infeasible", infeasible),
        fallback_steps=sum(part["fallback"] for part in parts), failed_steps=sum(part["failed"] for part in parts),
        slack_steps=sum(part["slack"] for part in parts), action=INFEASIBLE_ACTION,
        diverged_runs=int(sum(part["diverged"].sum() for part in parts)),
        states=np.concatenate([part["states"] for part in parts]) if keep else None,
        inputs=np.concatenate([part["inputs"] for part in parts]) if keep else None,
        applied=np.concatenate([part["applied"] for part in parts]) if keep and parts[0]["applied"] is not None
        else None)


def _twin(system: System) -> System:
    """The system the programs plan with: the channel's stationary mu (Bernoulli), the chain's predicted mu_t."""
    return system.with_mu(stationary_channel(system) if system.channel is None else system.mu_schedule)


def loop_task(system_data: dict[str, Any], constraints_data: dict[str, Any], controller: str, protocol: str,
              V: np.ndarray, W: np.ndarray | None, chunks: list[tuple[int, int]], keep: int = 0,
              actuator: str = "zero") -> list[dict[str, Any]]:
    """Chunks of runs of one controller as one task (in this process or on a Dask worker: the system and
    constraints rebuilt from their dicts, exact), its program compiled once for them; ``V``, ``W`` hold the
    task's runs, ``chunks`` their (start, stop) within them, the first ``keep`` of them kept; ``actuator`` the
    strategy on a loss. O(runs steps) solves."""
    system = system_from_dict(system_data)
    constraints = check_constraints(constraints_data, system.n, system.m)
    twin = _twin(system)
    made = _Controller(system, twin, constraints, controller, protocol, actuator)
    return [_chunk(system, twin, constraints, made, V[:, a:b], None if W is None else W[:, a:b],
                   _kept(keep, a, b)) for a, b in chunks]


def _kept(keep: int, a: int, b: int) -> int:
    """How many of the runs a..b-1 are among the first ``keep``."""
    return max(0, min(b, keep) - a)


def simulate_mpc(system: System, constraints: Constraints | Any, samples: int, steps: int = 30, seed: int = 0,
                 protocols: Sequence[str] = ("tcp", "udp"), controllers: Sequence[str] = CONTROLLERS,
                 progress: bool | None = None, keep: int = 0, threads: int = 1, dask: Any = None,
                 actuator: str | Actuator = "zero") -> MPCSimulation:
    """The constrained receding-horizon loop sampled, each controller on the same paths (module docstring).

    Parameters
    ----------
    system : System
        A stationary Bernoulli channel, or a Markov (Gilbert–Elliott) one sampled per run.
    constraints : Constraints or mapping (the ``[constraints]`` table)
    samples : int
        Runs (>= 2). Each controller with a program solves it samples × steps times (the ``mpc_solves`` budget,
        each solve weighed by its program's size: `mpc_solve_size`).
    steps : int
        Loop steps (>= 1).
    seed : int
    protocols : sequence of {"tcp", "udp"}
    controllers : sequence of `CONTROLLERS`
    progress : bool, optional
        A progress bar over the chunks of runs (None: when stderr is a terminal).
    keep : int
        Runs whose trajectories are kept (the first ``keep``, at most ``samples``): each `ControllerRun`'s
        ``states`` and ``inputs``, and the simulation's ``delivered``, the same paths for every controller. 0 keeps
        none (the default: the summaries alone).
    threads : int
        Threads running chunks of `CHUNK` runs at once, each with its own compiled programs (a `ConstrainedQP`
        is not thread-safe). The answer is the serial run's, float for float: a run's numbers depend on its own
        paths only, and the chunks are cut by the run count alone.
    dask : distributed.Client, optional
        Run the chunks as Dask tasks of `TASK_CHUNKS` chunks each (one compilation per task; e.g. a client of
        `packetloss_cvx.studies.engine.dask_client`); the same floats again. Any object with ``submit`` whose
        futures have ``result()`` serves (a ``concurrent.futures`` process pool too).
    actuator : str or Actuator
        What the actuator does on a loss (`packetloss_cvx.closedloop.actuator.parse_actuator`): "zero" (the paper's
        model, the default), "hold" (its last applied input), "buffer:L" (the packet is the plan's first L inputs,
        the clipped law's rolled out; on a loss the actuator plays the next entry of the last plan it received, zero
        once it is exhausted) or "buffer:L:hold" (its last applied input once exhausted). Under hold and buffer the
        input and rate rows are checked on the inputs the actuator applies, and a TCP-like controller plans from
        the input applied last (the acknowledgements tell it), a UDP-like one from its last command (it assumes
        the packet arrived); certainty-equivalent MPC then runs once per protocol. Every strategy sees the same
        paths on the same seed.

    Returns
    -------
    MPCSimulation
        ``runs[protocol][controller]``; under zero "certainty-equivalent" is one run shared by both protocols.
        ``.plot()`` draws the kept trajectories and the violation frequencies.

    Raises
    ------
    InputError
        A count below its minimum, an unknown protocol, controller or ``actuator`` strategy (L outside 1..N),
        a non-stationary Bernoulli schedule,
        time-varying weights (``state_weights``, ``input_weights``: the loop's stage cost needs one weight a step),
        constraints that do not fit the system, ``threads`` below 1 or ``dask`` without ``submit``.
    BudgetError
        More program solves than the ``mpc_solves`` budget (`mpc_solves`: each weighed by its program's size; the
        clipped laws' run-steps at their measured share of a solve), or arrays beyond the ``memory_bytes`` budget
        (`mpc_bytes`), before any path is drawn.

    Notes
    -----
    A loop that diverges (a run's stage cost or state beyond the double range) is a result, as `simulate`'s loops
    report one: that controller's ``mean_stage_cost`` is inf (null in JSON), ``diverged_runs`` counts the runs, no
    warning is printed and its programs are not solved again in those runs.

    Time O(controllers samples steps) solves of the program (about 5 ms each at n = 2, N = 8), plus
    O(samples steps n (n + m)) for the clipped law. Threads share one interpreter: the solves' Python side (the
    KKT check, the polish, cvxpy's unpacking) holds the GIL, so threads gain little; Dask's worker processes do.

    Examples
    --------
    x' = x + v u from x0 = 1, mu = 1/2, |u| <= 0.3: the clipped law and the programs saturate alike at the first step
    (nothing else binds: the expected state has no limit)

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> sim = simulate_mpc(s, Constraints(u_min=[-0.3], u_max=[0.3]), samples=4, steps=2, protocols=["tcp"])
    >>> [sim.runs["tcp"][c].violation("u_min[0]").count for c in CONTROLLERS]
    [0, 0, 0]
    """
    system = check_system(system)
    loop_weights(system)
    constraints = check_constraints(constraints, system.n, system.m)
    samples, steps = check_count(samples, "samples", 2), check_count(steps, "steps", 1)
    seed = check_count(seed, "seed", 0)
    keep = check_count(keep, "keep", 0)
    if keep > samples:
        raise InputError("keep", f"expected at most samples = {samples} runs to keep, found {keep}")
    threads = check_count(threads, "threads", 1)
    if dask is not None and not callable(getattr(dask, "submit", None)):
        raise InputError("dask", f"expected a distributed.Client (or an executor with submit), found {dask!r}; "
                                 "studies.engine.dask_client('local') makes one")
    protocols = list(dict.fromkeys(protocols))
    for p in protocols:
        if p not in ("tcp", "udp"):
            raise InputError("protocol", f"expected tcp or udp, found {p!r}")
    for name in controllers:
        if name not in CONTROLLERS:
            raise InputError("controller", f"expected some of {', '.join(CONTROLLERS)}, found {name!r}")
    if not protocols or not controllers:
        raise InputError("protocol" if not protocols else "controller", "expected at least one")
    strategy = parse_actuator(actuator, system.horizon)
    jobs = loop_jobs(protocols, controllers, strategy)
    check_loop_budgets(system, constraints, samples, steps, [jobs], keep)
    twin = _twin(system)
    channel = "bernoulli" if system.channel is None else system.channel.form
    V, W = loop_paths(system, samples, steps, seed)
    chunks = [(a, min(a + CHUNK, samples)) for a in range(0, samples, CHUNK)]
    parts: dict[tuple[str, str], list[Any]] = {job: [None] * len(chunks) for job in jobs}
    with progress_bar(total=len(jobs) * samples, desc="simulate (constrained loop)", progress=progress) as bar:
        if dask is not None:
            _on_dask(dask, system, constraints, jobs, chunks, V, W, parts, bar, keep, str(strategy))
        elif threads > 1:
            _on_threads(threads, system, twin, constraints, jobs, chunks, V, W, parts, bar, keep, str(strategy))
        else:
            for job in jobs:
                made = _Controller(system, twin, constraints, *job, str(strategy))
                for k, (a, b) in enumerate(chunks):
                    parts[job][k] = _chunk(system, twin, constraints, made, V[:, a:b], None if W is None else
                                           W[:, a:b], _kept(keep, a, b))
                    bar.update(b - a)
    runs: dict[str, dict[str, ControllerRun]] = {p: {} for p in protocols}
    for name, p in jobs:
        run = _assemble(constraints, system.n, system.m, name, p, parts[name, p], keep)
        shared = name == "certainty-equivalent" and strategy.kind == "zero"      # one run for both protocols
        for q in protocols if shared else (p,):
            runs[q][name] = run
    return MPCSimulation(samples=samples, steps=steps, seed=seed, channel=channel,
                         constraints=constraints.to_dict(), runs=runs,
                         delivered=V[:, :keep].swapaxes(0, 1).astype(bool) if keep else None,
                         actuator=str(strategy))


def loop_jobs(protocols: Sequence[str], controllers: Sequence[str], strategy: Actuator) -> list[tuple[str, str]]:
    """The (controller, protocol) runs of the loop, in `CONTROLLERS` order: one per controller and protocol, but
    under zero certainty-equivalent plans alike for both (mu = 1, from the last command): one run, shared.

    >>> loop_jobs(["tcp", "udp"], ["certainty-equivalent"], parse_actuator("hold"))
    [('certainty-equivalent', 'tcp'), ('certainty-equivalent', 'udp')]
    """
    names = [name for name in CONTROLLERS if name in controllers]
    shared = strategy.kind == "zero"
    return [(name, p) for name in names for p in protocols
            if name != "certainty-equivalent" or p == protocols[0] or not shared]


def check_loop_budgets(system: System, constraints: Constraints, samples: int, steps: int,
                       runs: Sequence[Sequence[tuple[str, str]]], keep: int = 0) -> None:
    """Refuse, before any path is drawn, loops beyond the ``mpc_solves`` or ``memory_bytes`` budget, or programs
    beyond their size: ``runs`` the jobs (`loop_jobs`) of each loop to be run (several: one per actuator strategy,
    each on the same paths), summed. O(1).

    Raises
    ------
    BudgetError
        Field ``samples`` (the solves, the memory) or ``horizon`` (a program's size).
    """
    jobs = [job for loop in runs for job in loop]
    programs = sum(name != "clipped" for name, _ in jobs)
    clipped = len(jobs) - programs
    N, rows, chance = system.horizon, constraints.program_rows(system.horizon), len(constraints.chance)
    # behind a chain the expected-cost programs' chance rows are exact under it (denser cones, priced so); the
    # certainty-equivalent one plans on delivered inputs, its rows the plug-in ones
    states = chain_states(system.channel) if chance else 0
    exact = sum(name == "expected-cost" for name, _ in jobs) if states else 0
    units, priced = mpc_loop_solves(samples, steps, programs, clipped, exact, N, system.n, system.m, rows, chance,
                                    states)
    check("mpc_solves", units, "samples", f"{count_text(samples)} runs of {count_text(steps)} steps x {programs} "
          "programs" + (f" and {clipped} clipped laws" if clipped else "") + f" ({priced})")
    needed = max(mpc_bytes(samples, steps, system.n, system.m, len(loop), constraints.loop_rows(), keep)
                 for loop in runs)
    check("memory_bytes", needed, "samples", f"{count_text(samples)} runs of {count_text(steps)} steps (about "
                                             f"{gib_text(needed)} of paths and per-run records)",
          instead="use fewer runs or steps")
    if programs:        # the programs' size, before any path is drawn (ConstrainedQP checks it again)
        check_constrained(N, system.n, system.m, rows, chance, "horizon", states=states if exact else 0)


def _on_threads(threads: int, system: System, twin: System, constraints: Constraints, jobs: list[tuple[str, str]],
                chunks: list[tuple[int, int]], V: np.ndarray, W: np.ndarray | None,
                parts: dict[tuple[str, str], list[Any]], bar: Any, keep: int, actuator: str) -> None:
    """Every (job, chunk) on a pool of ``threads`` threads, each thread compiling its own controllers once."""
    local = threading.local()

    def task(job: tuple[str, str], a: int, b: int) -> dict[str, Any]:
        made = getattr(local, "made", None)
        if made is None:
            made = local.made = {}
        if job not in made:
            made[job] = _Controller(system, twin, constraints, *job, actuator)
        return _chunk(system, twin, constraints, made[job], V[:, a:b], None if W is None else W[:, a:b],
                      _kept(keep, a, b))

    pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="mpc")
    try:
        futures = {pool.submit(task, job, a, b): (job, k, b - a) for job in jobs for k, (a, b) in enumerate(chunks)}
        for future in as_completed(futures):
            job, k, size = futures[future]
            parts[job][k] = future.result()        # a chunk's error is raised here with its own type
            bar.update(size)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _on_dask(client: Any, system: System, constraints: Constraints, jobs: list[tuple[str, str]],
             chunks: list[tuple[int, int]], V: np.ndarray, W: np.ndarray | None,
             parts: dict[tuple[str, str], list[Any]], bar: Any, keep: int, actuator: str) -> None:
    """Every job's chunks as tasks of `TASK_CHUNKS` chunks (`loop_task`), results put back in run order."""
    system_data, constraints_data = system.to_dict(), constraints.to_dict()
    futures = []
    for job in jobs:
        for first in range(0, len(chunks), TASK_CHUNKS):
            group = chunks[first:first + TASK_CHUNKS]
            a, b = group[0][0], group[-1][1]
            local = [(x - a, y - a) for x, y in group]
            task = (loop_task, system_data, constraints_data, *job, V[:, a:b], None if W is None else W[:, a:b],
                    local, _kept(keep, a, b), actuator)
            future = client.submit(*task, pure=False) if _is_dask(client) else client.submit(*task)
            futures.append((future, job, first, b - a))
    for future, job, first, size in futures:
        for k, part in enumerate(future.result()):      # a worker's error is raised here with its own type
            parts[job][first + k] = part
        bar.update(size)


def _is_dask(client: Any) -> bool:
    """A distributed.Client (its submit takes ``pure=``), not a concurrent.futures executor."""
    return type(client).__module__.startswith("distributed")
