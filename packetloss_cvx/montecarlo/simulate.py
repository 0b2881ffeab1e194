"""Monte Carlo checks of the exact expectations, vectorised over runs.

Open loop: each protocol's optimal plan U* is applied whatever the losses; the sampled realised
cost is compared with the plan's exact expectation under the stated model. Closed loop: stationary
laws ``u = -K x`` (the receding-horizon laws of both protocols and the DP optimum) run for ``steps`` steps
on the same sampled losses and noise (common random numbers); each run's mean stage cost is compared
with its exact expectation from second moments (`moments`).

Runs are drawn in blocks of ``BLOCK`` (a fixed size, so the numbers depend only on the seed): block b
draws from its own stream, ``SeedSequence(seed).spawn(2)[part].spawn(blocks)[b]`` (part 0 open loop,
1 closed loop; in the closed loop the block's stream spawns one child for the losses, one for the
noise, each drawn run by run, so the first runs are the same whatever the number of samples).
Inside a block every step is one array operation over the block's runs and laws.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..budgets import check, count_text, estimated_seconds, simulate_work
from ..closedloop.moments import finite_horizon_costs, stationary_channel
from ..closedloop.riccati import dp_riccati
from ..closedloop.stability import is_mean_square_stable, mean_square_radius
from ..closedloop.tails import error_bar_reason
from ..errors import InputError, NumericalError
from ..lq.costs import closed_form, expected_cost
from ..model.system import System, loop_weights
from ..progress import progress_bar
from ..results import ClosedLoopRun, Simulation
from .channels import sample_deliveries, sample_delivery_paths, sample_noise, sample_noise_paths
from .markov import simulate_markov
from .runs import (
    BLOCK,
    check_count,
    check_loop_memory,
    loop_statistics,
    open_loop_checks,
    plan_costs,
    run_blocks,
    z_score,
)

__all__ = ["BLOCK", "LAWS", "law_gains", "simulate", "z_score"]

#: The laws a closed loop can run: the receding-horizon laws of both protocols and the DP optimum.
LAWS = ("tcp", "udp", "dp")


def open_loop_draws(system: System, samples: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
    """The deliveries (samples, N, m) and the noise (samples, N, n), or None without noise, of ``samples`` open-loop
    runs, from `.channels`. Time and memory O(samples N (m + n))."""
    N, m, n = system.horizon, system.m, system.n
    V = sample_deliveries(system, samples, rng).reshape(samples, N, m)
    W = sample_noise(system, samples, rng).reshape(samples, N, n) if system.noise_cov.any() else None
    return V, W


def open_loop_costs(system: System, inputs: np.ndarray, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Realised costs ``x'Qx + sum_t X_{t+1}'Omega_t X_{t+1} + (V_t u_t)'Psi_t (V_t u_t)`` of the plan
    ``inputs`` (N×m) on `open_loop_draws`. Time O(samples N n (n + m))."""
    return plan_costs(system, inputs, *open_loop_draws(system, samples, rng))


def law_gains(system: System, laws: Sequence[str]) -> dict[str, np.ndarray | str]:
    """Each law's stationary gain, or the reason there is none (the DP optimum without a stabilising
    solution). "tcp"/"udp": the receding-horizon gain (Theorem 1's first block); "dp": the modified Riccati law.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> g = law_gains(s, ["tcp", "dp"])   # no losses: 2-step LQR gain 2*3/4; the DARE's P = 2 + sqrt 5, K = 2P/(1+P)
    >>> float(g["tcp"][0, 0]), bool(np.isclose(g["dp"][0, 0], (1 + 5 ** 0.5) / 2))
    (1.5, True)
    >>> from packetloss_cvx.closedloop.riccati import NO_SOLUTION
    >>> law_gains(s.with_mu([0.5]), ["dp"])["dp"].startswith(NO_SOLUTION)   # below the critical 1 - 1/a^2
    True
    """
    out: dict[str, np.ndarray | str] = {}
    for law in laws:
        if law == "dp":
            try:
                out[law] = dp_riccati(system).gain
            except NumericalError as err:
                out[law] = str(err)
        else:
            out[law] = closed_form(system, law).gain
    return out


