"""The constrained receding-horizon loop (montecarlo/mpc.py).

References, none taken from the code under test: with no constraint binding, the unconstrained receding-horizon
loops of `simulate` (Bernoulli: `closed_loop_block`) and `markov_loop_block` (a chain) on the same seeds; a scalar
one-step plant whose programs are solved by hand (u = clip(-a x / (1 + mu)), the soft program's u = u_min), its
path walked by hand on deliveries drawn from numpy's stream directly, and its violations tallied by hand; the
Wilson interval by its formula.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from packetloss_cvx.errors import DimensionError, InputError
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo.markov_loop import BeliefGains, markov_loop_block
from packetloss_cvx.montecarlo.mpc import CONFIDENCE, CONTROLLERS, frequency, simulate_mpc, wilson_interval
from packetloss_cvx.montecarlo.simulate import closed_loop_block
from packetloss_cvx.tolerances import CONSTRAINED_AGREEMENT_RTOL


def _plant(**extra) -> System:
    fields = dict(A=[[1.1, 0.2], [0.0, 0.8]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=5, state_weight=[1.0, 2.0],
                  input_weight=[1.0, 0.5], x0=[1.0, -0.5], noise_cov=[[0.02, 0.0], [0.0, 0.01]])
    return System(**{**dict(mu=[0.7, 0.6]), **fields, **extra})


def _loose(system: System) -> Constraints:
    """Bounds far outside anything the loop reaches: none binds."""
    return Constraints(u_min=[-50.0] * system.m, u_max=[50.0] * system.m, du_max=[100.0] * system.m,
                       x_min=[-1e3] * system.n, x_max=[1e3] * system.n, chance=[([1.0, 0.0], 1e3, 0.1)])


def _streams(seed: int):
    """simulate's closed-loop streams for one block: losses, noise."""
    stream = np.random.SeedSequence(seed).spawn(2)[1].spawn(1)[0]
    return [np.random.default_rng(child) for child in stream.spawn(2)]


@pytest.mark.parametrize("seed", [0, 3])
def test_loose_constraints_give_the_unconstrained_loop_on_the_same_seed(seed):
    s = _plant()
    samples, steps = 6, 8
    sim = simulate_mpc(s, _loose(s), samples, steps, seed=seed, controllers=["clipped", "expected-cost"])
    gains = np.array([closed_form(s, p).gain for p in ("tcp", "udp")])
    _, _, stage, _ = closed_loop_block(s, gains, steps, samples, *_streams(seed)[:1], noise_rng=_streams(seed)[1])
    for k, protocol in enumerate(("tcp", "udp")):
        ref = stage[k].mean(axis=0)                                     # per step, over runs
        for controller in ("clipped", "expected-cost"):
            run = sim.runs[protocol][controller]
            assert np.allclose(run.stage_cost_mean, ref, rtol=CONSTRAINED_AGREEMENT_RTOL, atol=0.0)
            assert all(v.count == 0 for v in run.violations)
        assert sim.runs[protocol]["expected-cost"].infeasible.count == 0


def test_loose_constraints_behind_a_chain_give_the_plug_in_loop():
    s = _plant(mu=None, channel=GilbertElliott(p=[0.2, 0.3], r=[0.5, 0.6]))
    samples, steps, seed = 5, 6, 2
    sim = simulate_mpc(s, _loose(s), samples, steps, seed=seed, controllers=["expected-cost"])
    _, _, stage, _ = markov_loop_block(s, ["tcp", "udp"], BeliefGains(s, "tcp"), BeliefGains(s, "udp"), None, steps,
                                       samples, *_streams(seed))
    assert sim.channel == "gilbert-elliott"
    for k, protocol in enumerate(("tcp", "udp")):
        assert np.allclose(sim.runs[protocol]["expected-cost"].stage_cost_mean, stage[k].mean(axis=0),
                           rtol=CONSTRAINED_AGREEMENT_RTOL, atol=0.0)


