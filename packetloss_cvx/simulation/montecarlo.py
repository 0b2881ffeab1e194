"""Monte Carlo checks of the exact expectations, vectorised over runs.

Open loop: each protocol's optimal plan U* is applied whatever the losses; the sampled realised
cost is compared with the plan's exact expectation under the stated model. Closed loop: stationary
laws ``u = -K x`` (the receding-horizon laws of both protocols and the DP optimum) run for T steps
on the same sampled losses and noise (common random numbers); each run's mean stage cost is compared
with its exact expectation from second moments (:mod:`.moments`).

Runs are drawn in blocks of ``BLOCK`` (a fixed size, so the numbers depend only on the seed): block b
draws from its own stream, ``SeedSequence(seed).spawn(2)[part].spawn(blocks)[b]`` (part 0 open loop,
1 closed loop; in the closed loop the block's stream spawns one child for the losses, one for the
noise, each drawn run by run, so the first runs are the same whatever the number of samples).
Inside a block every step is one array operation over the block's runs and laws.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..costs import closed_form, expected_cost
from ..errors import InputError, NumericalError, ResourceError
from ..model import System
from ..progress import progress_bar
from ..results import ClosedLoopRun, OpenLoopCheck, Simulation
from ..tolerances import MEMORY_BUDGET_BYTES
from .channels import sample_deliveries, sample_delivery_paths, sample_noise, sample_noise_paths
from .moments import finite_horizon_costs, stationary_channel
from .riccati import dp_riccati
from .stability import is_mean_square_stable, mean_square_radius

__all__ = ["BLOCK", "LAWS", "law_gains", "simulate", "z_score"]

#: Runs per block: one random stream, one progress step, O(BLOCK (N m + N n)) memory per block.
BLOCK = 4096
#: The laws a closed loop can run: the receding-horizon laws of both protocols and the DP optimum.
LAWS = ("tcp", "udp", "dp")


def _count(value: object, field: str, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < least:
        raise InputError(field, f"expected an integer >= {least}, found {value!r}")
    return int(value)


def _blocks(samples: int) -> list[int]:
    return [min(BLOCK, samples - start) for start in range(0, samples, BLOCK)]


def _stats(values: np.ndarray) -> tuple[float, float]:
    with np.errstate(over="ignore", invalid="ignore"):
        return float(values.mean()), float(values.std(ddof=1) / np.sqrt(values.size))


def z_score(mean: float, stderr: float, exact: float) -> float:
    """``(mean - exact) / stderr``; for a sample without spread (``stderr`` at rounding level, 1e-12 of the
    scale: deterministic deliveries, no noise) 0 when ``mean`` matches ``exact`` to 1e-9 relative, else
    +-inf: rounding differences between runs are not read as a 316-sigma disagreement."""
    scale = max(abs(exact), abs(mean), np.finfo(float).tiny)
    if stderr <= 1e-12 * scale:
        return 0.0 if abs(mean - exact) <= 1e-9 * scale else float(np.copysign(np.inf, mean - exact))
    return (mean - exact) / stderr


def open_loop_costs(system: System, inputs: np.ndarray, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Realised costs ``x'Qx + sum_t X_{t+1}'Omega_t X_{t+1} + (V_t u_t)'Psi_t (V_t u_t)`` of the plan
    ``inputs`` (N×m), deliveries and noise from :mod:`.channels`. Time O(samples N n (n + m))."""
    N, m, n = system.horizon, system.m, system.n
    V = sample_deliveries(system, samples, rng).reshape(samples, N, m)
    W = sample_noise(system, samples, rng).reshape(samples, N, n) if system.noise_cov.any() else None
    X = np.repeat(system.x0[None], samples, axis=0)
    total = np.full(samples, float(system.x0 @ system.initial_weight @ system.x0))
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(N):
            applied = V[:, t] * inputs[t]
            total += applied ** 2 @ system.input_weights[t]
            X = X @ system.A.T + applied @ system.B.T
            if W is not None:
                X += W[:, t]
            total += np.einsum("si,ij,sj->s", X, system.state_weights[t], X)
    return total


