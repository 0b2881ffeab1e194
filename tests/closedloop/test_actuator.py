"""closedloop.actuator: zero, hold and the buffered plan on a loss, each exact through the mode engine.

References, none of them the engine: (a) every delivery path (and channel path) of a short horizon, the actuator's
logic written out per path and weighted by the path's probability; (b) a seeded simulation of a long horizon with
its confidence interval; (c) the scalar plant's renewal closed forms (module docstring of the hand tests);
(d) today's loop (closedloop.stability, moments, mjls) for "zero".
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from scipy.optimize import brentq

from packetloss_cvx.closedloop.actuator import (
    MAX_BUFFER_MODES,
    actuator_costs,
    actuator_loop,
    actuator_radius,
    parse_actuator,
)
from packetloss_cvx.closedloop.mjls import jump_law_stage_costs, mode_chain, mode_start
from packetloss_cvx.closedloop.mjls import mean_square_radius as chain_radius
from packetloss_cvx.closedloop.moments import closed_loop, finite_horizon_costs
from packetloss_cvx.closedloop.stability import mean_square_radius
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import (
    ACTUATOR_CRITICAL_MU_ATOL,
    ACTUATOR_EXACT_RTOL,
    ACTUATOR_ZERO_RTOL,
    ROW_SUM_ATOL,
    SAMPLED_Z_MAX,
)

#: buffer:5 on the n = 2 plants keeps the plan's predicted state (n < L - 1), the shorter buffers its entries
STRATEGIES = ["zero", "hold", "buffer:1", "buffer:2", "buffer:3", "buffer:5"]


def _system(m: int = 1, channel=None, mu=None, noise: bool = True, horizon: int = 6) -> System:
    """A 2-state plant, unstable open loop, one or two actuators."""
    B = [[0.2], [1.0]] if m == 1 else [[0.2, 1.0], [1.0, 0.0]]
    return System(A=[[1.1, 0.4], [-0.3, 0.8]], B=B, horizon=horizon, state_weight=[1.0, 2.0],
                  input_weight=[0.5] * m, x0=[1.0, -0.7], noise_cov=[[0.05, 0.01], [0.01, 0.1]] if noise else None,
                  mu=None if channel is not None else (mu if mu is not None else [0.7] * m), channel=channel)


def _gain(m: int) -> np.ndarray:
    return np.array([[0.4, 0.9]]) if m == 1 else np.array([[0.3, 0.5], [0.4, 0.2]])


def _channel(system: System) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, h, start) of the system's channel: one state for Bernoulli."""
    if system.channel is None:
        return np.ones((1, 1)), system.mu_schedule[0][None], np.ones(1)
    _, T, h = mode_chain(system.channel)
    return T, h, mode_start(system.channel)


def _kind(spec: str) -> tuple[str, int]:
    kind, _, length = spec.partition(":")
    return kind, int(length.partition(":")[0] or 1)


def _holds_when_exhausted(spec: str) -> bool:
    return spec.endswith(":hold")