def _scalar_by_hand(a, mu, x0, u_max, x_max, samples, steps, seed, mu_plan, du=np.inf):
    """x' = a x + v u, N = 1, Q = R = 1, |u| <= u_max, |u - u_prev| <= du (u_prev the last command, 0 at first),
    E[x_1] <= x_max, no noise. The TCP-like program min (a x + mu u)^2 + mu u^2 has u = -a x / (1 + mu), clipped to
    [lowest, highest] = [max(-u_max, u_prev - du), min(u_max, u_prev + du)] (one variable, convex); it is infeasible
    when a x + mu lowest > x_max, and then the soft program (penalty 1e4 per unit) pushes u to lowest. Returns the
    realised states x_1..x_steps (samples, steps), the infeasible flags and the stage costs."""
    stream = np.random.SeedSequence(seed).spawn(2)[1].spawn(1)[0].spawn(2)[0]
    V = np.random.default_rng(stream).random((samples, steps, 1))[:, :, 0] < mu      # sample_delivery_paths' draw
    x, previous = np.full(samples, x0), np.zeros(samples)
    states, infeasible, stage = np.empty((samples, steps)), np.zeros((samples, steps), bool), np.empty((samples, steps))
    for t in range(steps):
        lowest, highest = np.maximum(-u_max, previous - du), np.minimum(u_max, previous + du)
        u = np.clip(-a * x / (1 + mu_plan), lowest, highest)
        bad = a * x + mu_plan * lowest > x_max
        u = previous = np.where(bad, lowest, u)
        infeasible[:, t] = bad
        applied = V[:, t] * u
        stage[:, t] = x ** 2 + applied ** 2
        x = a * x + applied
        states[:, t] = x
    return states, infeasible, stage


def _tally_interval(count, trials):
    """The Wilson score interval by its formula."""
    z = stats.norm.ppf(0.5 + CONFIDENCE / 2)
    p = count / trials
    centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
    half = z * np.sqrt(p * (1 - p) / trials + z * z / (4 * trials ** 2)) / (1 + z * z / trials)
    return max(0.0, centre - half), min(1.0, centre + half)


