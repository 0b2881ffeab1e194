"""``simulate`` (API and CLI): Monte Carlo within 4 standard errors of the exact expectations, the JSON
schema, seeding, exit codes, saved trajectories and the figure."""

import json

import numpy as np
import pytest

from packetloss_cvx import InputError, System, closed_form, expected_cost
from packetloss_cvx.cli import main
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.montecarlo.simulate import simulate

from ..references import enumerated_radius

OPEN = {"formula", "exact", "mean", "stderr", "z", "formula_basis", "basis"}
CLOSED = {"mean_stage_cost", "stderr", "exact_stage_cost", "mean_square_spectral_radius", "stable", "basis",
          "averaged_steps"}


def stable_random_system(seed):
    rng = np.random.default_rng(seed)
    return random_system(rng, n=3, m=2, horizon=5, spectral_radius=0.95, non_stationary=False, noise=True,
                         edge_mu=False, time_varying=False)      # a loop's cost has one weight (loop_weights)


@pytest.mark.parametrize("seed", [11, 12])
def test_monte_carlo_within_four_standard_errors(seed):
    s = stable_random_system(seed)
    sim = simulate(s, 20000, steps=30, seed=seed, closed_loop=True, progress=False)
    for p, check in sim.open_loop.items():
        assert abs(check.z) < 4
        assert check.exact == pytest.approx(expected_cost(s, closed_form(s, p).inputs, "udp"))
        assert check.formula == pytest.approx(closed_form(s, p).cost)
    for law, run in sim.closed_loop.items():
        assert abs(run.mean_stage_cost - run.exact_stage_cost) < 4 * run.stderr, law
        gain = closed_form(s, law).gain if law != "dp" else None
        if gain is not None:
            assert run.spectral_radius == pytest.approx(enumerated_radius(s.A, s.B, gain, s.mu), rel=1e-10)


def test_seeded_and_reproducible(two_actuator):
    a = simulate(two_actuator, 3000, steps=10, seed=4, closed_loop=True, progress=False)
    b = simulate(two_actuator, 3000, steps=10, seed=4, closed_loop=True, progress=False)
    c = simulate(two_actuator, 3000, steps=10, seed=5, closed_loop=True, progress=False)
    assert a.to_dict() == b.to_dict()
    assert a.to_dict() != c.to_dict()


def test_blocks_do_not_change_the_answer_for_a_prefix():
    """Block b draws from its own spawned stream, run by run: the first runs are the same in a larger run."""
    s = stable_random_system(3)
    assert s.noise_cov.any()
    small = simulate(s, 100, steps=5, seed=0, closed_loop=True, keep=100, progress=False)
    large = simulate(s, 5000, steps=5, seed=0, closed_loop=True, keep=100, progress=False)
    assert np.array_equal(small.trajectories, large.trajectories)


def test_bad_arguments():
    s = stable_random_system(1)
    with pytest.raises(InputError, match="samples"):
        simulate(s, 1)
    with pytest.raises(InputError, match="law"):
        simulate(s, 10, laws=["dp"])
    with pytest.raises(InputError, match="law"):
        simulate(s, 10, laws=["mpc"])
    sched = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0],
                   mu_schedule=[[0.5], [0.9]], x0=[1.0])
    with pytest.raises(InputError, match="mu_schedule"):
        simulate(sched, 10, closed_loop=True)
    assert simulate(sched, 10, progress=False).open_loop   # open loop follows the schedule