def closed_loop_block(system: System, gains: np.ndarray, steps: int, samples: int, rng: np.random.Generator,
                      keep: int = 0, noise_rng: np.random.Generator | None = None) -> tuple[np.ndarray, ...]:
    """Laws ``gains`` (L, m, n) run together for ``steps`` steps on one block of ``samples`` runs.

    Returns ``(run_cost, norms, stage, states)``: each run's mean stage cost (L, samples), ||x_t|| (L, samples,
    steps + 1), the stage costs (L, samples, steps), and the first ``keep`` runs' states (L, keep, steps + 1, n).
    Deliveries from ``rng``, noise from ``noise_rng`` (default: ``rng``, after the deliveries).
    Time O(L samples steps n (n + m)); one array operation per step, no loop over runs.

    The state is held with the runs along the last axis, ``X`` (L, n, samples): every product is a small matrix
    times a wide one and every sum over the state (the stage cost, ||x||^2) runs along contiguous rows.
    benchmarks/run.py section 14 times it against minimal vectorised loops of the same laws.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> cost, norms, stage, states = closed_loop_block(s, np.array([[[0.5]]]), 2, 3, np.random.default_rng(0), 1)
    >>> stage[0, 0].tolist(), norms[0, 0].tolist()      # x = 1, 1/2, 1/4; stage x^2 + (x/2)^2
    ([1.25, 0.3125], [1.0, 0.5, 0.25])
    >>> cost.shape, states[0, 0].ravel().tolist()
    ((1, 3), [1.0, 0.5, 0.25])
    """
    (Omega, psi), A, B = loop_weights(system), system.A, system.B
    V = sample_delivery_paths(system, steps, samples, rng)
    W = sample_noise_paths(system, steps, samples, noise_rng if noise_rng is not None else rng)
    V = np.ascontiguousarray(V.transpose(0, 2, 1))                                               # (steps, m, samples)
    W = None if W is None else np.ascontiguousarray(W.transpose(0, 2, 1))                        # (steps, n, samples)
    negative = -np.asarray(gains)
    L = negative.shape[0]
    X = np.broadcast_to(system.x0[:, None], (L, system.n, samples)).copy()
    squares = np.empty((steps + 1, L, samples))
    stage = np.empty((steps, L, samples))
    states = np.empty((L, keep, steps + 1, system.n))
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            np.einsum("lis,lis->ls", X, X, out=squares[t])
            if keep:
                states[:, :, t] = X[:, :, :keep].transpose(0, 2, 1)
            applied = V[t] * (negative @ X)
            np.add(np.einsum("lis,lis->ls", Omega @ X, X), psi @ (applied * applied), out=stage[t])
            X = A @ X
            X += B @ applied
            if W is not None:
                X += W[t]
        np.einsum("lis,lis->ls", X, X, out=squares[steps])
        states[:, :, steps] = X[:, :, :keep].transpose(0, 2, 1)
        norms = np.sqrt(squares, out=squares).transpose(1, 2, 0)
    stage = stage.transpose(1, 2, 0)
    return stage.mean(axis=2), norms, stage, states