def law_gains(system: System, laws: Sequence[str]) -> dict[str, np.ndarray | str]:
    """Each law's stationary gain, or the reason there is none (the DP optimum without a stabilising
    solution). "tcp"/"udp": the receding-horizon gain (Theorem 1's first block); "dp": the modified Riccati law."""
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
    """
    Omega, psi = system.state_weights[0], system.input_weights[0]
    V = sample_delivery_paths(system, steps, samples, rng)
    W = sample_noise_paths(system, steps, samples, noise_rng if noise_rng is not None else rng)
    L = gains.shape[0]
    X = np.broadcast_to(system.x0, (L, samples, system.n)).copy()
    norms = np.empty((L, samples, steps + 1))
    stage = np.empty((L, samples, steps))
    states = np.empty((L, keep, steps + 1, system.n))
    KT = np.transpose(gains, (0, 2, 1))
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            norms[:, :, t] = np.linalg.norm(X, axis=2)
            states[:, :, t] = X[:, :keep]
            applied = V[t] * -(X @ KT)
            stage[:, :, t] = np.einsum("lsi,ij,lsj->ls", X, Omega, X) + applied ** 2 @ psi
            X = X @ system.A.T + applied @ system.B.T
            if W is not None:
                X += W[t]
        norms[:, :, steps] = np.linalg.norm(X, axis=2)
        states[:, :, steps] = X[:, :keep]
    return stage.mean(axis=2), norms, stage, states


def simulate(system: System, samples: int, steps: int = 50, seed: int = 0, closed_loop: bool = False,
             laws: Sequence[str] = LAWS, keep: int = 0, progress: bool | None = None) -> Simulation:
    """Sample the stated model and compare with the exact expectations.

    Parameters
    ----------
    system : System
    samples : int
        Runs (>= 2), vectorised in blocks of :data:`BLOCK`.
    steps : int
        Closed-loop steps T (>= 1).
    seed : int
        Seeds every stream (>= 0).
    closed_loop : bool
        Also run the laws in closed loop (needs a stationary channel).
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
    ResourceError
        A block's arrays (O(BLOCK T (n + m + laws))) would exceed the memory budget (refused before drawing).

    Notes
    -----
    Time O(samples N n (n + m)) open loop, O(laws samples T n (n + m)) closed loop, plus the exact values
    (O(T n^3) each); memory O(BLOCK (N + T) (n + m) laws).

    Examples
    --------
    >>> from packetloss_cvx import load_example
    >>> sim = simulate(load_example("two_actuator"), samples=2000, seed=0, laws=["tcp"])
    >>> check = sim.open_loop["tcp"]
    >>> bool(abs(check.mean - check.exact) < 4 * check.stderr)
    True
    """
    samples, steps, seed = _count(samples, "samples", 2), _count(steps, "steps", 1), _count(seed, "seed", 0)
    keep = min(_count(keep, "keep", 0), samples)
    laws = list(dict.fromkeys(laws))
    for law in laws:
        if law not in LAWS:
            raise InputError("law", f"expected tcp, udp or dp, found {law!r}")
    if not laws or (not closed_loop and laws == ["dp"]):
        raise InputError("law", "the DP optimum is a closed-loop law: run the closed loop (closed_loop=True, "
                                "--closed-loop) or add tcp or udp")
    if closed_loop:
        stationary_channel(system)
        _check_memory(system, min(BLOCK, samples), steps, len(laws), keep)
    open_part, closed_part = np.random.SeedSequence(seed).spawn(2)
    blocks = _blocks(samples)
    plans = {p: closed_form(system, p) for p in laws if p != "dp"}
    costs: dict[str, list[np.ndarray]] = {p: [] for p in plans}
    work = len(blocks) * (len(plans) > 0) + len(blocks) * closed_loop
    with progress_bar(total=work, desc="simulate", progress=progress) as bar:
        for size, stream in zip(blocks, open_part.spawn(len(blocks)), strict=True):
            if not plans:
                break
            for p, sol in plans.items():   # every plan on the same draws: one generator per plan from the same stream
                costs[p].append(open_loop_costs(system, sol.inputs, size, np.random.default_rng(stream)))
            bar.update(1)
        open_loop = {}
        for p, sol in plans.items():
            mean, stderr = _stats(np.concatenate(costs[p]))
            exact = expected_cost(system, sol.inputs, "udp")
            open_loop[p] = OpenLoopCheck(sol.cost, exact, mean, stderr, z_score(mean, stderr, exact))
        runs, trajectories = {}, None
        if closed_loop:
            runs, trajectories = _closed_loop(system, law_gains(system, laws), steps, blocks,
                                              closed_part.spawn(len(blocks)), keep, bar)
    return Simulation(samples, steps, seed, open_loop, runs, trajectories)


def _check_memory(system: System, block: int, steps: int, laws: int, keep: int) -> None:
    """Refuse, before drawing, a closed loop whose block arrays exceed the memory budget: deliveries and
    noise (block steps (m + 8 n)), norms and stage costs (16 laws block steps), kept states."""
    needed = block * (steps + 1) * (system.m + 8 * system.n + 16 * laws) + 8 * laws * keep * (steps + 1) * system.n
    if needed > MEMORY_BUDGET_BYTES:
        raise ResourceError(f"the closed-loop simulation needs about {needed / 2**30:.1f} GiB per block of {block} "
                            f"runs over {steps} steps (budget {MEMORY_BUDGET_BYTES / 2**30:.1f} GiB): fewer steps",
                            needed, MEMORY_BUDGET_BYTES)


def _closed_loop(system: System, gains: dict[str, np.ndarray | str], steps: int, blocks: list[int],
                 streams: list[np.random.SeedSequence], keep: int, bar) -> tuple[dict[str, ClosedLoopRun], np.ndarray]:
    """Every law with a gain on the same blocks; the statistics and exact values of each."""
    names = [law for law, g in gains.items() if not isinstance(g, str)]
    K = np.array([gains[law] for law in names]).reshape(len(names), system.m, system.n)
    run_costs, stages, norm_sum, norm_sq, kept = [], [], 0.0, 0.0, []
    left = keep
    for size, stream in zip(blocks, streams, strict=True):
        if names:
            losses, noise = (np.random.default_rng(child) for child in stream.spawn(2))
            cost, norms, stage, states = closed_loop_block(system, K, steps, size, losses, keep=min(left, size),
                                                           noise_rng=noise)
            left -= states.shape[1]
            run_costs.append(cost)
            stages.append(stage.sum(axis=1))
            with np.errstate(over="ignore", invalid="ignore"):
                norm_sum = norm_sum + norms.sum(axis=1)
                norm_sq = norm_sq + (norms ** 2).sum(axis=1)
            kept.append(states)
        bar.update(1)
    samples = sum(blocks)
    out: dict[str, ClosedLoopRun] = {}
    nan = np.full(steps + 1, np.nan)
    for law, gain in gains.items():
        if isinstance(gain, str):
            out[law] = ClosedLoopRun(law, np.nan, np.nan, np.nan, np.nan, False, nan, nan, nan[:-1], reason=gain)
            continue
        k = names.index(law)
        mean, stderr = _stats(np.concatenate([c[k] for c in run_costs]))
        radius = mean_square_radius(system.A, system.B, gain, system.mu_schedule[0])
        exact = float(finite_horizon_costs(system, gain, steps)[0].mean())
        with np.errstate(over="ignore", invalid="ignore"):
            norm_mean = norm_sum[k] / samples
            norm_std = np.sqrt(np.maximum(norm_sq[k] / samples - norm_mean ** 2, 0.0))
            stage_mean = sum(s[k] for s in stages) / samples
        out[law] = ClosedLoopRun(law, mean, stderr, exact, radius, is_mean_square_stable(radius), norm_mean, norm_std,
                                 stage_mean)
    trajectories = np.concatenate(kept, axis=1) if kept else np.empty((0, 0, steps + 1, system.n))
    return out, trajectories
