"""What every Monte Carlo of [`simulate`][packetloss_cvx.montecarlo.simulate.simulate] shares, whatever the channel:
run counts and blocks, sample statistics and z-scores, the memory check of a closed-loop block, and the
realised cost of an open-loop plan on given deliveries and noise."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from ..budgets import check, count_text, gib_text, loop_bytes
from ..errors import InputError
from ..model.system import System
from ..results import OpenLoopCheck

__all__ = [
    "BLOCK", "LoopStats", "check_count", "check_loop_memory", "loop_statistics",
    "open_loop_checks", "plan_costs", "run_blocks",
    "sample_stats", "z_score",
]

#: Runs per block: one random stream, one progress step, O(BLOCK (N m + N n)) memory per block.
BLOCK = 4096


class LoopStats(NamedTuple):
    """One law's closed-loop sample: mean and standard error of the runs' mean stage cost; per step the mean
    and standard deviation of ||x_t|| (t <= steps) and the mean stage cost (t < steps).

    Examples
    --------
    >>> st = LoopStats(2.5, 0.1, np.ones(3), np.zeros(3), np.full(2, 2.5))   # steps = 2
    >>> mean, stderr, *per_step = st                                          # a tuple: it unpacks
    >>> st.mean == mean, [a.shape for a in per_step]
    (True, [(3,), (3,), (2,)])
    """

    mean: float
    stderr: float
    norm_mean: np.ndarray
    norm_std: np.ndarray
    stage_mean: np.ndarray


def check_count(value: object, field: str, least: int) -> int:
    """``value`` as an int >= ``least``, else InputError naming ``field``. O(1).

    Examples
    --------
    >>> check_count(np.int64(3), "samples", 2)
    3
    >>> for bad in (1, True, 2.0):                 # below least, a bool, a float
    ...     try:
    ...         check_count(bad, "samples", 2)
    ...     except InputError as err:
    ...         print(err.field)
    samples
    samples
    samples
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < least:
        raise InputError(field, f"expected an integer >= {least}, found {value!r}")
    return int(value)


def run_blocks(samples: int) -> list[int]:
    """Block sizes: ``samples`` split in blocks of `BLOCK` (the last one shorter). O(samples / BLOCK).

    Examples
    --------
    >>> run_blocks(2 * BLOCK + 5) == [BLOCK, BLOCK, 5], run_blocks(BLOCK) == [BLOCK]
    (True, True)
    """
    return [min(BLOCK, samples - start) for start in range(0, samples, BLOCK)]


def sample_stats(values: np.ndarray) -> tuple[float, float]:
    """``(mean, standard error)`` of a sample (inf/nan propagate), computed on the sample divided by its largest
    magnitude, so that costs up to the double range do not overflow in their squares. O(size).

    Examples
    --------
    >>> mean, stderr = sample_stats(np.array([1.0, 2.0, 3.0, 4.0]))   # variance (ddof 1) 5/3, over sqrt(4)
    >>> mean, bool(np.isclose(stderr, (5 / 3) ** 0.5 / 2))
    (2.5, True)
    >>> mean, stderr = sample_stats(np.array([1.0, 2.0, 3.0, 4.0]) * 1e200)   # the squares would be 1e400
    >>> bool(np.isclose(mean, 2.5e200)), bool(np.isclose(stderr, (5 / 3) ** 0.5 / 2 * 1e200))
    (True, True)
    """
    with np.errstate(over="ignore", invalid="ignore"):
        scale = float(np.abs(values).max()) if values.size else 0.0
        if not np.isfinite(scale) or scale == 0.0:
            return float(values.mean()), float(values.std(ddof=1) / np.sqrt(values.size))
        unit = values / scale
        return float(unit.mean() * scale), float(unit.std(ddof=1) / np.sqrt(values.size) * scale)


def z_score(mean: float, stderr: float, exact: float) -> float:
    """``(mean - exact) / stderr``; for a sample without spread (``stderr`` at rounding level, 1e-12 of the
    scale: deterministic deliveries, no noise) 0 when ``mean`` matches ``exact`` to 1e-9 relative, else
    +-inf: rounding differences between runs are not read as a 316-sigma disagreement. nan when a number is not
    finite (a spread or a cost beyond the double range: there is no error bar to measure against).

    >>> z_score(1.0, 0.5, 0.0), z_score(2.0, 0.0, 2.0), z_score(1e300, float("inf"), 2e300)
    (2.0, 0.0, nan)
    """
    if not (np.isfinite(stderr) and np.isfinite(mean) and np.isfinite(exact)):
        return float("nan")
    scale = max(abs(exact), abs(mean), np.finfo(float).tiny)
    if stderr <= 1e-12 * scale:
        return 0.0 if abs(mean - exact) <= 1e-9 * scale else float(np.copysign(np.inf, mean - exact))
    return (mean - exact) / stderr