def enumerated_costs(system: System, K: np.ndarray, steps: int, spec: str) -> tuple[np.ndarray, float]:
    """Expected stage costs over every channel path and delivery path of ``steps`` steps, each path run forward
    with the actuator's logic written out: zero plays v u; hold plays u if delivered, else the last applied input;
    buffer:L stores the delivered plan ``-k_i (A - B K)^j x``, j < L, and plays entry ``j`` after j losses, 0 beyond
    (buffer:L:hold: the last applied input beyond).
    The state is carried as columns: x0 and, for each step s and noise direction, ``Sigma^(1/2) e_j`` entering at
    s (E over the noise is the sum over columns). No moment recursion, no mode chain."""
    A, B = system.A, system.B
    n, m = B.shape
    Omega, psi = system.state_weights[0], system.input_weights[0]
    root = np.linalg.cholesky(system.noise_cov + 0.0 * np.eye(n)) if np.any(system.noise_cov) else np.zeros((n, 0))
    T, h, start = _channel(system)
    Kc = K if K.ndim == 3 else np.repeat(K[None], T.shape[0], axis=0)
    kind, L = _kind(spec)
    stage, terminal = np.zeros(steps), 0.0
    patterns = list(itertools.product([0, 1], repeat=m))
    for states in itertools.product(range(T.shape[0]), repeat=steps):
        p_states = start[states[0]] * np.prod([T[a, b] for a, b in itertools.pairwise(states)])
        if p_states == 0.0:
            continue
        for path in itertools.product(patterns, repeat=steps):
            prob = p_states * np.prod([h[c, i] if v[i] else 1 - h[c, i] for c, v in zip(states, path, strict=True)
                                       for i in range(m)])
            if prob == 0.0:
                continue
            X = system.x0[:, None].copy()
            held = np.zeros((m, 1))                      # hold: the last applied input, per column
            plans = [None] * m                           # buffer: (L, columns) per actuator
            played = [0] * m                             # entries of the plan played so far
            for t, (c, v) in enumerate(zip(states, path, strict=True)):
                u = -Kc[c] @ X
                applied = np.zeros_like(u)
                for i in range(m):
                    if kind == "zero":
                        applied[i] = u[i] if v[i] else 0.0
                    elif kind == "hold":
                        applied[i] = u[i] if v[i] else held[i]
                    else:
                        if v[i]:
                            Acl = A - B @ Kc[c]
                            plans[i] = np.array([-Kc[c][i] @ np.linalg.matrix_power(Acl, j) @ X for j in range(L)])
                            played[i] = 0
                        else:
                            played[i] += 1
                        ok = plans[i] is not None and played[i] < L
                        applied[i] = plans[i][played[i]] if ok else (held[i] if _holds_when_exhausted(spec) else 0.0)
                held = applied
                stage[t] += prob * (np.sum(X * (Omega @ X)) + np.sum(psi[:, None] * applied ** 2))
                X = A @ X + B @ applied
                X = np.hstack([X, root])                 # this step's noise, new columns
                held = np.hstack([held, np.zeros((m, root.shape[1]))])
                plans = [None if P is None else np.hstack([P, np.zeros((L, root.shape[1]))]) for P in plans]
            terminal += prob * np.sum(X * (Omega @ X))
    return stage, terminal


def sampled_costs(system: System, K: np.ndarray, steps: int, spec: str, runs: int,
                  seed: int) -> tuple[float, float]:
    """Mean and standard error of the total cost (stages and terminal) over ``runs`` sampled paths, the actuator's
    logic as in :func:`enumerated_costs`, vectorised over the runs."""
    rng = np.random.default_rng(seed)
    A, B = system.A, system.B
    n, m = B.shape
    Omega, psi = system.state_weights[0], system.input_weights[0]
    T, h, start = _channel(system)
    Kc = K if K.ndim == 3 else np.repeat(K[None], T.shape[0], axis=0)
    kind, L = _kind(spec)
    root = np.linalg.cholesky(system.noise_cov)
    X = np.repeat(system.x0[None], runs, axis=0)
    c = rng.choice(T.shape[0], size=runs, p=start)
    held = np.zeros((runs, m))
    plans = np.zeros((runs, m, L))
    played = np.full((runs, m), L)                     # nothing buffered yet
    powers = np.array([[np.linalg.matrix_power(A - B @ Kc[s], j) for j in range(L)] for s in range(T.shape[0])])
    total = np.zeros(runs)
    for _ in range(steps):
        v = rng.random((runs, m)) < h[c]
        u = -np.einsum("rij,rj->ri", Kc[c], X)
        if kind == "zero":
            applied = np.where(v, u, 0.0)
        elif kind == "hold":
            applied = np.where(v, u, held)
        else:
            plan = -np.einsum("rij,rljk,rk->ril", Kc[c], powers[c], X)
            plans = np.where(v[:, :, None], plan, plans)
            played = np.where(v, 0, played + 1)
            index = np.minimum(played, L - 1)
            entry = np.take_along_axis(plans, index[:, :, None], axis=2)[:, :, 0]
            applied = np.where(played < L, entry, held if _holds_when_exhausted(spec) else 0.0)
        held = applied
        total += np.einsum("ri,ij,rj->r", X, Omega, X) + applied ** 2 @ psi
        X = X @ A.T + applied @ B.T + rng.standard_normal((runs, n)) @ root.T
        c = np.sum(rng.random(runs)[:, None] > np.cumsum(T[c], axis=1)[:, :-1], axis=1)     # the next state
    total += np.einsum("ri,ij,rj->r", X, Omega, X)
    return float(total.mean()), float(total.std(ddof=1) / np.sqrt(runs))


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(np.max(np.abs(b)), np.finfo(float).tiny))


