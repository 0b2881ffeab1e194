"""Sampling the loop of ``u = -K x`` when the actuator zeroes, holds or plays the buffered plan on a loss, against
its exact expectation (`packetloss_cvx.closedloop.actuator`).

Each run draws its channel path (Bernoulli, or the system's chain from its initial belief), its deliveries and its
noise from ``SeedSequence([seed, ACTUATOR_STREAM])``, in blocks of ``BLOCK`` runs (block b from its own child
stream, so that the first runs are the same whatever the number of samples); every step is one array operation
over the block's runs. The actuator's logic is written out (not the engine's augmented state): zero plays ``v u``,
hold ``u`` or the last applied input, buffer:L stores the delivered plan ``-K (A - B K)^j x``, j < L, and plays
entry j after j losses, 0 beyond (buffer:L:hold: the last applied input beyond).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..closedloop.actuator import Actuator, actuator_costs, actuator_loop, actuator_radius, parse_actuator
from ..closedloop.mjls import mode_chain, mode_start
from ..closedloop.moments import check_steps, stationary_channel
from ..closedloop.stability import is_mean_square_stable
from ..closedloop.tails import error_bar_reason
from ..errors import NumericalError
from ..model.system import System, check_system, loop_weights
from .runs import BLOCK, check_count, z_score

__all__ = ["ACTUATOR_STREAM", "sample_actuator_loop", "simulate_actuator"]

#: The entropy word that keeps these draws apart from simulate's other streams under the same seed.
ACTUATOR_STREAM = 37


def _chain(channel: object, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(T, h, start)`` of a chain, or of one state delivering ``channel`` (Bernoulli mu)."""
    if isinstance(channel, np.ndarray):
        return np.ones((1, 1)), channel.reshape(1, m), np.ones(1)
    _, T, h = mode_chain(channel)
    return T, h, mode_start(channel)


def _block(system: System, K: np.ndarray, strategy: Actuator, T: np.ndarray, h: np.ndarray, start: np.ndarray,
           steps: int, runs: int, rng: np.random.Generator) -> np.ndarray:
    """Each run's stage costs (runs, steps) of one block. Time O(runs steps (n^2 + m n L))."""
    A, B = system.A, system.B
    n, m = B.shape
    Omega, psi = loop_weights(system)
    L = strategy.length
    root = np.linalg.cholesky(system.noise_cov) if system.noise_cov.any() else None
    powers = np.array([[np.linalg.matrix_power(A - B @ K[s], j) for j in range(L)] for s in range(T.shape[0])])
    X = np.repeat(system.x0[None], runs, axis=0)
    c = np.sum(rng.random(runs)[:, None] > np.cumsum(start)[:-1], axis=1)
    held, plans = np.zeros((runs, m)), np.zeros((runs, m, L))
    played = np.full((runs, m), L)                           # nothing buffered before the first packet
    stage = np.empty((runs, steps))
    for t in range(steps):
        v = rng.random((runs, m)) < h[c]
        u = -np.einsum("rij,rj->ri", K[c], X)
        if strategy.kind == "zero":
            applied = np.where(v, u, 0.0)
        elif strategy.kind == "hold":
            applied = np.where(v, u, held)
        else:
            plans = np.where(v[:, :, None], -np.einsum("rij,rljk,rk->ril", K[c], powers[c], X), plans)
            played = np.where(v, 0, played + 1)
            entry = np.take_along_axis(plans, np.minimum(played, L - 1)[:, :, None], axis=2)[:, :, 0]
            applied = np.where(played < L, entry, held if strategy.exhausted == "hold" else 0.0)
        held = applied
        stage[:, t] = np.einsum("ri,ij,rj->r", X, Omega, X) + applied ** 2 @ psi
        X = X @ A.T + applied @ B.T
        if root is not None:
            X += rng.standard_normal((runs, n)) @ root.T
        c = np.sum(rng.random(runs)[:, None] > np.cumsum(T[c], axis=1)[:, :-1], axis=1)
    return stage


