"""The constrained loop when the actuator zeroes, holds or plays the buffered plan on a loss
(`simulate_mpc(..., actuator=...)`, montecarlo/mpc.py).

References, none taken from the code under test: a scalar program whose plans are known by hand (x' = x + u, N = 2,
Q = R = 1, every packet assumed to arrive: the plan from x is (-0.6 x, -0.2 x)) walked on a fixed loss path; the
clipped law on a scalar plant walked step by step in the test (its gain from Theorem 1, `closed_form`); the bounds
themselves (a plan within the input and rate bounds, played in order, stays within them); and the exact expected
cost of the same linear law under each strategy (`closedloop.actuator.actuator_costs`, the mode engine) against the
sampled loop with loose bounds.
"""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.closedloop.actuator import actuator_costs
from packetloss_cvx.errors import InputError
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo import mpc
from packetloss_cvx.montecarlo.mpc import CONTROLLERS, simulate_mpc
from packetloss_cvx.tolerances import CONSTRAINED_ACTIVE_RTOL, SAMPLED_Z_MAX


def _plant(**extra) -> System:
    fields = dict(A=[[1.1, 0.2], [0.0, 0.8]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=5, state_weight=[1.0, 2.0],
                  input_weight=[1.0, 0.5], x0=[1.0, -0.5], noise_cov=[[0.02, 0.0], [0.0, 0.01]])
    return System(**{**dict(mu=[0.7, 0.6]), **fields, **extra})


def _fixed_path(monkeypatch, path: list[int], samples: int) -> None:
    """Every run sees the deliveries ``path`` (one actuator), no noise."""
    V = np.repeat(np.array(path, dtype=bool)[:, None, None], samples, axis=1)
    monkeypatch.setattr(mpc, "loop_paths", lambda system, samples, steps, seed: (V[:steps], None))


def test_the_default_is_zero_and_zero_is_the_strategy_named():
    s = _plant()
    c = Constraints(u_min=[-0.6, -0.5], u_max=[0.6, 0.5], du_max=[0.2, 0.2], x_max=[1.5, 1.0])
    default = simulate_mpc(s, c, 4, 4, seed=2, keep=4)
    named = simulate_mpc(s, c, 4, 4, seed=2, keep=4, actuator="zero")
    assert default.actuator == "zero"
    assert default.to_dict()["actuator"] == "zero"
    assert default.to_dict() == named.to_dict()
    for p in ("tcp", "udp"):
        assert default.runs[p]["certainty-equivalent"] is default.runs["tcp"]["certainty-equivalent"]
        for name in CONTROLLERS:
            assert default.runs[p][name].applied is None
            assert np.array_equal(default.runs[p][name].inputs, named.runs[p][name].inputs)


@pytest.mark.parametrize(("actuator", "stages"), [
    # x0 = 1, deliveries 1, 0, 0, 1; the plan from x is (-0.6 x, -0.2 x)
    ("zero", [1 + 0.36, 0.16, 0.16, 0.16 + 0.24 ** 2]),                   # x: 1, 0.4, 0.4, 0.4, 0.16
    ("hold", [1 + 0.36, 0.16 + 0.36, 0.04 + 0.36, 0.64 + 0.48 ** 2]),     # x: 1, 0.4, -0.2, -0.8, -0.32
    ("buffer:2", [1 + 0.36, 0.16 + 0.04, 0.04, 0.04 + 0.12 ** 2]),        # x: 1, 0.4, 0.2, 0.2, 0.08
    ("buffer:2:hold", [1 + 0.36, 0.16 + 0.04, 0.04 + 0.04, 0.0]),         # x: 1, 0.4, 0.2, 0, 0
])
def test_a_scalar_program_walked_by_hand_on_a_fixed_loss_path(monkeypatch, actuator, stages):
    s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    _fixed_path(monkeypatch, [1, 0, 0, 1], 2)
    sim = simulate_mpc(s, Constraints(u_max=[5.0]), 2, 4, protocols=["tcp"], controllers=["expected-cost"],
                       actuator=actuator)
    run = sim.runs["tcp"]["expected-cost"]
    assert sim.actuator == actuator
    assert np.allclose(run.stage_cost_mean, stages, rtol=1e-9, atol=1e-12)


def _clipped_by_hand(a: float, k: float, x0: float, path: list[int], length: int, keeps: bool, u_max: float,
                     du_max: float, from_applied: bool) -> tuple[list[float], list[float]]:
    """x' = a x + applied, Q = R = 1, the law u = clip(-k x) to |u| <= u_max and |u - u_prev| <= du_max, the packet
    its ``length`` inputs rolled out on x' = a x + u; the actuator plays entry j after j losses, then its last
    input (``keeps``) or zero. Returns the stage costs and the applied inputs."""
    x, last, command = x0, 0.0, 0.0
    buffer, played = [0.0] * length, length
    stages, applied = [], []
    for delivered in path:
        previous = last if from_applied else command
        plan, xp = [], x
        for _ in range(length):
            previous = min(max(-k * xp, -u_max, previous - du_max), u_max, previous + du_max)
            plan.append(previous)
            xp = a * xp + previous
        command = plan[0]
        if delivered:
            buffer, played = plan, 0
        else:
            played = min(played + 1, length)
        last = buffer[played] if played < length else (last if keeps else 0.0)
        stages.append(x * x + last * last)
        applied.append(last)
        x = a * x + last
    return stages, applied


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize(("actuator", "length", "keeps"), [("hold", 1, True), ("buffer:3", 3, False),
                                                          ("buffer:3:hold", 3, True)])
def test_the_clipped_law_walked_by_hand_on_a_fixed_loss_path(monkeypatch, protocol, actuator, length, keeps):
    # x' = 1.2 x + v u, N = 3, mu = 0.6; |u| <= 0.5, |du| <= 0.3: the first command is clipped to -0.3 (rate from
    # rest), the TCP-like plan's second entry to -0.5 (the box: -k 0.9 < -0.6); a TCP-like controller plans from
    # the applied input, a UDP-like one from its last command
    s = System(A=[[1.2]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.6], x0=[1.0])
    path = [1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 0]
    _fixed_path(monkeypatch, path, 2)
    c = Constraints(u_min=[-0.5], u_max=[0.5], du_max=[0.3])
    sim = simulate_mpc(s, c, 2, len(path), protocols=[protocol], controllers=["clipped"], actuator=actuator,
                       keep=2)
    k = float(closed_form(s, protocol).gain[0, 0])
    stages, applied = _clipped_by_hand(1.2, k, 1.0, path, length, keeps, 0.5, 0.3, protocol == "tcp")
    run = sim.runs[protocol]["clipped"]
    assert applied[0] == pytest.approx(-0.3, abs=1e-15)
    if protocol == "tcp" and length > 1:
        assert applied[1] == pytest.approx(-0.5, abs=1e-15)                # the buffered second entry, lost packet
    assert np.allclose(run.applied[:, :, 0], applied, rtol=1e-13, atol=1e-15)
    assert np.allclose(run.stage_cost_mean, stages, rtol=1e-13, atol=1e-15)
    steps_of = np.abs(np.diff(np.concatenate([[0.0], applied])))
    assert run.violation("du_max[0]").count == 2 * np.sum(steps_of > 0.3 + CONSTRAINED_ACTIVE_RTOL)


def _tight() -> Constraints:
    return Constraints(u_min=[-0.6, -0.5], u_max=[0.6, 0.5], du_max=[0.15, 0.2], x_max=[1.5, 1.0])


@pytest.mark.parametrize("actuator", ["hold", "buffer:3:hold", "buffer:5:hold"])
def test_the_buffered_plan_respects_input_and_rate_bounds_by_construction(actuator):
    # a TCP-like controller plans from the input the actuator applied: every plan lies in the box, its first entry
    # within the rate bound of that input and each next entry of the one before, so a plan played in order and held
    # once exhausted never leaves the bounds, whatever the deliveries; the bounds do bind (not a vacuous pass)
    s = _plant()
    c = _tight()
    samples, steps = 12, 10
    sim = simulate_mpc(s, c, samples, steps, seed=5, protocols=["tcp"], actuator=actuator, keep=samples)
    assert not sim.delivered.all()
    for name in CONTROLLERS:
        run = sim.runs["tcp"][name]
        for row in ("u_min[0]", "u_min[1]", "u_max[0]", "u_max[1]", "du_max[0]", "du_max[1]"):
            assert run.violation(row).count == 0, (name, row)
        a = run.applied
        step = np.abs(np.diff(np.concatenate([np.zeros((samples, 1, 2)), a], axis=1), axis=1))
        assert np.all(step <= c.du_max + CONSTRAINED_ACTIVE_RTOL)          # recounted from the inputs
        assert np.all(np.abs(a) <= c.u_max + CONSTRAINED_ACTIVE_RTOL)
        assert np.isclose(step, c.du_max, rtol=1e-6).any()                      # the rate bound binds


def test_a_buffer_that_zeroes_once_exhausted_breaks_the_rate_bound_only_there():
    s = _plant(mu=[0.5, 0.4])
    c = _tight()
    samples, steps, L = 12, 12, 2
    sim = simulate_mpc(s, c, samples, steps, seed=1, protocols=["tcp"], actuator=f"buffer:{L}", keep=samples)
    V = sim.delivered
    for name in CONTROLLERS:
        run = sim.runs["tcp"][name]
        a = run.applied
        step = np.abs(np.diff(np.concatenate([np.zeros((samples, 1, 2)), a], axis=1), axis=1))
        broken = step > c.du_max + CONSTRAINED_ACTIVE_RTOL
        for i in range(2):
            assert run.violation(f"du_max[{i}]").count == broken[:, :, i].sum()
            assert run.violation(f"u_max[{i}]").count == run.violation(f"u_min[{i}]").count == 0
        for r, t, i in zip(*np.nonzero(broken), strict=True):           # the plan just ran out: L losses, zero
            assert t >= L
            assert not V[r, t - L + 1:t + 1, i].any()
            assert a[r, t, i] == 0.0
    assert sum(sim.runs["tcp"][name].violation("du_max[0]").count for name in CONTROLLERS) > 0


def test_every_strategy_runs_on_the_same_paths():
    s = _plant()
    c = _tight()
    sims = {a: simulate_mpc(s, c, 4, 5, seed=7, protocols=["udp"], controllers=["clipped"], actuator=a, keep=4)
            for a in ("zero", "hold", "buffer:2")}
    assert all(np.array_equal(sim.delivered, sims["zero"].delivered) for sim in sims.values())
    # the first step is the same command everywhere (nothing received before it); the strategies differ after
    assert all(np.array_equal(sim.runs["udp"]["clipped"].inputs[:, 0], sims["zero"].runs["udp"]["clipped"].inputs[
        :, 0]) for sim in sims.values())


def test_certainty_equivalent_runs_per_protocol_under_hold():
    s = _plant()
    sim = simulate_mpc(s, _tight(), 4, 4, seed=3, controllers=["certainty-equivalent"], actuator="hold")
    tcp, udp = sim.runs["tcp"]["certainty-equivalent"], sim.runs["udp"]["certainty-equivalent"]
    assert tcp is not udp
    assert (tcp.protocol, udp.protocol) == ("tcp", "udp")


@pytest.mark.parametrize("bad", ["buffer:0", "buffer:6", "drop", "hold:2", "buffer:2:zap"])
def test_a_bad_strategy_is_refused_naming_the_field(bad):
    with pytest.raises(InputError, match="^actuator: expected zero, hold or buffer:L"):
        simulate_mpc(_plant(), _tight(), 2, 2, actuator=bad)


@pytest.mark.parametrize("actuator", ["hold", "buffer:3", "buffer:3:hold"])
def test_with_loose_bounds_the_loop_costs_the_linear_law_exactly(actuator):
    # no bound binds: the clipped law is u = -K x, its packet the nominal plan -K (A - B K)^j x; the sampled loop's
    # mean stage cost is the mode engine's exact one within its sampling interval
    s = _plant(horizon=3, x0=[2.0, -1.0], noise_cov=[[0.2, 0.0], [0.0, 0.1]])
    loose = Constraints(u_min=[-1e3] * 2, u_max=[1e3] * 2, du_max=[1e3] * 2)
    samples, steps = 3000, 12
    sim = simulate_mpc(s, loose, samples, steps, seed=11, controllers=["clipped"], actuator=actuator)
    for protocol in ("tcp", "udp"):
        run = sim.runs[protocol]["clipped"]
        stage, _ = actuator_costs(s, closed_form(s, protocol).gain, steps, actuator)
        assert all(v.count == 0 for v in run.violations)
        assert abs(run.mean_stage_cost - stage.mean()) <= SAMPLED_Z_MAX * run.stderr, (protocol, run.mean_stage_cost,
                                                                                      stage.mean(), run.stderr)
        assert run.stderr < 0.05 * stage.mean()                              # an interval that can tell


def test_threads_and_tasks_give_the_serial_runs_float_for_float_under_a_buffer(monkeypatch):
    # the strategy travels to every thread and task (loop_task rebuilds the controller from its name): the serial
    # run is the reference, through its whole JSON and the kept applied inputs
    from concurrent.futures import ThreadPoolExecutor

    s = _plant()
    args = dict(samples=2 * mpc.CHUNK + 3, steps=4, seed=6, progress=False, keep=mpc.CHUNK + 2,
                actuator="buffer:3:hold")
    serial = simulate_mpc(s, _tight(), **args)
    threads = simulate_mpc(s, _tight(), threads=2, **args)
    monkeypatch.setattr(mpc, "TASK_CHUNKS", 2)
    with ThreadPoolExecutor(2) as pool:
        tasks = simulate_mpc(s, _tight(), dask=pool, **args)
    for spread in (threads, tasks):
        assert spread.to_dict() == serial.to_dict()
        for p in ("tcp", "udp"):
            for name in CONTROLLERS:
                assert np.array_equal(spread.runs[p][name].applied, serial.runs[p][name].applied)
    assert serial.runs["tcp"]["certainty-equivalent"] is not serial.runs["udp"]["certainty-equivalent"]