CHANNELS = {
    "bernoulli-1": dict(m=1),
    "bernoulli-2": dict(m=2, mu=[0.6, 0.8]),
    "gilbert-1": dict(m=1, channel=GilbertElliott(p=[0.2], r=[0.5], h_bad=[0.1], h_good=[0.9], belief=[0.7])),
    "kstate-1": dict(m=1, channel=MarkovChannel(transition=[[[0.7, 0.2, 0.1], [0.3, 0.4, 0.3], [0.2, 0.2, 0.6]]],
                                                delivery=[[0.95, 0.5, 0.05]])),
}


@pytest.mark.parametrize("spec", STRATEGIES)
@pytest.mark.parametrize("name", list(CHANNELS))
def test_costs_match_every_delivery_path(name: str, spec: str) -> None:
    """The engine's exact costs against the enumeration of every path (noise included), 3 to 4 steps."""
    system = _system(**CHANNELS[name])
    m = system.m
    steps = 3 if (m == 2 or system.channel is not None) else 4
    K = _gain(m)
    stage, terminal = actuator_costs(system, K, steps, spec)
    ref_stage, ref_terminal = enumerated_costs(system, K, steps, spec)
    assert _relative(stage, ref_stage) <= ACTUATOR_EXACT_RTOL
    assert abs(terminal - ref_terminal) <= ACTUATOR_EXACT_RTOL * abs(ref_terminal)


@pytest.mark.parametrize("spec", ["buffer:2:hold", "buffer:3:hold", "buffer:5:hold"])
@pytest.mark.parametrize("name", list(CHANNELS))
def test_a_buffer_that_holds_once_exhausted_matches_every_delivery_path(name: str, spec: str) -> None:
    """buffer:L:hold's exact costs against the enumeration (the last applied input played beyond the plan), 3 to
    4 steps: long enough to exhaust buffer:2's plan."""
    system = _system(**CHANNELS[name])
    steps = 3 if (system.m == 2 or system.channel is not None) else 4
    K = _gain(system.m)
    stage, terminal = actuator_costs(system, K, steps, spec)
    ref_stage, ref_terminal = enumerated_costs(system, K, steps, spec)
    assert _relative(np.append(stage, terminal), np.append(ref_stage, ref_terminal)) <= ACTUATOR_EXACT_RTOL
    zero_stage, _ = actuator_costs(system, K, steps, spec.removesuffix(":hold"))
    if spec == "buffer:2:hold":                          # exhausted within the horizon: the two options differ
        assert _relative(stage, zero_stage) > 1e-6


@pytest.mark.parametrize("name", ["gilbert-1", "bernoulli-2"])
def test_a_buffer_that_holds_once_exhausted_matches_sampling(name: str) -> None:
    """40 steps: buffer:6:hold's exact total cost within SAMPLED_Z_MAX standard errors of 20,000 sampled runs (the
    plan's predicted state: one gain, n < L - 1)."""
    system = _system(**CHANNELS[name], horizon=40)
    K = _gain(system.m)
    stage, terminal = actuator_costs(system, K, 40, "buffer:6:hold")
    mean, stderr = sampled_costs(system, K, 40, "buffer:6:hold", 20000, seed=41)
    assert abs(mean - (stage.sum() + terminal)) <= SAMPLED_Z_MAX * stderr


def test_a_buffer_that_holds_once_exhausted_keeps_either_memory_alike() -> None:
    """The plan's predicted state (one gain) and its L - 1 entries (a gain one ulp apart): same radius and costs."""
    system = _system(**CHANNELS["gilbert-1"])
    M = actuator_loop(system.A, system.B, _gain(1), system.channel, "zero").T.shape[0]
    K = np.repeat(_gain(1)[None], M, axis=0)
    K_ulp = K.copy()
    K_ulp[-1] = np.nextafter(K_ulp[-1], np.inf)
    short, long = (actuator_loop(system.A, system.B, G, system.channel, "buffer:6:hold") for G in (K, K_ulp))
    assert (short.A.shape[-1], long.A.shape[-1]) == (2 + 2, 2 + 5)
    assert abs(short.radius() - long.radius()) <= ACTUATOR_EXACT_RTOL * long.radius()
    weights = (system.state_weights[0], system.input_weights[0], system.noise_cov, system.x0, 12)
    costs = [np.append(*loop.stage_costs(*weights)) for loop in (short, long)]
    assert _relative(costs[0], costs[1]) <= ACTUATOR_EXACT_RTOL