def test_cli_schema_and_unstable_exit_zero(capsys):
    assert main(["simulate", "pendulum", "--samples", "500", "--steps", "20", "--closed-loop", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"tcp", "udp", "dp"}
    for p in ("tcp", "udp"):
        assert set(data[p]) == {"open_loop", "closed_loop"}
        assert set(data[p]["open_loop"]) == OPEN
        assert set(data[p]["closed_loop"]) == CLOSED | {"stderr_reason"}   # unstable: no error bar, and why
        assert data[p]["closed_loop"]["stable"] is False   # the paper's pendulum laws: radius > 1
        assert data[p]["closed_loop"]["stderr"] is None
    assert set(data["dp"]) == {"closed_loop"}
    assert data["dp"]["closed_loop"]["stable"] is True


def test_cli_open_loop_only_and_one_law(capsys):
    assert main(["simulate", "two_actuator", "--samples", "200", "--law", "udp", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"udp"}
    assert set(data["udp"]) == {"open_loop"}


@pytest.mark.parametrize("argv", [
    ["--samples", "1"], ["--steps", "0"], ["--seed", "-1"], ["--law", "dp"], ["--save", "x.txt", "--closed-loop"],
    ["--plot", "x.png"],
])
def test_cli_bad_input_exit_two(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "two_actuator", "--samples", "10", *argv]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_cli_non_stationary_closed_loop_exit_two(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text('[plant]\nA = [[1.0]]\nB = [[1.0]]\n[cost]\nhorizon = 2\nstate_weight = [1.0]\n'
                 'input_weight = [1.0]\n[channel]\nmu_schedule = [[0.5], [0.9]]\n[state]\nx0 = [1.0]\n')
    assert main(["simulate", str(f), "--samples", "10", "--closed-loop"]) == 2
    assert "--closed-loop" in capsys.readouterr().err


def test_cli_save_and_plot(tmp_path, capsys):
    npz, png = tmp_path / "runs.npz", tmp_path / "loop.png"
    assert main(["simulate", "two_actuator", "--samples", "300", "--steps", "7", "--closed-loop",
                 "--save", str(npz), "--plot", str(png), "--quiet"]) == 0
    assert "closed loop" in capsys.readouterr().out
    saved = np.load(npz)
    assert saved["trajectories"].shape == (3, 300, 8, 2)
    assert list(saved["laws"]) == ["tcp", "udp", "dp"]
    assert png.stat().st_size > 1000


def test_solve_says_whether_the_pendulum_loops_are_stable(capsys):
    assert main(["solve", "pendulum", "--no-qp"]) == 0
    text = capsys.readouterr().out
    assert text.count("NOT mean-square stable") == 2
    assert main(["solve", "two_actuator", "--no-qp", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    for p in ("tcp", "udp"):
        assert data[p]["stable"] is True
        assert 0 < data[p]["mean_square_spectral_radius"] < 1


def test_deterministic_channel_has_zero_z():
    s = System(A=[[0.9, 0.1], [0.0, 0.8]], B=[[1.0], [0.5]], horizon=6, state_weight=[1.0, 1.0], input_weight=[1.0],
               mu=[1.0], x0=[1.0, -1.0])
    sim = simulate(s, 5000, steps=10, seed=0, closed_loop=True, progress=False)
    for check in sim.open_loop.values():
        assert check.z == 0.0
        assert check.mean == pytest.approx(check.exact, rel=1e-12)
    for run in sim.closed_loop.values():
        assert run.mean_stage_cost == pytest.approx(run.exact_stage_cost, rel=1e-12)


def test_no_stabilising_law_is_a_result(tmp_path, capsys):
    """a = 3, mu = 0.5 < 1 - 1/9: no law holds the second moment; the DP entry says why, exit 0."""
    f = tmp_path / "s.toml"
    f.write_text('[plant]\nA = [[3.0]]\nB = [[1.0]]\n[cost]\nhorizon = 3\nstate_weight = [1.0]\n'
                 'input_weight = [1.0]\n[channel]\nmu = [0.5]\n[state]\nx0 = [1.0]\n')
    assert main(["simulate", str(f), "--samples", "200", "--steps", "5", "--closed-loop", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    dp = data["dp"]["closed_loop"]
    assert dp["stable"] is False
    assert "no stabilising solution" in dp["reason"]
    assert dp["mean_stage_cost"] is None
    assert data["tcp"]["closed_loop"]["stable"] is False


def test_solve_non_stationary_channel_uses_the_first_step(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text('[plant]\nA = [[1.2]]\nB = [[1.0]]\n[cost]\nhorizon = 2\nstate_weight = [1.0]\n'
                 'input_weight = [1.0]\n[channel]\nmu_schedule = [[0.9], [0.2]]\n[state]\nx0 = [1.0]\n')
    assert main(["solve", str(f), "--no-qp", "--json"]) == 0
    entry = json.loads(capsys.readouterr().out)["tcp"]
    k = entry["gain"][0][0]
    assert entry["mean_square_spectral_radius"] == pytest.approx((1.2 - 0.9 * k) ** 2 + 0.09 * k ** 2)
    assert "first step" in entry["stability_note"]


def test_huge_closed_loop_is_refused_before_drawing(two_actuator, monkeypatch):
    from packetloss_cvx import ResourceError
    with pytest.raises(ResourceError, match="PACKETLOSS_CVX_BUDGET_SIMULATE_WORK"):    # the work budget first
        simulate(two_actuator, 10000, steps=10 ** 9, closed_loop=True, progress=False)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_SIMULATE_WORK", "inf")        # raised on purpose: the memory check
    with pytest.raises(ResourceError, match="steps: .*PACKETLOSS_CVX_BUDGET_MEMORY_BYTES"):
        simulate(two_actuator, 10000, steps=10 ** 9, closed_loop=True, progress=False)


def test_cli_explains_the_tcp_plans_exact_cost_above_its_formula(tmp_path, capsys):
    # one step of x' = x + v u from x0 = 1, mu = 1/2: the TCP-like plan u = -2/3 has J* = 2/3 and exact
    # cost 7/9; the gap is the loss variance u^2 mu (1 - mu) = 1/9 (docs/claims.md, expected-cost-tcp)
    from packetloss_cvx.model.files import save_system

    scalar = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = str(save_system(scalar, tmp_path / "scalar.toml"))
    assert main(["simulate", path, "--samples", "100", "-q"]) == 0
    lines = capsys.readouterr().out.splitlines()
    tcp = next(k for k, line in enumerate(lines) if "TCP-like plan" in line)
    note = lines[tcp + 1]
    assert "expected-cost-tcp" in note
    assert "docs/claims.md" in note
    assert f"= {1 / 9:.6g} " in note
    assert not any("expected-cost-tcp" in line for line in lines[tcp + 2:])   # once, under the TCP-like plan only
    assert main(["simulate", path, "--samples", "100", "-q", "--mu", "1"]) == 0   # every packet arrives: no gap
    assert "expected-cost-tcp" not in capsys.readouterr().out


def test_a_loop_with_nothing_random_has_a_zero_spread_not_rare_bursts(capsys):
    """two_actuator at mu = 0 (no input ever arrives, no noise): every run is x_t = A^t x0, so the laws' loops are
    deterministic though not mean-square stable; the sample is the exact cost with zero spread, and nothing may
    blame rare loss bursts or rare runs."""
    from packetloss_cvx import load_example
    from packetloss_cvx.model.system import loop_weights

    s = load_example("two_actuator").with_mu([0.0, 0.0])
    assert not s.noise_cov.any()
    steps = 12
    Omega, _ = loop_weights(s)
    x, costs = s.x0.copy(), []
    for _ in range(steps):          # the hand rollout: nothing arrives, so u never acts
        costs.append(float(x @ Omega @ x))
        x = s.A @ x
    sim = simulate(s, 20, steps=steps, seed=3, closed_loop=True, laws=["tcp", "udp"], progress=False)
    for run in sim.closed_loop.values():
        assert not run.stable
        assert run.stderr == 0.0
        assert run.stderr_reason == ""
        assert run.mean_stage_cost == pytest.approx(np.mean(costs), rel=1e-12)
    assert main(["simulate", "two_actuator", "--mu", "0", "--closed-loop", "--samples", "20", "--steps", "12",
                 "-q"]) == 0
    text = capsys.readouterr().out
    assert "rare" not in text
    assert text.count("zero spread") == 2


def test_an_overflow_of_a_stable_plant_does_not_blame_instability():
    """A = 1e-300 I (stable), B and weights of 1e300: the exact cost overflows from the entries alone; the error says
    so rather than naming only an unstable plant it never checked."""
    from packetloss_cvx import NumericalError

    s = System(A=[[1e-300, 0.0], [0.0, 1e-300]], B=[[1e-300, 0.0], [0.0, 1e300]], horizon=5,
               state_weight=[1e-300, 1e300], input_weight=[1e-300, 1e300], mu=[0.9, 0.9], x0=[1.0, 1.0])
    assert max(abs(np.linalg.eigvals(s.A))) < 1
    with pytest.raises(NumericalError) as err:
        simulate(s, 10, progress=False)
    assert "entries of A, B, the weights" in str(err.value)
    assert "rescale the model's units" in str(err.value)
