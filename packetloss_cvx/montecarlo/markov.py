"""``simulate`` behind Gilbert–Elliott channels: the chain sampled per run, compared with the exact
expectations under the chain (never with the Bernoulli model of its plug-in mu_t).

Open loop: each protocol's plug-in plan (the paper's law with the chain's predicted mu_t, ``formula`` its
J*) and the exact minimiser of the plan's expected cost under correlated losses
([`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form], key ``"exact_minimiser"``), each sampled and
compared with [`markov_cost`][packetloss_cvx.lq.markov_cost] (the expected realised cost under the chain).

Closed loop (`markov_loop_block`): "tcp" re-plans at the
HMM-filtered belief, "udp" at the propagated prior, "dp" is the mode-dependent coupled-Riccati law with the
channel state known (`coupled_riccati`). Exact values where a finite mode
description exists (`jump_law_stage_costs`): the UDP-like law always (one
time-varying gain), the TCP-like law when every outcome reveals its channel's state (the gain is a function of
the last state), the DP law always; otherwise None with the reason. Draws as the Bernoulli path's (same
streams, same layout), so a memoryless Gilbert chain (p + r = 1) reproduces the Bernoulli numbers with mu = r.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..closedloop.mjls import coupled_riccati, jump_law_stage_costs, mean_square_radius, mode_chain
from ..closedloop.stability import is_mean_square_stable
from ..closedloop.tails import error_bar_reason
from ..errors import InputError, NumericalError, ResourceError
from ..lq.costs import closed_form
from ..lq.markov_cost import exact_closed_form, exact_cost
from ..model.chain import filter_belief
from ..model.system import System
from ..progress import progress_bar
from ..results import ClosedLoopRun, OpenLoopCheck, Simulation
from .channels import sample_noise
from .markov_channels import reveals_state, sample_markov_paths
from .markov_loop import BeliefGains, markov_loop_block
from .runs import (
    BLOCK,
    check_loop_memory,
    loop_statistics,
    open_loop_checks,
    plan_costs,
    run_blocks,
)

__all__ = ["DP_NOTE", "EXACT_PLAN", "markov_open_loop_costs", "markov_open_loop_draws", "simulate_markov"]

#: The open-loop entry of the exact minimiser's plan.
EXACT_PLAN = "exact_minimiser"
#: What the "dp" law is behind a chain (reported with it).
DP_NOTE = ("mode-dependent coupled-Riccati law (Costa, Fragoso, Marques 2005, ch. 4): the controller knows every "
           "channel's current state (good/bad) before it sends, more than TCP-like acknowledgements give")


def markov_open_loop_costs(system: System, inputs: np.ndarray, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Realised costs of the plan ``inputs`` (N×m) with the chain sampled per run
    (`sample_markov_paths`, then the noise as
    `sample_noise`). Time O(samples N n (n + m)).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> from packetloss_cvx.montecarlo.simulate import open_loop_costs
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            noise_cov=[[0.5]], channel=GilbertElliott(p=[0.4], r=[0.6]))    # p + r = 1: memoryless
    >>> U = np.array([[-1.0], [-0.5]])
    >>> c = markov_open_loop_costs(s, U, 4000, np.random.default_rng(0))
    >>> bool(np.array_equal(c, open_loop_costs(s.with_mu([0.6]), U, 4000, np.random.default_rng(0))))   # same draws
    True
    >>> bool(abs(c.mean() - exact_cost(s, U)) < 4 * c.std() / 4000 ** 0.5)
    True
    """
    return plan_costs(system, inputs, *markov_open_loop_draws(system, samples, rng))