def test_mode_gains_match_every_delivery_path() -> None:
    """A law per channel state behind a Gilbert channel: the plan and the input follow the state at sending."""
    system = _system(**CHANNELS["gilbert-1"])
    K = np.array([[[0.4, 0.9]], [[0.1, 1.3]]])
    for spec in ("hold", "buffer:3", "buffer:5"):      # per-state gains: the buffer keeps its entries
        stage, terminal = actuator_costs(system, K, 3, spec)
        ref_stage, ref_terminal = enumerated_costs(system, K, 3, spec)
        assert _relative(np.append(stage, terminal), np.append(ref_stage, ref_terminal)) <= ACTUATOR_EXACT_RTOL


@pytest.mark.parametrize(("name", "spec"), [("bernoulli-1", "hold"), ("bernoulli-2", "buffer:3"),
                                            ("gilbert-1", "buffer:4"), ("gilbert-1", "hold")])
def test_long_horizon_costs_match_sampling(name: str, spec: str) -> None:
    """40 steps (beyond enumeration): the exact total cost within SAMPLED_Z_MAX standard errors of 20,000 runs."""
    system = _system(**CHANNELS[name], horizon=40)
    K = _gain(system.m)
    stage, terminal = actuator_costs(system, K, 40, spec)
    mean, stderr = sampled_costs(system, K, 40, spec, 20000, seed=37)
    assert abs(mean - (stage.sum() + terminal)) <= SAMPLED_Z_MAX * stderr


@pytest.mark.parametrize("name", list(CHANNELS))
def test_zero_is_todays_loop(name: str) -> None:
    """"zero" is today's loop: radius and costs of closedloop.stability / moments (Bernoulli) and mjls (chains)."""
    system = _system(**CHANNELS[name])
    K = _gain(system.m)
    radius = actuator_radius(system, K, "zero")
    stage, terminal = actuator_costs(system, K, 12, "zero")
    if system.channel is None:
        today = mean_square_radius(system.A, system.B, K, system.mu_schedule[0])
        assert abs(closed_loop(system, K).spectral_radius - today) <= ACTUATOR_ZERO_RTOL * today
        ref_stage, ref_terminal = finite_horizon_costs(system, K, 12)
        assert abs(terminal - ref_terminal) <= ACTUATOR_ZERO_RTOL * ref_terminal
    else:
        today = chain_radius(system.A, system.B, system.channel, K)
        ref_stage = jump_law_stage_costs(system, np.broadcast_to(K, (len(mode_start(system.channel)), *K.shape)), 12)
    assert abs(radius - today) <= ACTUATOR_ZERO_RTOL * today
    assert _relative(stage, ref_stage) <= ACTUATOR_ZERO_RTOL


@pytest.mark.parametrize("name", list(CHANNELS))
def test_buffer_of_one_is_zero(name: str) -> None:
    """A plan of one entry is the current input only: buffer:1 (delivery patterns as modes) is zero (random V)."""
    system = _system(**CHANNELS[name])
    K = _gain(system.m)
    zero, one = actuator_radius(system, K, "zero"), actuator_radius(system, K, "buffer:1")
    assert abs(one - zero) <= ACTUATOR_EXACT_RTOL * zero
    assert _relative(actuator_costs(system, K, 8, "buffer:1")[0], actuator_costs(system, K, 8, "zero")[0]) \
        <= ACTUATOR_EXACT_RTOL


