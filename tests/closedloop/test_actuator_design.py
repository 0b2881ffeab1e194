"""closedloop.actuator_design: the optimal TCP-like linear law per actuator strategy.

References, none of them the coupled Riccati equation over the strategy's modes: (a) every delivery path of a short
horizon, the actuator's firmware written out per path, the controller's input a free vector per delivery history,
the expected cost minimised by one least-squares solve; (b) the channel's own DP (closedloop.riccati.dp_riccati,
mjls.coupled_riccati: the expectation over the deliveries in closed form) for zero; (c) hand values on the scalar
plant; (d) a seeded simulation of the firmware under the designed law, against the engine's exact cost.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from packetloss_cvx.closedloop.actuator import actuator_costs, parse_actuator
from packetloss_cvx.closedloop.actuator_design import actuator_dp, actuator_dp_finite, design_modes
from packetloss_cvx.closedloop.mjls import coupled_riccati
from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import ACTUATOR_DP_RTOL, SAMPLED_Z_MAX


def _system(m: int = 1, mu=None, noise: bool = False, horizon: int = 6, channel=None) -> System:
    """A 2-state plant, unstable open loop, one or two actuators (as tests/closedloop/test_actuator.py)."""
    B = [[0.2], [1.0]] if m == 1 else [[0.2, 1.0], [1.0, 0.0]]
    return System(A=[[1.1, 0.4], [-0.3, 0.8]], B=B, horizon=horizon, state_weight=[1.0, 2.0],
                  input_weight=[0.5] * m, x0=[1.0, -0.7], noise_cov=[[0.05, 0.01], [0.01, 0.1]] if noise else None,
                  mu=None if channel is not None else (mu if mu is not None else [0.7] * m), channel=channel)


def _enumerated_optimum(system: System, steps: int, actuator: str) -> float:
    """min over the inputs of the expected cost of ``steps`` steps from x0 (no noise), the controller's packet a
    free vector per delivery history (TCP-like: it knows every earlier delivery), the actuator's firmware run on
    every delivery path. Every quantity is affine in the stacked decisions theta: a row of coefficients and a
    constant (last column). Time O(2^(m steps) ...): short horizons only."""
    strategy = parse_actuator(actuator, system.horizon)
    A, B, x0 = system.A, system.B, system.x0
    n, m = B.shape
    L = strategy.length if strategy.kind == "buffer" else 1
    Omega, psi, mu = system.state_weights[0], system.input_weights[0], system.mu_schedule[0]
    patterns = list(itertools.product((0, 1), repeat=m))
    nodes = {h: k for k, h in enumerate(h for t in range(steps) for h in itertools.product(patterns, repeat=t))}
    width = len(nodes) * m * L + 1                                     # the decisions and the constant 1
    Hq, g, c0 = np.zeros((width - 1, width - 1)), np.zeros(width - 1), 0.0

    def packet(history: tuple, i: int) -> np.ndarray:                # actuator i's L entries: (L, width) rows
        rows = np.zeros((L, width))
        start = (nodes[history] * m + i) * L
        rows[:, start:start + L] = np.eye(L)
        return rows

    for path in itertools.product(patterns, repeat=steps):
        prob = np.prod([mu[i] if d[i] else 1.0 - mu[i] for d in path for i in range(m)])
        x = np.zeros((n, width))
        x[:, -1] = x0
        held = [np.zeros(width) for _ in range(m)]
        plan = [None] * m
        age = [0] * m
        quad = np.zeros((width, width))
        for t, d in enumerate(path):
            applied = []
            for i in range(m):
                U = packet(path[:t], i)
                if d[i]:
                    plan[i], age[i] = U, 0
                    a = U[0]
                elif strategy.kind == "zero":
                    a = np.zeros(width)
                elif strategy.kind == "hold":
                    a = held[i]
                else:
                    age[i] += 1
                    a = plan[i][age[i]] if plan[i] is not None and age[i] < L else \
                        (held[i] if strategy.exhausted == "hold" else np.zeros(width))
                held[i] = a
                applied.append(a)
            a = np.array(applied)
            quad += x.T @ Omega @ x + (a.T * psi) @ a
            x = A @ x + B @ a
        quad += x.T @ Omega @ x
        Hq += prob * quad[:-1, :-1]
        g += prob * quad[:-1, -1]
        c0 += prob * quad[-1, -1]
    theta = np.linalg.lstsq(Hq, -g, rcond=None)[0]
    return float(c0 + g @ theta)


@pytest.mark.parametrize(("m", "actuator", "steps"), [
    (1, "zero", 4), (1, "hold", 4), (1, "buffer:2", 4), (1, "buffer:3", 4), (1, "buffer:4", 4),
    (1, "buffer:2:hold", 4), (1, "buffer:3:hold", 4),
    (2, "zero", 3), (2, "hold", 3), (2, "buffer:2", 3), (2, "buffer:3", 3), (2, "buffer:2:hold", 3)])
def test_finite_horizon_optimum_is_the_enumerated_optimum_over_delivery_paths(m, actuator, steps):
    """The coupled Riccati recursion's optimal cost from x0 is the least expected cost over every causal input
    sequence (a free input per delivery history), the firmware written out per path."""
    system = _system(m, mu=[0.7, 0.4][:m])
    _, cost = actuator_dp_finite(system, steps, actuator)
    assert cost == pytest.approx(_enumerated_optimum(system, steps, actuator), rel=ACTUATOR_DP_RTOL)


def test_hold_and_buffer_designs_beat_the_zero_optimum_played_by_their_firmware():
    """The strategy's own optimum is no worse than the zero-optimal gain run with the strategy's firmware (exact
    costs of a given law, closedloop.actuator.actuator_costs), and strictly better here."""
    system = _system(2, mu=[0.6, 0.5])
    steps = 8
    gains_zero, _ = actuator_dp_finite(system, steps, "zero")
    stationary_zero = dp_riccati(system).gain
    for actuator in ("hold", "buffer:3"):
        _, best = actuator_dp_finite(system, steps, actuator)
        stage, terminal = actuator_costs(system, stationary_zero, steps, actuator)
        assert best < stage.sum() + terminal
    _, zero_best = actuator_dp_finite(system, steps, "zero")
    assert zero_best == pytest.approx(float(system.x0 @ _zero_finite_P(system, steps) @ system.x0),
                                      rel=ACTUATOR_DP_RTOL)
    assert gains_zero.shape == (steps, 1, 2, 2)


def _zero_finite_P(system: System, steps: int) -> np.ndarray:
    from packetloss_cvx.closedloop.riccati import dp_finite_horizon

    return dp_finite_horizon(system, steps)[1]


@pytest.mark.parametrize("mu", [[0.9, 0.5], [0.3, 1.0], [0.0, 0.8]])
def test_zero_is_the_modified_riccati_equation(mu):
    """zero's equation, the expectation over the 2^m delivery patterns written out, is the modified Riccati
    equation with the expectation in closed form (dp_riccati): the same P, and the same gain on every actuator
    that can deliver."""
    system = _system(2, mu=mu)
    design, reference = actuator_dp(system, "zero"), dp_riccati(system)
    assert np.allclose(design.P[0], reference.cost_to_go, rtol=ACTUATOR_DP_RTOL, atol=0.0)
    delivering = np.asarray(mu) > 0
    assert np.allclose(design.K[0][delivering], reference.gain[delivering], rtol=ACTUATOR_DP_RTOL,
                       atol=ACTUATOR_DP_RTOL * np.abs(reference.gain).max())
    assert design.radius == pytest.approx(reference.spectral_radius, rel=ACTUATOR_DP_RTOL)


def test_zero_behind_a_chain_is_the_coupled_riccati_equation_of_the_chain():
    channel = GilbertElliott(p=[0.2, 0.1], r=[0.5, 0.3], h_good=[0.95, 0.9], h_bad=[0.2, 0.3])
    system = _system(2, channel=channel)
    design, reference = actuator_dp(system, "zero"), coupled_riccati(system)
    assert np.allclose(design.P, reference.cost_matrices, rtol=ACTUATOR_DP_RTOL, atol=0.0)
    assert np.allclose(design.K, reference.gains, rtol=ACTUATOR_DP_RTOL, atol=ACTUATOR_DP_RTOL)


def test_buffer_one_is_zero():
    system = _system(2, mu=[0.6, 0.8], noise=True)
    one, zero = actuator_dp(system, "buffer:1"), actuator_dp(system, "zero")
    assert np.allclose(one.P, zero.P, rtol=ACTUATOR_DP_RTOL, atol=0.0)
    assert one.cost == pytest.approx(zero.cost, rel=ACTUATOR_DP_RTOL)


def test_scalar_hold_without_dynamics_by_hand():
    """x+ = applied input (A = 0), cost x^2 + a^2: the value is x^2 + c w^2 with c = (1 - mu)(2 + c) (a held w
    costs w^2 now and w^2 in the state next, and is held again), so c = 2 (1 - mu) / mu and the optimal input 0."""
    mu = 0.4
    system = System(A=[[0.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    design = actuator_dp(system, "hold")
    assert np.allclose(design.P[0], np.diag([1.0, 2 * (1 - mu) / mu]), rtol=ACTUATOR_DP_RTOL, atol=1e-15)
    assert np.allclose(design.K[0], 0.0, atol=1e-15)


@pytest.mark.parametrize(("actuator", "c_entry", "c_exhausted"), [
    ("buffer:2:hold", lambda mu: 2 * (1 - mu) / mu, lambda mu: 2 * (1 - mu) / mu),
    ("buffer:2", lambda mu: 2 * (1 - mu), lambda mu: 0.0)])
def test_scalar_buffer_without_dynamics_by_hand(actuator, c_entry, c_exhausted):
    """x+ = applied input (A = 0), cost x^2 + a^2, z = (x, b), b the plan's second entry: the optimal packet is 0
    and the value x^2 + c_beta b^2. Exhausted (age 2), buffer:2:hold plays b on a loss and keeps it: c_2 = (1 - mu)
    (2 + c_2) = 2 (1 - mu) / mu, as hold; with an entry left (age 1) a loss plays b and exhausts the plan, kept:
    c_1 = (1 - mu)(2 + c_2) = c_2. buffer:2 zeroes it once played: c_2 = 0, c_1 = 2 (1 - mu)."""
    mu = 0.4
    system = System(A=[[0.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    design = actuator_dp(system, actuator)
    entry, exhausted = design.modes.labels.index("c0 ages (1,)"), design.modes.labels.index("c0 ages (2,)")
    assert np.allclose(design.P[entry], np.diag([1.0, c_entry(mu)]), rtol=ACTUATOR_DP_RTOL, atol=1e-15)
    assert np.allclose(design.P[exhausted], np.diag([1.0, c_exhausted(mu)]), rtol=ACTUATOR_DP_RTOL, atol=1e-15)
    assert np.allclose(design.K, 0.0, atol=1e-15)


@pytest.mark.parametrize("L", [2, 3])
def test_buffer_hold_is_the_buffer_while_no_plan_can_run_out(L):
    """Within L steps no plan is exhausted after a delivery (exhaustion takes a delivery and L - 1 losses after
    it, L + 1 steps in all; before the first packet both play 0), so buffer:L:hold's optimum over L steps is
    buffer:L's; over L + 1 steps the held last entry is played on one path, and the two differ."""
    system = _system(2, mu=[0.6, 0.5], noise=True)
    _, hold = actuator_dp_finite(system, L, f"buffer:{L}:hold")
    _, zero = actuator_dp_finite(system, L, f"buffer:{L}")
    assert hold == pytest.approx(zero, rel=ACTUATOR_DP_RTOL)
    _, hold = actuator_dp_finite(system, L + 1, f"buffer:{L}:hold")
    _, zero = actuator_dp_finite(system, L + 1, f"buffer:{L}")
    assert abs(hold - zero) > 1e3 * ACTUATOR_DP_RTOL * zero