def markov_open_loop_draws(system: System, samples: int,
                           rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
    """The deliveries (samples, N, m) with the chain sampled per run
    (`sample_markov_paths`) and the noise (samples, N, n) as
    `sample_noise`, or None without noise. Time and memory
    O(samples N (m + n)).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.0], r=[1.0], state=["bad"]))     # bad, then good for ever
    >>> V, W = markov_open_loop_draws(s, 2, np.random.default_rng(0))
    >>> V[:, :, 0].tolist(), W is None
    ([[False, True, True], [False, True, True]], True)
    """
    N, n = system.horizon, system.n
    _, V = sample_markov_paths(system.channel, N, samples, rng)
    W = sample_noise(system, samples, rng).reshape(samples, N, n) if system.noise_cov.any() else None
    return V, W


def simulate_markov(system: System, samples: int, steps: int, seed: int, closed_loop: bool, laws: Sequence[str],
                    keep: int, progress: bool | None) -> Simulation:
    """[`simulate`][packetloss_cvx.montecarlo.simulate.simulate] for a system with a Gilbert–Elliott channel (arguments
    validated there). Same seeding as the Bernoulli path. Time O(samples N n (n + m) + N (D^3 + m^3)), D = n (1 + m)
    open loop; closed loop O(laws samples steps n (n + m)) plus one plan per distinct belief and the exact values
    (O(steps 4^m n^3) each, the radii O((2^m n^2)^3)).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.3]))
    >>> sim = simulate_markov(s, 2000, 5, 0, True, ["udp"], 0, False)
    >>> check, run = sim.open_loop["udp"], sim.closed_loop["udp"]
    >>> bool(abs(check.mean - check.exact) < 4 * check.stderr)
    True
    >>> bool(abs(run.mean_stage_cost - run.exact_stage_cost) < 4 * run.stderr), run.stable
    (True, True)
    """
    if closed_loop:
        check_loop_memory(system, min(BLOCK, samples), steps, len(laws), keep)
    open_part, closed_part = np.random.SeedSequence(seed).spawn(2)
    blocks = run_blocks(samples)
    plans = {p: closed_form(system.with_mu(system.mu_schedule), p) for p in laws if p != "dp"}
    extra = ""
    if plans:
        try:
            plans[EXACT_PLAN] = exact_closed_form(system, "udp")
        except (NumericalError, ResourceError) as err:
            extra = str(err)
    work = len(blocks) * (len(plans) > 0) + len(blocks) * closed_loop
    with progress_bar(total=work, desc="simulate (Gilbert-Elliott)", progress=progress) as bar:
        open_loop = open_loop_checks(plans, blocks, open_part.spawn(len(blocks)),
                                     lambda size, rng: markov_open_loop_draws(system, size, rng),
                                     lambda inputs, draws: plan_costs(system, inputs, *draws),
                                     lambda inputs: exact_cost(system, inputs, "udp"), bar)
        if extra:
            open_loop[EXACT_PLAN] = OpenLoopCheck(np.nan, np.nan, np.nan, np.nan, np.nan, reason=extra)
        runs, trajectories = {}, None
        if closed_loop:
            runs, trajectories = _closed_loop(system, list(laws), steps, blocks, closed_part.spawn(len(blocks)),
                                              keep, bar)
    return Simulation(samples, steps, seed, open_loop, runs, trajectories,
                      channel=system.channel.form)


def _closed_loop(system: System, laws: list[str], steps: int, blocks: list[int], streams: list[np.random.SeedSequence],
                 keep: int, bar) -> tuple[dict[str, ClosedLoopRun], np.ndarray]:
    most = sum(blocks) * steps                   # the most distinct beliefs a law can meet: one a run and step
    tcp = BeliefGains(system, "tcp", most=most) if "tcp" in laws else None
    udp = BeliefGains(system, "udp", most=most) if "udp" in laws else None
    dp, dp_reason = None, ""
    if "dp" in laws:
        try:
            dp = coupled_riccati(system)
        except (NumericalError, ResourceError, InputError) as err:
            dp_reason = str(err)
    names = [law for law in laws if law != "dp" or dp is not None]

    def block(size: int, losses: np.random.Generator, noise: np.random.Generator, kept: int) -> tuple[np.ndarray, ...]:
        return markov_loop_block(system, names, tcp, udp, None if dp is None else dp.gains, steps, size, losses,
                                 noise, kept)

    stats, trajectories = loop_statistics(len(names), block, steps, system.n, blocks, streams, keep, bar)
    out: dict[str, ClosedLoopRun] = {}
    for law in laws:
        if law == "dp" and dp is None:
            nan = np.full(steps + 1, np.nan)
            out[law] = ClosedLoopRun(law, np.nan, np.nan, np.nan, np.nan, False, nan, nan, nan[:-1], reason=dp_reason,
                                     note=DP_NOTE)
            continue
        exact, radius, reason, limit = _exact(system, law, steps, tcp if law == "tcp" else udp, dp)
        st = stats[names.index(law)]
        no_bar = _error_bar(system, limit)
        out[law] = ClosedLoopRun(law, st.mean, np.nan if no_bar else st.stderr, exact, radius,
                                 is_mean_square_stable(radius), st.norm_mean, st.norm_std, st.stage_mean,
                                 exact_reason=reason, note=_note(system, law), stderr_reason=no_bar)
    return out, trajectories


def _note(system: System, law: str) -> str:
    if law == "dp":
        return DP_NOTE
    if law == "udp" and system.channel.belief is not None:
        return ("the UDP-like law changes with the propagated belief; its radius is the limiting law's (at the "
                "stationary belief, which the belief approaches at rate |1 - p - r|)")
    return ""


def _error_bar(system: System, limit: tuple[np.ndarray, str] | None) -> str:
    """Why the law's sampled cost has no error bar behind the chain ("" when its limiting law's coupled fourth
    moments are proved bounded, simulation.tails)."""
    if limit is None:
        return ("no error bar: the law has no finite Markov jump description, so its fourth moments (the sample's "
                "variance) are unproved; use the exact value where one is given")
    _, T, h = mode_chain(system.channel)
    return error_bar_reason(system.A, system.B, limit[0], h, T, limit[1])


def _exact(system: System, law: str, steps: int, gains: BeliefGains | None,
           dp) -> tuple[float, float, str, tuple[np.ndarray, str] | None]:
    """``(exact mean stage cost, MJLS radius, reason, (limiting mode gains, delivery))`` of a law behind the chain;
    nan with the reason where no finite mode description exists, or the mode chain or the dense operator is
    refused (the limiting law None where there is none)."""
    ch = system.channel
    if law == "tcp" and not reveals_state(ch):
        return np.nan, np.nan, ("the TCP-like law re-plans at the HMM-filtered belief, which takes a continuum of "
                                "values when an outcome does not reveal its channel's state (h_good, h_bad not "
                                "1 and 0): no finite Markov jump description, so no exact value or MJLS radius"), None
    try:
        modes, _, h = mode_chain(ch)
        if law == "dp":
            return (float(jump_law_stage_costs(system, dp.gains, steps, "current").mean()), dp.spectral_radius, "",
                    (dp.gains, "current"))
        if law == "udp":
            prior, K = np.array(ch.initial_belief, dtype=float), []
            for _ in range(steps):                       # the simulation's own propagation, hence its plans
                K.append(gains(prior))
                prior = ch.propagate(prior)
            table, delivery, first, limit = np.repeat(np.array(K)[:, None], len(modes), axis=1), "current", None, \
                gains(ch.stationary)
        else:                                            # the last outcome reveals the state: a gain per state
            spread = np.array([np.pad(np.full(k, 1.0 / k), (0, max(ch.sizes) - k)) for k in ch.sizes])  # full support
            table = np.array([gains(filter_belief(ch, spread, h[a] == 1)) for a in range(len(modes))])
            delivery, first, limit = "next", gains(np.array(ch.initial_belief, dtype=float)), table
        exact = float(jump_law_stage_costs(system, table, steps, delivery, first_gain=first).mean())
    except (InputError, ResourceError) as err:
        return np.nan, np.nan, str(err), None
    if law == "udp" and not ch.belief_settles:
        return exact, np.nan, ("the propagated belief of a periodic or frozen chain (|1 - p - r| = 1) need not settle: "
                               "no limiting law whose radius decides stability"), None
    M = len(modes)
    limit = np.broadcast_to(limit, (M, *np.shape(limit)[-2:])) if np.ndim(limit) == 2 else limit
    try:
        return exact, mean_square_radius(system.A, system.B, ch, limit, delivery), "", (np.asarray(limit), delivery)
    except ResourceError as err:
        return exact, np.nan, str(err), (np.asarray(limit), delivery)