def test_a_held_input_behind_a_dead_link_is_marginal() -> None:
    """mu = 0: hold's z+ = [[a, b], [0, 1]] z for ever, second-moment eigenvalues the products of 0.5 and 1: the radius
    is 1 (not proved stable), while zero and the buffer (emptied once exhausted) give a^2 = 1/4."""
    s = System(A=[[0.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.0], x0=[1.0])
    assert abs(actuator_radius(s, [[0.3]], "hold") - 1.0) <= ACTUATOR_EXACT_RTOL
    for spec in ("zero", "buffer:3"):
        assert abs(actuator_radius(s, [[0.3]], spec) - 0.25) <= ACTUATOR_EXACT_RTOL * 0.25


def test_every_strategy_is_the_nominal_loop_without_losses() -> None:
    """mu = 1: nothing is lost, so every strategy's radius is rho(A - B K)^2 (the augmented memory decays)."""
    system = _system(mu=[1.0])
    K = _gain(1)
    nominal = max(abs(np.linalg.eigvals(system.A - system.B @ K))) ** 2
    for spec in STRATEGIES:
        assert abs(actuator_radius(system, K, spec) - nominal) <= ACTUATOR_EXACT_RTOL * nominal


@pytest.mark.parametrize("L", [5, 8, 20])
@pytest.mark.parametrize("name", ["gilbert-1", "kstate-1"])
def test_the_buffers_two_memories_agree(name: str, L: int) -> None:
    """One gain for every channel state: the buffer keeps the plan's predicted state (n entries); a gain that differs
    in one state by one ulp makes it keep the L - 1 entries instead. Same radius and costs, two state spaces."""
    system = _system(**CHANNELS[name])
    T = actuator_loop(system.A, system.B, _gain(1), system.channel, "zero").T
    K = np.repeat(_gain(1)[None], T.shape[0], axis=0)
    K_ulp = K.copy()
    K_ulp[-1] = np.nextafter(K_ulp[-1], np.inf)
    short = actuator_loop(system.A, system.B, K, system.channel, f"buffer:{L}")
    long = actuator_loop(system.A, system.B, K_ulp, system.channel, f"buffer:{L}")
    assert (short.A.shape[-1], long.A.shape[-1]) == (2 + 2, 2 + L - 1)
    assert abs(short.radius() - long.radius()) <= ACTUATOR_EXACT_RTOL * long.radius()
    weights = (system.state_weights[0], system.input_weights[0], system.noise_cov, system.x0, 12)
    costs = [np.append(*loop.stage_costs(*weights)) for loop in (short, long)]
    assert _relative(costs[0], costs[1]) <= ACTUATOR_EXACT_RTOL


@pytest.mark.parametrize("spec", ["hold", "buffer:2", "buffer:3"])
def test_krylov_radius_matches_the_dense_one(spec: str) -> None:
    """Beyond 400 rows the engine's radius is ARPACK's on the map (buffer:3 of two actuators: 16 modes of 6^2):
    the dense eigenvalues of the same map agree."""
    system = _system(m=2, mu=[0.9, 0.5])
    loop = actuator_loop(system.A, system.B, _gain(2), system.mu_schedule[0], spec)
    dense, krylov = loop.radius("dense"), loop.radius("krylov")
    assert abs(krylov - dense) <= ACTUATOR_EXACT_RTOL * dense


# ---------------------------------------------------------------- the scalar plant by hand
#
# x+ = a x + b a_k, u = -k x, deliveries Bernoulli(mu), g = a - b k. After a delivery at k0 the state until the next
# delivery, tau steps later (P(tau = j) = mu (1 - mu)^(j - 1)), is phi(j) x_k0, and at delivery times E[x^2]
# multiplies by R = E[phi(tau)^2] (a renewal: the actuator's memory is reset by each delivery); the loop is
# mean-square stable iff R < 1 (the series converging needs (1 - mu) a^2 < 1). With G(r) = mu r / (1 - (1 - mu) r):
#   zero:      phi(j) = g a^(j - 1),                       R = g^2 G(a^2) / a^2
#   hold:      phi(j) = a^j - b k (a^j - 1) / (a - 1)      R = al^2 G(a^2) + 2 al be G(a) + be^2 G(1)
#              (al = 1 - b k / (a - 1), be = b k / (a - 1); the held -k x_k0 summed over j steps)
#   buffer:L:  phi(j) = g^j for j <= L (the plan is the nominal path), g^L a^(j - L) beyond:
#              R = mu g^2 sum_{j < L} ((1 - mu) g^2)^j + mu g^(2L) (1 - mu)^L a^2 / (1 - (1 - mu) a^2)
# (Schenato 2009 compares zero and hold this way.) The engine's radius is 1 exactly where R = 1: the critical mu.

def _renewal(spec: str, a: float, b: float, k: float, mu: float) -> float:
    g, q = a - b * k, 1.0 - mu
    G = lambda r: mu * r / (1.0 - q * r)                                   # noqa: E731
    kind, L = _kind(spec)
    if kind == "zero":
        return g * g * G(a * a) / (a * a)
    if kind == "hold":
        al, be = 1.0 - b * k / (a - 1.0), b * k / (a - 1.0)
        return al * al * G(a * a) + 2 * al * be * G(a) + be * be * G(1.0)
    return (mu * g * g * sum((q * g * g) ** j for j in range(L))
            + mu * g ** (2 * L) * q ** L * a * a / (1.0 - q * a * a))


@pytest.mark.parametrize(("a", "b", "k"), [(1.5, 1.0, 1.2), (1.3, 0.5, 3.0), (2.0, 1.0, 1.6)])
@pytest.mark.parametrize("spec", ["zero", "hold", "buffer:2", "buffer:4"])
def test_scalar_critical_mu_matches_the_renewal_closed_form(spec: str, a: float, b: float, k: float) -> None:
    """The engine's radius crosses 1 at the mu where the hand closed form's R crosses 1."""
    def system(mu: float) -> System:
        return System(A=[[a]], B=[[b]], horizon=6, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])

    low = 1.0 - 1.0 / (a * a) + 1e-9                                       # below: the series diverges
    hand = brentq(lambda mu: _renewal(spec, a, b, k, mu) - 1.0, low, 1.0 - 1e-12, xtol=1e-14)
    engine = brentq(lambda mu: actuator_radius(system(mu), [[k]], spec) - 1.0, low, 1.0 - 1e-12, xtol=1e-14)
    assert abs(engine - hand) <= ACTUATOR_CRITICAL_MU_ATOL