@pytest.mark.parametrize("actuator", ["hold", "buffer:3", "buffer:3:hold"])
def test_information_modes_of_a_static_plan_cost_what_the_firmware_loop_says(actuator):
    """The plan of ``u = -K x`` (entry j: ``-k_i (A - B K)^j x``), written as a law over the information modes,
    costs through DesignModes' loop exactly what closedloop.actuator's own construction of the firmware's loop
    (modes: the plan's age from 0, its memory built from K) gives for the same law."""
    system = _system(2, mu=[0.6, 0.5], noise=True)
    K = dp_riccati(system).gain
    modes = design_modes(system.A, system.B, system.mu_schedule[0], actuator)
    strategy = parse_actuator(actuator)
    L = strategy.length if strategy.kind == "buffer" else 1
    closed = system.A - system.B @ K
    plan = np.stack([K[i] @ np.linalg.matrix_power(closed, j) for i in range(2) for j in range(L)])   # (mL, n)
    gains = np.zeros((modes.modes, *modes.B.shape[-1:], modes.A.shape[-1]))
    gains[:, :, :2] = plan
    steps = 12
    stage, terminal = modes.loop(gains).stage_costs(system.state_weights[0], system.input_weights[0],
                                                    system.noise_cov, system.x0, steps)
    stage_ref, terminal_ref = actuator_costs(system, K, steps, actuator)
    assert np.allclose(stage, stage_ref, rtol=ACTUATOR_DP_RTOL, atol=0.0)
    assert terminal == pytest.approx(terminal_ref, rel=ACTUATOR_DP_RTOL)