def open_loop_checks(plans: dict[str, Any], blocks: list[int], streams: list[np.random.SeedSequence],
                     draw: Callable[[int, np.random.Generator], Any], cost: Callable[[np.ndarray, Any], np.ndarray],
                     exact: Callable[[np.ndarray], float], bar: Any) -> dict[str, OpenLoopCheck]:
    """Each plan (``.inputs``, ``.cost`` the formula) sampled block by block on the same draws, against
    ``exact(inputs)``: each block's draws ``draw(size, rng)`` (rng from the block's stream) made once and costed
    for every plan, ``cost(inputs, draws)``; ``bar`` moves one step a block. O(samples) memory per plan, plus one
    block's draws; time one draw per block plus what ``cost`` costs per plan.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> plan = SimpleNamespace(inputs=np.zeros((1, 1)), cost=1.0)
    >>> def draw(size, rng):
    ...     return rng.standard_normal(size)
    >>> seqs = np.random.SeedSequence(0).spawn(2)
    >>> checks = open_loop_checks({"a": plan, "b": plan}, [500, 500], seqs, draw, lambda u, z: 1.0 + z,
    ...                           lambda u: 1.0, SimpleNamespace(update=lambda k: None))
    >>> checks["a"] == checks["b"], abs(checks["a"].z) < 4     # the same draws for every plan; mean 1, variance 1
    (True, True)
    """
    costs: dict[str, list[np.ndarray]] = {p: [] for p in plans}
    if plans:
        for size, stream in zip(blocks, streams, strict=True):
            draws = draw(size, np.random.default_rng(stream))
            for p, sol in plans.items():
                costs[p].append(cost(sol.inputs, draws))
            bar.update(1)
    checks = {}
    for p, sol in plans.items():
        mean, stderr = sample_stats(np.concatenate(costs[p]))
        value = exact(sol.inputs)
        no_bar = "" if np.isfinite(stderr) else (
            "no error bar: the sampled costs' spread exceeds the double range (their squares overflow), so the "
            "sample's standard error is not computed; use the exact value")
        checks[p] = OpenLoopCheck(sol.cost, value, mean, np.nan if no_bar else stderr,
                                  z_score(mean, stderr, value), stderr_reason=no_bar)
    return checks


def check_loop_memory(system: System, block: int, steps: int, laws: int, keep: int) -> None:
    """Refuse, before drawing, a closed loop whose block arrays exceed the ``memory_bytes`` budget (budgets.py):
    deliveries and noise as drawn and as the loop reads them (runs last: a copy of each, block steps (2 m + 16 n)),
    norms and stage costs (16 laws block steps), kept states. The steps are the caller's count: a
    [`BudgetError`][packetloss_cvx.errors.BudgetError] under ``steps``, as for the work budget.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> check_loop_memory(s, BLOCK, 50, 3, 0)            # 4096 * 51 * 66 bytes: fine
    >>> from packetloss_cvx.errors import BudgetError
    >>> try:
    ...     check_loop_memory(s, BLOCK, 10**7, 3, 0)      # about 2e12 bytes
    ... except BudgetError as err:
    ...     print(err.field, err.env)
    steps PACKETLOSS_CVX_BUDGET_MEMORY_BYTES
    """
    needed = loop_bytes(block, steps, system.n, system.m, laws, keep)
    check("memory_bytes", needed, "steps", f"{count_text(steps)} steps of a closed loop (about {gib_text(needed)} "
                                           f"for a block of {block} runs)", instead="use fewer steps")