@pytest.mark.parametrize(("mu", "du"), [(0.5, np.inf), (0.8, np.inf), (0.7, 0.6)])
def test_a_scalar_loop_by_hand(mu, du):
    a, x0, u_max, x_max, samples, steps, seed = 1.3, 2.0, 1.0, 2.0, 12, 6, 5
    s = System(A=[[a]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[x0])
    c = Constraints(u_min=[-u_max], u_max=[u_max], x_max=[x_max], du_max=None if np.isinf(du) else [du])
    sim = simulate_mpc(s, c, samples, steps, seed=seed, protocols=["tcp"])
    run = sim.runs["tcp"]["expected-cost"]
    states, infeasible, stage = _scalar_by_hand(a, mu, x0, u_max, x_max, samples, steps, seed, mu, du)
    assert np.allclose(run.stage_cost_mean, stage.mean(axis=0), rtol=CONSTRAINED_AGREEMENT_RTOL)
    assert run.infeasible.count == infeasible.sum() > 0                    # the hand count; some steps infeasible
    assert run.fallback_steps == infeasible.sum()
    assert run.failed_steps == 0
    violated = states > x_max
    v = run.violation("x_max[0]")
    assert (v.count, v.runs_with) == (violated.sum(), violated.any(axis=1).sum())
    assert v.step_counts.tolist() == violated.sum(axis=0).tolist()
    worst = int(np.argmax(violated.sum(axis=0)))
    assert v.worst_step == worst
    assert v.worst_ci == pytest.approx(_tally_interval(violated[:, worst].sum(), samples), abs=1e-12)
    assert v.runs_ci == pytest.approx(_tally_interval(violated.any(axis=1).sum(), samples), abs=1e-12)
    # certainty-equivalent: the same program planned with mu = 1
    states, infeasible, stage = _scalar_by_hand(a, mu, x0, u_max, x_max, samples, steps, seed, 1.0, du)
    ce = sim.runs["tcp"]["certainty-equivalent"]
    assert np.allclose(ce.stage_cost_mean, stage.mean(axis=0), rtol=CONSTRAINED_AGREEMENT_RTOL)
    assert ce.infeasible.count == infeasible.sum()
    assert ce.violation("x_max[0]").count == (states > x_max).sum()


def test_the_rate_bound_holds_across_steps_from_rest():
    s = _plant()
    du = 0.15
    c = Constraints(u_min=[-1.0, -1.0], u_max=[1.0, 1.0], du_max=[du, du])
    sim = simulate_mpc(s, c, 4, 6, seed=1, protocols=["tcp"])
    for controller in CONTROLLERS:
        run = sim.runs["tcp"][controller]
        assert run.violation("du_max[0]").count == 0
        assert run.violation("du_max[1]").count == 0
    # the unconstrained first input -K x0 moves by more than du from rest: the rate bound is what held it
    assert np.abs(closed_form(s, "tcp").gain @ s.x0).max() > du


def test_wilson_interval_is_the_formula():
    for count, trials in [(0, 10), (3, 10), (10, 10), (17, 250)]:
        assert wilson_interval(count, trials) == pytest.approx(_tally_interval(count, trials), abs=1e-12)


def test_frequency_counts_a_hand_tally():
    flags = np.array([[0, 1, 1], [0, 0, 1], [0, 0, 0], [1, 0, 1]], dtype=bool)
    f = frequency("x", flags, allowed=0.1)
    assert (f.count, f.runs, f.frequency, f.worst_step, f.runs_with) == (5, 4, 5 / 12, 2, 3)
    assert f.worst_ci == pytest.approx(_tally_interval(3, 4))
    assert f.runs_ci == pytest.approx(_tally_interval(3, 4))
    assert f.to_dict()["allowed"] == 0.1


def test_certainty_equivalent_is_one_run_for_both_protocols():
    s = _plant()
    sim = simulate_mpc(s, Constraints(u_min=[-0.4, -0.4], u_max=[0.4, 0.4]), 3, 3,
                       controllers=["certainty-equivalent"])
    assert sim.runs["tcp"]["certainty-equivalent"] is sim.runs["udp"]["certainty-equivalent"]
    data = sim.to_dict()
    assert set(data) >= {"samples", "steps", "seed", "channel", "constraints", "tcp", "udp"}
    assert data["tcp"]["certainty-equivalent"]["infeasible"]["count"] == 0


def test_bad_arguments_are_refused_naming_the_field():
    s = _plant()
    with pytest.raises(InputError, match="controller"):
        simulate_mpc(s, Constraints(u_max=[1.0, 1.0]), 3, 2, controllers=["pid"])
    with pytest.raises(InputError, match="protocol"):
        simulate_mpc(s, Constraints(u_max=[1.0, 1.0]), 3, 2, protocols=["tcpip"])
    with pytest.raises(DimensionError, match="u_max"):
        simulate_mpc(s, Constraints(u_max=[1.0]), 3, 2)
    with pytest.raises(InputError, match="samples"):
        simulate_mpc(s, Constraints(u_max=[1.0, 1.0]), 1, 2)


def test_a_step_without_a_trusted_answer_plays_the_rest_of_the_last_plan(monkeypatch):
    # every packet arrives (mu = 1), x' = x + u, N = 2, Q = R = 1: the plan from x is (-0.6 x, -0.2 x) (two-step
    # Riccati: u0 = -(3/5) x, then u1 = -x1 / 2 at x1 = 0.4 x). The third solve (run 0 at step 1) fails: the loop
    # plays -0.2; and the second (run 1 at step 0) in a second simulation, with no plan yet: zero.
    from packetloss_cvx.errors import SolverError
    from packetloss_cvx.qp.constrained import ConstrainedQP

    s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    solve, calls = ConstrainedQP.solve, []

    def failing(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == failing.at:
            raise SolverError("max_iter", "planted")
        return solve(self, *args, **kwargs)

    failing.at = 3
    monkeypatch.setattr(ConstrainedQP, "solve", failing)
    sim = simulate_mpc(s, Constraints(u_max=[5.0]), 2, 3, protocols=["tcp"], controllers=["expected-cost"])
    run = sim.runs["tcp"]["expected-cost"]
    assert run.failed_steps == 1
    assert run.infeasible.count == 0
    # run 0: x = 1 -> 0.4 (u = -0.6) -> 0.2 (the old plan's -0.2, not the new plan's -0.24) -> u = -0.12
    # run 1: every solve trusted: x = 1 -> 0.4 -> 0.16, u = -0.6, -0.24, -0.096
    first = [1.0 + 0.36, 0.16 + 0.04, 0.04 + 0.0144]
    second = [1.0 + 0.36, 0.16 + 0.0576, 0.0256 + 0.096 ** 2]
    assert np.allclose(run.stage_cost_mean, (np.array(first) + np.array(second)) / 2, rtol=1e-9)
    calls.clear()
    failing.at = 2
    run = simulate_mpc(s, Constraints(u_max=[5.0]), 2, 3, protocols=["tcp"], controllers=["expected-cost"]).runs[
        "tcp"]["expected-cost"]
    # run 1: nothing applied at step 0 (x stays 1), then x = 1 -> 0.4: stages 1, 1.36, 0.2176
    assert np.allclose(run.stage_cost_mean, (np.array(second) + np.array([1.0, 1.36, 0.2176])) / 2, rtol=1e-9)


def test_kept_trajectories_are_the_loop_walked_by_hand():
    # x' = 1.3 x + v u, N = 1, |u| <= 1, E[x_1] <= 2, no noise (_scalar_by_hand): every run kept, the states, the
    # commands and the deliveries are the hand walk's; the stage costs and the violations recounted from them are
    # the run's summaries
    a, mu, x0, samples, steps, seed = 1.3, 0.7, 2.0, 8, 5, 3
    s = System(A=[[a]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[x0])
    c = Constraints(u_min=[-1.0], u_max=[1.0], x_max=[2.0])
    sim = simulate_mpc(s, c, samples, steps, seed=seed, protocols=["tcp"], keep=samples)
    states, _, _ = _scalar_by_hand(a, mu, x0, 1.0, 2.0, samples, steps, seed, mu)
    stream = np.random.SeedSequence(seed).spawn(2)[1].spawn(1)[0].spawn(2)[0]
    V = np.random.default_rng(stream).random((samples, steps, 1)) < mu                 # sample_delivery_paths' draw
    assert sim.delivered.shape == (samples, steps, 1)
    assert np.array_equal(sim.delivered, V)
    for name in CONTROLLERS:
        run = sim.runs["tcp"][name]
        assert run.states.shape == (samples, steps + 1, 1)
        assert run.inputs.shape == (samples, steps, 1)
        x, u = run.states[:, :, 0], run.inputs[:, :, 0]
        assert np.allclose(x[:, 1:], a * x[:, :-1] + V[:, :, 0] * u, rtol=1e-13, atol=0.0)     # the plant, walked
        assert np.allclose(run.stage_cost_mean, (x[:, :-1] ** 2 + (V[:, :, 0] * u) ** 2).mean(axis=0), rtol=1e-12)
        assert run.violation("x_max[0]").count == (x[:, 1:] > 2.0).sum()
        assert np.all(np.abs(u) <= 1.0 + 1e-9)
    assert np.allclose(sim.runs["tcp"]["expected-cost"].states[:, 1:, 0], states, rtol=CONSTRAINED_AGREEMENT_RTOL)


def test_keeping_trajectories_changes_no_summary_and_keeps_the_first_runs():
    s = _plant()
    c = Constraints(u_min=[-0.5, -0.5], u_max=[0.5, 0.5], chance=[([1.0, 0.0], 0.4, 0.2)])
    plain = simulate_mpc(s, c, 4, 3, seed=2, protocols=["udp"])
    kept = simulate_mpc(s, c, 4, 3, seed=2, protocols=["udp"], keep=2)
    every = simulate_mpc(s, c, 4, 3, seed=2, protocols=["udp"], keep=4)
    assert plain.delivered is None
    assert all(r.states is None and r.inputs is None for r in plain.runs["udp"].values())
    assert plain.to_dict() == kept.to_dict()                                # the JSON holds no trajectory
    for name in CONTROLLERS:
        assert np.array_equal(kept.runs["udp"][name].states, every.runs["udp"][name].states[:2])
        assert np.array_equal(kept.runs["udp"][name].inputs, every.runs["udp"][name].inputs[:2])
        assert np.array_equal(kept.runs["udp"][name].states[:, 0], np.broadcast_to(s.x0, (2, 2)))
    assert np.array_equal(kept.delivered, every.delivered[:2])
    with pytest.raises(InputError, match="keep"):
        simulate_mpc(s, c, 4, 3, keep=5)
    with pytest.raises(InputError, match="keep"):
        simulate_mpc(s, c, 4, 3, keep=-1)