def _hold_matrix(a: float, b: float, k: float, mu: float) -> np.ndarray:
    """Hold's moments (S, C, W) = E[x^2], E[x w], E[w^2] (w the held input), by hand: the applied input is
    ``-k x`` with probability mu, else w, so E[x a] = -mu k S + (1 - mu) C, E[a^2] = mu k^2 S + (1 - mu) W, and
    ``x+ = a x + b a_k``, ``w+ = a_k``."""
    q = 1.0 - mu
    return np.array([[a * a - 2 * a * b * mu * k + b * b * mu * k * k, 2 * a * b * q, b * b * q],
                     [-a * mu * k + b * mu * k * k, a * q, b * q],
                     [mu * k * k, 0.0, q]])


def _buffer_matrix(a: float, b: float, k: float, mu: float, L: int) -> np.ndarray:
    """buffer:L's moments ``E[x^2 1{c}]`` by hand, c the losses since the last delivery (capped at L - 1): without
    noise a buffered entry is ``-k`` times the state the plan predicted, which is the state, so the step is
    ``x+ = g x`` (g = a - b k) when delivered or while an entry is left (c <= L - 2), else ``x+ = a x``."""
    g2, q = (a - b * k) ** 2, 1.0 - mu
    Mx = np.zeros((L, L))
    for c in range(L):
        Mx[0, c] += mu * g2
        Mx[min(c + 1, L - 1), c] += q * (g2 if c <= L - 2 else a * a)
    return Mx


@pytest.mark.parametrize(("a", "b", "k", "mu"), [(0.9, 1.0, 0.8, 0.5), (1.2, 0.5, 2.0, 0.6), (1.5, 1.0, 0.6, 0.8),
                                                (0.5, 1.0, 2.0, 0.1)])