def plan_costs(system: System, inputs: np.ndarray, delivered: np.ndarray, noise: np.ndarray | None) -> np.ndarray:
    """Realised costs ``x'Qx + sum_t X_{t+1}'Omega_t X_{t+1} + (V_t u_t)'Psi_t (V_t u_t)`` of the plan
    ``inputs`` (N×m) on the deliveries ``delivered`` (samples, N, m) and the noise (samples, N, n) or None.
    The cost inside the expectation of eq:plant0.
    Time O(samples N n (n + m)).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> v = np.array([True, False]).reshape(2, 1, 1)      # run 0 delivers u = -2, run 1 loses it
    >>> plan_costs(s, np.array([[-2.0]]), v, None).tolist()   # Q = 0; (V u)^2 + (1 + V u)^2
    [5.0, 1.0]
    >>> plan_costs(s, np.array([[-2.0]]), v, np.full((2, 1, 1), 1.0)).tolist()   # w = 1: x1 = 0 or 2
    [4.0, 4.0]
    """
    samples = delivered.shape[0]
    X = np.repeat(system.x0[None], samples, axis=0)
    total = np.full(samples, float(system.x0 @ system.initial_weight @ system.x0))
    # time-major copies: each step reads one contiguous (samples, .) slice; the same numbers
    delivered = np.ascontiguousarray(np.swapaxes(delivered, 0, 1))
    noise = None if noise is None else np.ascontiguousarray(np.swapaxes(noise, 0, 1))
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(system.horizon):
            applied = delivered[t] * inputs[t]
            total += applied ** 2 @ system.input_weights[t]
            X = X @ system.A.T + applied @ system.B.T
            if noise is not None:
                X += noise[t]
            total += np.einsum("si,si->s", X @ system.state_weights[t], X)   # a 3-operand einsum: ~10x slower
    return total


def loop_statistics(count: int, block: Callable[..., tuple[np.ndarray, ...]], steps: int, n: int,
                    blocks: list[int], streams: list[np.random.SeedSequence], keep: int,
                    bar: Any) -> tuple[list[LoopStats], np.ndarray]:
    """Run ``count`` laws together block by block and gather each law's statistics.

    ``block(size, losses, noise, keep)`` returns ``(run_cost (L, size), norms (L, size, steps + 1), stage (L, size,
    steps), states (L, keep, steps + 1, n))`` (as `closed_loop_block`);
    block b draws its losses and its noise from the two children of ``streams[b]``. Returns one
    `LoopStats` per law and the kept states (L, keep, steps + 1, n). Time: the blocks', plus O(L samples steps).

    Examples
    --------
    >>> from packetloss_cvx.montecarlo.simulate import closed_loop_block
    >>> from packetloss_cvx.closedloop.moments import finite_horizon_costs
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> gains = np.array([[[0.5]], [[0.0]]])                # u = -x/2, and no input
    >>> def block(size, losses, noise, keep):
    ...     return closed_loop_block(s, gains, 3, size, losses, keep, noise)
    >>> bar = type("Bar", (), {"update": lambda self, k: None})()
    >>> stats, kept = loop_statistics(2, block, 3, 1, [3000], np.random.SeedSequence(0).spawn(1), 2, bar)
    >>> exact = finite_horizon_costs(s, [[0.5]], 3)[0].mean()   # the mean stage cost's expectation
    >>> bool(abs(stats[0].mean - exact) < 4 * stats[0].stderr), kept.shape
    (True, (2, 2, 4, 1))
    >>> stats[1].mean, stats[1].stderr, stats[1].norm_std.tolist()   # no input: x = 1 in every run
    (1.0, 0.0, [0.0, 0.0, 0.0, 0.0])
    """
    run_costs, stages, norm_sum, norm_sq, kept = [], [], 0.0, 0.0, []
    left = keep
    for size, stream in zip(blocks, streams, strict=True):
        if count:
            losses, noise = (np.random.default_rng(child) for child in stream.spawn(2))
            cost, norms, stage, states = block(size, losses, noise, min(left, size))
            left -= states.shape[1]
            run_costs.append(cost)
            stages.append(stage.sum(axis=1))
            with np.errstate(over="ignore", invalid="ignore"):
                norm_sum = norm_sum + norms.sum(axis=1)
                norm_sq = norm_sq + (norms ** 2).sum(axis=1)
            kept.append(states)
        bar.update(1)
    samples = sum(blocks)
    out = []
    for k in range(count):
        mean, stderr = sample_stats(np.concatenate([c[k] for c in run_costs]))
        with np.errstate(over="ignore", invalid="ignore"):
            norm_mean = norm_sum[k] / samples
            norm_std = np.sqrt(np.maximum(norm_sq[k] / samples - norm_mean ** 2, 0.0))
            stage_mean = sum(s[k] for s in stages) / samples
        out.append(LoopStats(mean, stderr, norm_mean, norm_std, stage_mean))
    trajectories = np.concatenate(kept, axis=1) if kept else np.empty((0, 0, steps + 1, n))
    return out, trajectories