def test_scalar_zero_is_the_closed_form_of_the_modified_riccati_equation():
    """a = 2, b = q = r = 1: ``P = 1 + 4P - 4 mu P^2 / (1 + P)``; times (1 + P): ``(4 mu - 3) P^2 - 4P - 1 = 0``,
    its positive root; the gain ``2P / (1 + P)``."""
    mu = 0.9
    system = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    a2, a1, a0 = 4 * mu - 3, -4.0, -1.0
    P = (-a1 + np.sqrt(a1 * a1 - 4 * a2 * a0)) / (2 * a2)
    design = actuator_dp(system, "zero")
    assert design.P[0, 0, 0] == pytest.approx(P, rel=ACTUATOR_DP_RTOL)
    assert design.K[0, 0, 0] == pytest.approx(2 * P / (1 + P), rel=ACTUATOR_DP_RTOL)


@pytest.mark.parametrize("actuator", ["hold", "buffer:3", "buffer:3:hold"])
def test_every_packet_delivered_is_the_dare_on_the_plant(actuator):
    """mu = 1: the held input and the plan's tail are never played; the cost-to-go is the DARE's on x."""
    from scipy.linalg import solve_discrete_are

    system = _system(2, mu=[1.0, 1.0])
    design = actuator_dp(system, actuator)
    dare = solve_discrete_are(system.A, system.B, system.state_weights[0], np.diag(system.input_weights[0]))
    start = int(np.argmax(design.modes.start))
    assert np.allclose(design.P[start][:2, :2], dare, rtol=ACTUATOR_DP_RTOL, atol=0.0)
    assert np.allclose(design.P[start][2:], 0.0, atol=ACTUATOR_DP_RTOL * np.abs(dare).max())