def simulate(system: System, samples: int, steps: int = 50, seed: int = 0, closed_loop: bool = False,
             laws: Sequence[str] = LAWS, keep: int = 0, progress: bool | None = None) -> Simulation:
    """Sample the stated model and compare with the exact expectations.
    The plant is sampled as the paper states it (eq:plant).

    Parameters
    ----------
    system : System
    samples : int
        Runs (>= 2), vectorised in blocks of `BLOCK`.
    steps : int
        Closed-loop steps (>= 1).
    seed : int
        Seeds every stream (>= 0).
    closed_loop : bool
        Also run the laws in closed loop (needs a stationary Bernoulli channel, or a Gilbert–Elliott one).
    laws : sequence of {"tcp", "udp", "dp"}
        Open loop for the protocols among them; closed loop for all of them. "dp" has no open-loop plan.
    keep : int
        Keep the states of the first ``keep`` runs (``Simulation.trajectories``).
    progress : bool, optional
        A progress bar over blocks (None: when stderr is a terminal).

    Returns
    -------
    Simulation

    Raises
    ------
    InputError
        A count below its minimum, an unknown law, "dp" alone without closed loop, or a closed loop over a
        non-stationary channel.
    BudgetError
        More work than the ``simulate_work`` budget (`simulate_work`),
        refused before anything is drawn (``simulate(system, 2**63)`` at once); or, under ``steps``, a closed
        loop's block arrays (O(BLOCK steps (n + m + laws))) beyond the ``memory_bytes`` budget.
    ResourceError
        Behind a Gilbert–Elliott channel: a TCP-like law meeting more distinct beliefs than the ``belief_plans``
        budget (channels whose outcome does not reveal the state), or a dense exact cost beyond the budget.

    Notes
    -----
    Time O(samples N n (n + m)) open loop, O(laws samples steps n (n + m)) closed loop, plus the exact values
    (O(steps n^3) each); memory O(BLOCK (N + steps) (n + m) laws).

    Behind a Gilbert–Elliott channel (``system.channel``) the chain is sampled per run and every number is
    compared with the exact expectation under the chain (`.markov`): the open loop adds the
    exact minimiser's plan (``"exact_minimiser"``); in closed loop "tcp"/"udp" re-plan at the filtered /
    propagated belief and "dp" is the mode-dependent coupled-Riccati law (channel state known).

    Examples
    --------
    >>> from packetloss_cvx import load_example
    >>> sim = simulate(load_example("two_actuator"), samples=2000, seed=0, laws=["tcp"])
    >>> check = sim.open_loop["tcp"]
    >>> bool(abs(check.mean - check.exact) < 4 * check.stderr)
    True
    """
    samples, steps = check_count(samples, "samples", 2), check_count(steps, "steps", 1)
    if not isinstance(closed_loop, bool | np.bool_):       # "no" is truthy: it would have run the closed loop
        raise InputError("closed_loop", f"expected True or False, found {closed_loop!r:.40}")
    seed = check_count(seed, "seed", 0)
    keep = min(check_count(keep, "keep", 0), samples)
    laws = list(dict.fromkeys(laws))
    for law in laws:
        if law not in LAWS:
            raise InputError("law", f"expected tcp, udp or dp, found {law!r}")
    if not laws or (not closed_loop and laws == ["dp"]):
        raise InputError("law", "the DP optimum is a closed-loop law: run the closed loop (closed_loop=True, "
                                "--closed-loop) or add tcp or udp")
    plans, loops = sum(law != "dp" for law in laws), len(laws) if closed_loop else 0
    cost = simulate_work(samples, steps, system.horizon, system.n, system.m, plans, loops)
    check("simulate_work", cost, "samples",
          f"{count_text(samples)} samples{f' of {count_text(steps)} steps' if closed_loop else ''} "
          f"(n = {system.n}, m = {system.m}, "
          f"N = {system.horizon}; {plans} plans, {loops} loops)")        # before anything is drawn
    if system.channel is not None:
        return simulate_markov(system, samples, steps, seed, closed_loop, laws, keep, progress)
    if closed_loop:
        stationary_channel(system)
        check_loop_memory(system, min(BLOCK, samples), steps, len(laws), keep)
    open_part, closed_part = np.random.SeedSequence(seed).spawn(2)
    blocks = run_blocks(samples)
    plans = {p: closed_form(system, p) for p in laws if p != "dp"}
    work = len(blocks) * (len(plans) > 0) + len(blocks) * closed_loop
    with progress_bar(total=work, desc="simulate", progress=progress,
                      estimate=estimated_seconds("simulate_work", cost)) as bar:
        open_loop = open_loop_checks(plans, blocks, open_part.spawn(len(blocks)),
                                     lambda size, rng: open_loop_draws(system, size, rng),
                                     lambda inputs, draws: plan_costs(system, inputs, *draws),
                                     lambda inputs: expected_cost(system, inputs, "udp"), bar)
        runs, trajectories = {}, None
        if closed_loop:
            runs, trajectories = _closed_loop(system, law_gains(system, laws), steps, blocks,
                                              closed_part.spawn(len(blocks)), keep, bar)
    return Simulation(samples, steps, seed, open_loop, runs, trajectories)


def _closed_loop(system: System, gains: dict[str, np.ndarray | str], steps: int, blocks: list[int],
                 streams: list[np.random.SeedSequence], keep: int, bar) -> tuple[dict[str, ClosedLoopRun], np.ndarray]:
    """Every law with a gain on the same blocks; the statistics and exact values of each."""
    names = [law for law, g in gains.items() if not isinstance(g, str)]
    K = np.array([gains[law] for law in names]).reshape(len(names), system.m, system.n)

    def block(size: int, losses: np.random.Generator, noise: np.random.Generator, kept: int) -> tuple[np.ndarray, ...]:
        return closed_loop_block(system, K, steps, size, losses, keep=kept, noise_rng=noise)

    stats, trajectories = loop_statistics(len(names), block, steps, system.n, blocks, streams, keep, bar)
    out: dict[str, ClosedLoopRun] = {}
    nan = np.full(steps + 1, np.nan)
    for law, gain in gains.items():
        if isinstance(gain, str):
            out[law] = ClosedLoopRun(law, np.nan, np.nan, np.nan, np.nan, False, nan, nan, nan[:-1], reason=gain)
            continue
        st = stats[names.index(law)]
        radius = mean_square_radius(system.A, system.B, gain, system.mu_schedule[0])
        exact = float(finite_horizon_costs(system, gain, steps)[0].mean())
        no_bar = error_bar_reason(system.A, system.B, gain, system.mu_schedule[0])
        out[law] = ClosedLoopRun(law, st.mean, np.nan if no_bar else st.stderr, exact, radius,
                                 is_mean_square_stable(radius), st.norm_mean, st.norm_std, st.stage_mean,
                                 stderr_reason=no_bar)
    return out, trajectories