def sample_actuator_loop(system: System, gain: npt.ArrayLike, steps: int, actuator: str | Actuator, samples: int,
                         seed: int = 0, mu: npt.ArrayLike | None = None) -> np.ndarray:
    """Each sampled run's stage costs ``x_t' Omega_1 x_t + a_t' Psi_0 a_t`` (a_t the applied input), (samples,
    steps), of ``u = -K x`` (per channel state behind a chain) with the actuator's strategy on a loss; channel as
    `actuator_radius`. Time O(samples steps (n^2 + m n L)).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> sample_actuator_loop(s, [[1.5]], 2, "hold", 2).tolist()      # nothing lost: x = 1, 1/2; u = -3/2, -3/4
    [[3.25, 0.8125], [3.25, 0.8125]]
    """
    system = check_system(system)
    strategy = parse_actuator(actuator, system.horizon)
    check_count(samples, "samples", 1)
    check_steps(steps, samples * system.m * strategy.length)
    channel = system.channel if system.channel is not None and mu is None else \
        np.asarray(stationary_channel(system) if mu is None else mu, dtype=float)
    actuator_loop(system.A, system.B, gain, channel, strategy)        # the gain and mu checked as the exact path does
    T, h, start = _chain(channel, system.m)
    K = np.asarray(gain, dtype=float)
    K = np.repeat(K[None], T.shape[0], axis=0) if K.ndim == 2 else K
    streams = np.random.SeedSequence([seed, ACTUATOR_STREAM]).spawn(-(-samples // BLOCK))
    parts = [_block(system, K, strategy, T, h, start, steps, min(BLOCK, samples - b * BLOCK),
                    np.random.default_rng(stream)) for b, stream in enumerate(streams)]
    return np.concatenate(parts, axis=0)


def simulate_actuator(system: System, gain: npt.ArrayLike, steps: int, actuator: str | Actuator, samples: int,
                      seed: int = 0) -> dict[str, float | bool | str | None]:
    """The sampled loop of `sample_actuator_loop` beside its exact expectation: the mean over runs of each
    run's mean stage cost over t < steps (``mean_stage_cost``, ``stderr``), the exact one (``exact_stage_cost``,
    closedloop.actuator), ``z`` (`z_score`), the mean-square ``radius`` (None with its ``reason``
    where it cannot be computed) and ``stable``. A sample without an error bar (the loop's fourth moments grow or
    are not computed: closedloop.tails.error_bar_reason on the strategy's loop, always so when the loop is not
    mean-square stable) has ``stderr`` and ``z`` None and ``stderr_reason`` saying why. Time: the sampling, plus
    the exact costs O(steps M (M N^2 + N^3)), the radius and the fourth moments.

    Examples
    --------
    >>> s = System(A=[[0.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0],
    ...            noise_cov=[[1.0]])
    >>> row = simulate_actuator(s, [[0.25]], 20, "hold", 4000, seed=1)
    >>> abs(row["z"]) < 4.5, row["stable"]
    (True, True)
    """
    check_count(samples, "samples", 2)
    stage = sample_actuator_loop(system, gain, steps, actuator, samples, seed)
    per_run = stage.mean(axis=1)
    mean, stderr = float(per_run.mean()), float(per_run.std(ddof=1) / np.sqrt(samples))
    exact = float(actuator_costs(system, gain, steps, actuator)[0].mean())
    try:
        radius, reason = actuator_radius(system, gain, actuator), ""
    except NumericalError as err:
        radius, reason = float("nan"), str(err)
    loop = actuator_loop(system.A, system.B, gain, system.channel if system.channel is not None else
                         np.asarray(stationary_channel(system), dtype=float), parse_actuator(actuator, system.horizon))
    no_bar = error_bar_reason(loop.A, loop.B, loop.K, loop.h, loop.T)   # rho_4 >= rho_2^2: unstable has no bar
    out: dict[str, float | bool | str | None] = {
        "mean_stage_cost": mean, "stderr": None if no_bar else stderr, "exact_stage_cost": exact,
        "z": None if no_bar else z_score(mean, stderr, exact), "radius": radius if np.isfinite(radius) else None,
        "stable": is_mean_square_stable(radius), "reason": reason}
    return {**out, "stderr_reason": no_bar} if no_bar else out