def test_stationary_law_is_the_limit_of_the_finite_horizon_optimum():
    """Without noise the finite-horizon optimum from x0 over many steps approaches the stationary x0'P x0 (from
    below: a terminal weight Omega <= the stationary P)."""
    system = _system(2, mu=[0.7, 0.5])
    for actuator in ("hold", "buffer:2"):
        stationary = actuator_dp(system, actuator).initial
        short = actuator_dp_finite(system, 20, actuator)[1]
        long = actuator_dp_finite(system, 200, actuator)[1]
        assert short <= long * (1 + ACTUATOR_DP_RTOL)
        assert long == pytest.approx(stationary, rel=ACTUATOR_DP_RTOL)


def _simulate(design, system: System, steps: int, samples: int, seed: int) -> np.ndarray:
    """The firmware run under the designed law u = -K_s z (z and s built from the firmware's memory, not from
    DesignModes' arrays): per sample the total cost of ``steps`` steps plus the terminal x'Omega x."""
    rng = np.random.default_rng(seed)
    strategy = design.modes.actuator
    A, B, x0, noise = system.A, system.B, system.x0, system.noise_cov
    n, m = B.shape
    L = strategy.length if strategy.kind == "buffer" else 1
    Omega, psi, mu = system.state_weights[0], system.input_weights[0], system.mu_schedule[0]
    chol = np.linalg.cholesky(noise + 1e-300 * np.eye(n)) if np.any(noise) else np.zeros((n, n))
    ages = list(itertools.product(range(1, L + 1), repeat=m))
    totals = np.empty(samples)
    for k in range(samples):
        x = x0.copy()
        held = np.zeros(m)
        plan = np.zeros((m, L))
        beta = [L] * m
        total = 0.0
        for _ in range(steps):
            if strategy.kind == "zero":
                z, s = x, 0
            elif strategy.kind == "hold":
                z, s = np.concatenate([x, held]), 0
            else:
                z = np.concatenate([x, *[plan[i, 1:] for i in range(m)]])
                s = ages.index(tuple(beta))
            u = -design.K[s] @ z
            d = rng.random(m) < mu
            a = np.empty(m)
            for i in range(m):
                if d[i]:
                    a[i] = u[i * L]
                    plan[i] = u[i * L:(i + 1) * L]
                    beta[i] = 1
                elif strategy.kind == "hold":
                    a[i] = held[i]
                elif strategy.kind == "buffer":
                    a[i] = plan[i, beta[i]] if beta[i] < L else (held[i] if strategy.exhausted == "hold" else 0.0)
                    beta[i] = min(beta[i] + 1, L)
                    if beta[i] == L and strategy.exhausted != "hold":
                        plan[i] = 0.0
                else:
                    a[i] = 0.0
            held = a
            total += x @ Omega @ x + a @ (psi * a)
            x = A @ x + B @ a + chol @ rng.standard_normal(n)
        totals[k] = total + x @ Omega @ x
    return totals