def test_scalar_radius_matches_the_hand_moments(a: float, b: float, k: float, mu: float) -> None:
    """The engine's radius of hold and buffer:L against the hand moment recursions' spectral radii, among them a
    point where the loop contracts faster than a loss repeats (radius below 1 - mu) and one whose nominal loop
    a - b k = -1.5 is unstable ((1 - mu) g^2 = 2.03 above the radii 1.27 and 1.70 of buffer:3 and :5): a plan
    counted as state after it is exhausted would show at either."""
    s = System(A=[[a]], B=[[b]], horizon=6, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    hand = max(abs(np.linalg.eigvals(_hold_matrix(a, b, k, mu))))
    assert abs(actuator_radius(s, [[k]], "hold") - hand) <= ACTUATOR_EXACT_RTOL * hand
    for L in (2, 3, 5):
        hand = max(abs(np.linalg.eigvals(_buffer_matrix(a, b, k, mu, L))))
        assert abs(actuator_radius(s, [[k]], f"buffer:{L}") - hand) <= ACTUATOR_EXACT_RTOL * hand


def test_neither_zero_nor_hold_dominates() -> None:
    """Schenato 2009: which strategy stabilises depends on the plant and the law. A slow law (a = 1.5, k = 0.6,
    mu = 0.8) is stabilised by holding and not by zeroing (hand R: 0.748 and 1.178); a near-deadbeat one (a = 1.2,
    k = 1.3, mu = 0.5) the other way round (12.8 and 0.018). The engine's radii say the same."""
    cases = [(1.5, 0.6, 0.8, "hold"), (1.2, 1.3, 0.5, "zero")]
    for a, k, mu, winner in cases:
        loser = "zero" if winner == "hold" else "hold"
        assert _renewal(winner, a, 1.0, k, mu) < 1.0 < _renewal(loser, a, 1.0, k, mu)
        s = System(A=[[a]], B=[[1.0]], horizon=6, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
        assert actuator_radius(s, [[k]], winner) < 1.0 < actuator_radius(s, [[k]], loser)


# ---------------------------------------------------------------- bad input

@pytest.mark.parametrize("spec", ["drop", "buffer:0", "buffer:-1", "buffer:x", "hold:2", "buffer:7", "", 3])
def test_bad_strategies_are_refused_in_one_line(spec: object) -> None:
    system = _system()
    with pytest.raises(InputError, match=r"^actuator: expected zero, hold or buffer:L with an integer 1 <= L "
                                         r"<= 6 \(the horizon\), found") as err:
        actuator_radius(system, _gain(1), spec)
    assert err.value.field == "actuator"
    assert "\n" not in str(err.value)


def test_buffer_beyond_the_mode_bound_is_refused() -> None:
    system = _system(m=2, horizon=40)
    with pytest.raises(InputError, match=rf"^actuator: buffer:40 .* 1681 modes; expected at most {MAX_BUFFER_MODES}"):
        actuator_costs(system, _gain(2), 5, "buffer:40")


def test_buffer_without_length_is_the_horizon() -> None:
    assert str(parse_actuator("buffer", horizon=6)) == "buffer:6"


def test_buffer_modes_form_a_chain() -> None:
    """buffer:3 behind two Gilbert channels: 2^2 joint states * 4^2 ages = 64 modes, state 2 + 2 * 2; the rows of T
    and the start are distributions."""
    channel = GilbertElliott(p=[0.2, 0.1], r=[0.5, 0.3], h_bad=[0.1, 0.2], h_good=[0.9, 0.8], belief=[0.7, 0.4])
    loop = actuator_loop(np.eye(2), np.eye(2), np.eye(2), channel, "buffer:3")
    assert loop.A.shape == (64, 6, 6)
    assert np.max(np.abs(loop.T.sum(axis=1) - 1.0)) <= ROW_SUM_ATOL
    assert abs(loop.start.sum() - 1.0) <= ROW_SUM_ATOL


# ---------------------------------------------------------------- the command line

def test_solve_prints_every_strategy_per_law(capsys) -> None:
    """``solve --actuator``: per protocol each strategy; "zero" is the loop solve already reports."""
    from packetloss_cvx.cli import main
    from packetloss_cvx.model.files import load_example

    from ..conftest import EXAMPLES

    code = main(["solve", str(EXAMPLES / "two_actuator.toml"), "--no-qp", "--actuator", "zero,hold,buffer:3", "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert err == ""
    data = json.loads(out)
    system = load_example("two_actuator")
    for protocol in ("tcp", "udp"):
        entry = data[protocol]["actuator"]
        assert entry["steps"] == system.horizon
        assert list(entry["strategies"]) == ["zero", "hold", "buffer:3"]
        zero = entry["strategies"]["zero"]["radius"]
        assert abs(zero - data[protocol]["mean_square_spectral_radius"]) <= ACTUATOR_ZERO_RTOL * zero
        gain = np.array(data[protocol]["gain"])
        stage, terminal = actuator_costs(system, gain, system.horizon, "hold")
        assert entry["strategies"]["hold"]["cost"] == stage.sum() + terminal


@pytest.mark.parametrize("spec", ["buffer:0", "buffer:11", "drop", "hold,buffer:x"])
def test_solve_refuses_a_bad_strategy_in_one_line(capsys, spec: str) -> None:
    from packetloss_cvx.cli import main

    from ..conftest import EXAMPLES

    code = main(["solve", str(EXAMPLES / "two_actuator.toml"), "--no-qp", "--actuator", spec])
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    assert err.splitlines() == [err.strip()]
    assert err.startswith("packetloss-cvx: error: --actuator: expected zero, hold or buffer:L with an integer "
                          "1 <= L <= 10 (the horizon), found")


def test_solve_compares_the_three_in_text(capsys, tmp_path) -> None:
    """``--actuator all`` on a scalar plant: one line per strategy, each verdict the hand renewal closed form's
    (R < 1) for the law solve prints (k = 0.646: R = 1.06 zeroing, 0.654 holding, 0.691 with the plan)."""
    from packetloss_cvx.cli import main
    from packetloss_cvx.lq.costs import closed_form
    from packetloss_cvx.model.files import save_system

    s = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[8.0], mu=[0.8], x0=[1.0])
    path = save_system(s, tmp_path / "scalar.toml")
    code = main(["solve", str(path), "--no-qp", "--protocol", "udp", "--actuator", "all"])
    out, _ = capsys.readouterr()
    assert code == 0
    k = float(closed_form(s, "udp").gain[0, 0])
    lines = {line.split(":")[0].strip(): line for line in out.splitlines() if "exact loop cost over 3 steps" in line}
    assert list(lines) == ["zero", "hold", "buffer"]
    for name, spec in (("zero", "zero"), ("hold", "hold"), ("buffer", "buffer:3")):
        stable = _renewal(spec, 1.5, 1.0, k, 0.8) < 1.0
        assert ("NOT mean-square stable" not in lines[name]) == stable, (spec, k, lines[name])


def test_simulate_samples_each_strategy_beside_its_exact_cost(capsys, tmp_path) -> None:
    """``simulate --closed-loop --actuator all``: the package's sampler within SAMPLED_Z_MAX standard errors of the
    exact mean stage cost, for each strategy, on a noisy two-state plant (the sampler is seeded)."""
    from packetloss_cvx.cli import main
    from packetloss_cvx.model.files import save_system

    system = _system(m=2, mu=[0.8, 0.6], horizon=4)
    path = save_system(system, tmp_path / "plant.toml")
    code = main(["simulate", str(path), "--closed-loop", "--law", "udp", "--actuator", "all", "--samples", "20000",
                 "--steps", "25", "--seed", "3", "--json"])
    out, _ = capsys.readouterr()
    assert code == 0
    rows = json.loads(out)["actuator"]["udp"]
    assert list(rows) == ["zero", "hold", "buffer:4"]
    for row in (rows["zero"], rows["buffer:4"]):
        assert abs(row["mean_stage_cost"] - row["exact_stage_cost"]) <= SAMPLED_Z_MAX * row["stderr"]
    assert all(row["stable"] for row in rows.values())
    # hold is mean-square stable but its fourth moments grow: no error bar. rho_4 by hand from the hold loop's
    # matrices per delivery pattern v, z = (x, w): x+ = A x + B a, w+ = a with a = V (-K x) + (I - V) w
    from packetloss_cvx.montecarlo.simulate import law_gains
    K = law_gains(system, ("udp",))["udp"]
    n, m, mu = 2, 2, np.array([0.8, 0.6])
    L4 = np.zeros(((n + m) ** 4,) * 2)
    for v in itertools.product([0.0, 1.0], repeat=m):
        V = np.diag(v)
        applied = np.hstack([-V @ K, np.eye(m) - V])
        F = np.vstack([np.hstack([system.A, np.zeros((n, m))]) + system.B @ applied, applied])
        F2 = np.kron(F, F)
        L4 += np.prod(np.where(np.array(v) == 1.0, mu, 1.0 - mu)) * np.kron(F2, F2)
    rho4 = float(np.abs(np.linalg.eigvals(L4)).max())
    assert rho4 >= 1.0
    assert rows["hold"]["stderr"] is None
    assert rows["hold"]["z"] is None
    assert f"rho_4 = {rho4:.4g} >= 1" in rows["hold"]["stderr_reason"]


@pytest.mark.parametrize(("extra", "message"), [
    ([], "--actuator: the actuator's strategy acts in the closed loop: add --closed-loop"),
    (["--closed-loop", "--actuator", "buffer:0"], "--actuator: expected zero, hold or buffer:L"),
])
def test_simulate_refuses_in_one_line(capsys, extra: list[str], message: str) -> None:
    from packetloss_cvx.cli import main

    from ..conftest import EXAMPLES

    argv = ["simulate", str(EXAMPLES / "two_actuator.toml"), "--samples", "10", *(extra or ["--actuator", "hold"])]
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    assert len(err.splitlines()) == 1
    assert err.startswith(f"packetloss-cvx: error: {message}")


def test_simulate_refuses_a_chain(capsys, tmp_path) -> None:
    """Behind a Markov channel simulate's laws read the belief: refused, pointing at solve --actuator."""
    from packetloss_cvx.cli import main
    from packetloss_cvx.model.files import save_system

    path = save_system(_system(**CHANNELS["gilbert-1"]), tmp_path / "chain.toml")
    code = main(["simulate", str(path), "--closed-loop", "--actuator", "hold", "--samples", "10"])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.startswith("packetloss-cvx: error: --actuator: behind a Markov channel")