@pytest.mark.parametrize("actuator", ["hold", "buffer:3", "buffer:2:hold"])
def test_designed_law_sampled_through_its_firmware_costs_what_the_engine_says(actuator):
    system = _system(2, mu=[0.6, 0.5], noise=True)
    design = actuator_dp(system, actuator)
    steps = 15
    stage, terminal = design.modes.loop(design.K).stage_costs(system.state_weights[0], system.input_weights[0],
                                                             system.noise_cov, system.x0, steps)
    totals = _simulate(design, system, steps, 4000, seed=7)
    error = totals.std(ddof=1) / np.sqrt(len(totals))
    assert abs(totals.mean() - (stage.sum() + terminal)) < SAMPLED_Z_MAX * error


def test_designed_loop_is_stable_and_its_average_cost_is_the_long_run_mean():
    """The average stage cost ``sum pi tr(E Sigma)`` is the limit of the exact stage costs of the loop."""
    system = _system(2, mu=[0.6, 0.5], noise=True)
    for actuator in ("zero", "hold", "buffer:2"):
        design = actuator_dp(system, actuator)
        assert design.radius < 1
        stage, _ = design.modes.loop(design.K).stage_costs(system.state_weights[0], system.input_weights[0],
                                                          system.noise_cov, system.x0, 400)
        assert stage[-1] == pytest.approx(design.cost, rel=ACTUATOR_DP_RTOL)


@pytest.mark.parametrize("spec", ["buffer:0", "buffer:7", "drop", "buffer:x"])
def test_bad_strategy_is_an_input_error(spec):
    with pytest.raises(InputError, match="actuator"):
        actuator_dp(_system(1), spec)


def test_design_modes_count_and_start():
    modes = design_modes([[1.0]], [[1.0, 0.5]], [0.5, 0.5], "buffer:3")
    assert modes.modes == 9
    assert modes.p.shape == (9, 4)
    assert np.allclose(modes.R.sum(axis=2), 1.0)
    assert modes.labels[int(np.argmax(modes.start))] == "c0 ages (3, 3)"


def test_a_buffer_whose_law_is_over_the_rows_budget_is_refused_upfront_naming_the_longest_within_it():
    """Rows by hand on two_actuator (n = m = 2, 4 patterns): buffer:L has L^2 modes and N = 2 + 2 (L - 1), so
    buffer:10 has 100 * 4 * 20^2 = 160000 rows, buffer:6 36 * 4 * 12^2 = 20736 (within 25000), buffer:7 38416."""
    import time

    from packetloss_cvx import load_example
    from packetloss_cvx.errors import BudgetError
    system = load_example("two_actuator")
    started = time.perf_counter()
    with pytest.raises(BudgetError, match=r"160000 rows.*use buffer:6 or shorter"):
        actuator_dp(system, "buffer:10")
    assert time.perf_counter() - started < 1.0          # upfront: before any Riccati step
    assert actuator_dp(system, "buffer:6").radius < 1.0


def test_udp_like_zero_and_noise_free_hold_get_the_tcp_like_law():
    """Bernoulli links: zero's optimum needs no acknowledgement (noise or not), and hold's none without noise with
    B of full column rank (the input applied last is B^+ (x_k - A x_k-1)): the same law, the same cost."""
    noisy, quiet = _system(2, mu=[0.6, 0.5], noise=True), _system(2, mu=[0.6, 0.5])
    for system, actuator in ((noisy, "zero"), (quiet, "zero"), (quiet, "hold")):
        tcp, udp = actuator_dp(system, actuator), actuator_dp(system, actuator, protocol="udp")
        assert np.array_equal(udp.K, tcp.K)
        assert udp.initial == tcp.initial
    _, cost = actuator_dp_finite(quiet, 3, "hold", protocol="udp")
    assert cost == pytest.approx(_enumerated_optimum(quiet, 3, "hold"), rel=ACTUATOR_DP_RTOL)


def test_noise_free_hold_law_run_from_the_state_history_alone_costs_the_tcp_like_optimum():
    """The UDP-like controller of hold: it never learns a delivery, it rebuilds the held input as
    ``B^+ (x_k - A x_k-1)`` (its own packets and the states only) and applies the TCP-like law to it; sampled
    through the firmware, the mean cost is the design's exact cost from x0 (the engine's stage costs). Measured: the
    same law with the held input taken as 0 costs 7 standard errors more here (a controller that does not rebuild
    it would fail)."""
    system = _system(2, mu=[0.3, 0.3])
    design = actuator_dp(system, "hold", protocol="udp")
    A, B, x0 = system.A, system.B, system.x0
    Omega, psi, mu = system.state_weights[0], system.input_weights[0], system.mu_schedule[0]
    rng = np.random.default_rng(11)
    steps, samples = 15, 4000
    pinv = np.linalg.pinv(B)
    totals = np.empty(samples)
    for k in range(samples):
        x, previous, held, total = x0.copy(), None, np.zeros(2), 0.0
        for _ in range(steps):
            rebuilt = np.zeros(2) if previous is None else pinv @ (x - A @ previous)     # the controller's view
            u = -design.K[0] @ np.concatenate([x, rebuilt])
            d = rng.random(2) < mu
            held = np.where(d, u, held)                                                  # the firmware's
            total += x @ Omega @ x + held @ (psi * held)
            previous, x = x, A @ x + B @ held
        totals[k] = total + x @ Omega @ x
    stage, terminal = design.modes.loop(design.K).stage_costs(Omega, psi, system.noise_cov, x0, steps)
    error = totals.std(ddof=1) / np.sqrt(samples)
    assert abs(totals.mean() - (stage.sum() + terminal)) < SAMPLED_Z_MAX * error


@pytest.mark.parametrize(("actuator", "case", "why"), [
    ("hold", "noise", "with process noise"),
    ("hold", "rank", "with B of rank below its columns"),
    ("buffer:2", "quiet", "the age of the plan"),
    ("buffer:2:hold", "quiet", "the age of the plan"),
    ("zero", "chain", "the channel state behind the chain is hidden")])
def test_udp_like_optimal_law_that_needs_what_only_acknowledgements_tell_is_refused_saying_why(actuator, case, why):
    from packetloss_cvx.closedloop.actuator_region import actuator_critical, actuator_membership
    from packetloss_cvx.errors import UnobservedModeError

    system = {"noise": _system(2, mu=[0.6, 0.5], noise=True), "quiet": _system(2, mu=[0.6, 0.5]),
              "rank": System(A=[[1.1, 0.4], [-0.3, 0.8]], B=[[1.0, 0.5], [0.0, 0.0]], horizon=4,
                             state_weight=[1.0, 2.0], input_weight=[0.5, 0.5], mu=[0.6, 0.5], x0=[1.0, -0.7]),
              "chain": _system(2, channel=GilbertElliott(p=[0.2, 0.1], r=[0.5, 0.3], h_good=[0.95, 0.9],
                                                         h_bad=[0.2, 0.3]))}[case]
    for call in (lambda: actuator_dp(system, actuator, protocol="udp"),
                 lambda: actuator_dp_finite(system, 3, actuator, protocol="udp"),
                 lambda: actuator_membership(system, actuator, protocol="udp")):
        with pytest.raises(UnobservedModeError, match=why) as caught:
            call()
        assert isinstance(caught.value, ValueError)
        assert "use protocol tcp" in str(caught.value)
    if case != "chain":
        with pytest.raises(UnobservedModeError, match=why):
            actuator_critical(system, actuator, protocol="udp")
    assert actuator_dp(system, actuator).K.ndim == 3            # TCP-like: computed


def test_an_unknown_protocol_is_an_input_error():
    with pytest.raises(InputError, match="protocol: expected tcp or udp"):
        actuator_dp(_system(1), "hold", protocol="ack")
