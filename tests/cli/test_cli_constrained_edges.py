"""The constrained commands at their edges: infinite bounds in strict JSON, work refused before it starts, the
chain file, the costs' bases, soft rows' violations in the text."""

from __future__ import annotations

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.files import save_system


def _scalar(tmp_path, name="scalar.toml", horizon=8, a=1.2, mu=0.7, **table):
    s = pl.System(A=[[a]], B=[[1.0]], horizon=horizon, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[3.0])
    return save_system(s, tmp_path / name, constraints=Constraints(**table) if table else None)


def test_infinite_bounds_are_null_in_the_json_of_simulate_and_solve(tmp_path, capsys):
    """An infinite entry leaves a bound out (design.md's own example has one): the JSON is strict (no inf), the
    entry null in its place, on stdout and in --out."""
    path = _scalar(tmp_path, u_min=[-1.0], u_max=[np.inf], du_max=[np.inf])
    out = tmp_path / "o.json"
    assert main(["simulate", str(path), "--json", "--quiet", "--samples", "2", "--mpc-samples", "2", "--steps", "3",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for text in (printed, out.read_text()):
        loop = json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))["constrained_loop"]
        assert loop["constraints"] == {"u_min": [-1.0], "u_max": [None], "du_max": [None]}
    assert main(["solve", "two_actuator", "--json", "--quiet", "--u-max", "0.5,inf", "--du-max", "0.3,inf"]) == 0
    data = json.loads(capsys.readouterr().out, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    assert data["tcp"]["constrained"]["status"] == "optimal"


@pytest.mark.parametrize("extra", [["--mpc-samples", "1000000000"], ["--steps", "10000000", "--mpc-samples", "2"],
                                   ["--mpc-samples", "100000", "--steps", "1000"]])
def test_the_constrained_loop_beyond_its_budget_is_refused_before_any_sampling(tmp_path, capsys, monkeypatch, extra):
    """Exit 2, one line naming --mpc-samples and the variable that raises the budget; the open-loop sampling, which
    runs first, never starts."""
    import packetloss_cvx.cli.simulate as command

    monkeypatch.setattr(command, "simulate", lambda *a, **k: (_ for _ in ()).throw(AssertionError("sampled")))
    path = _scalar(tmp_path, u_min=[-1.0], u_max=[1.0])
    assert main(["simulate", str(path), "--quiet", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "error: --mpc-samples:" in err[0]
    assert "PACKETLOSS_CVX_BUDGET_MPC_SOLVES=" in err[0]


def test_solve_refuses_a_constrained_program_beyond_its_budget_naming_the_horizon(tmp_path, capsys, monkeypatch):
    """A horizon of 1e5 with an input box died in a MemoryError of 74.5 GiB after 26 s: refused before any work,
    exit 2, one line naming cost.horizon; --no-qp (no constrained program) still solves."""
    import packetloss_cvx.cli.solve as command

    path = _scalar(tmp_path, horizon=100_000, a=0.9, u_min=[-1.0], u_max=[1.0])
    real = command.closed_form
    monkeypatch.setattr(command, "closed_form", lambda *a, **k: (_ for _ in ()).throw(AssertionError("solved")))
    assert main(["solve", str(path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "error: cost.horizon: the constrained program of N = 100000" in err[0]
    assert "PACKETLOSS_CVX_BUDGET_SOLVE_WORK=" in err[0]
    monkeypatch.setattr(command, "closed_form", real)
    assert main(["solve", str(path), "--quiet", "--no-qp", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["tcp"]["constrained"]["status"] == "skipped"


def _enumerated_cost(a, b, q, r, x0, plan, pattern_probability):
    """E[sum_k q x_k^2 + r (v_t u_t)^2], k = 1..N, t = 0..N-1, for x' = a x + b v u, by enumerating every delivery
    pattern v in {0, 1}^N with its probability."""
    N = len(plan)
    total = 0.0
    for bits in range(2 ** N):
        v = [(bits >> t) & 1 for t in range(N)]
        x, cost = x0, 0.0
        for t in range(N):
            applied = v[t] * plan[t]
            x = a * x + b * applied
            cost += q * x * x + r * applied * applied
        total += pattern_probability(v) * cost
    return total


def test_the_constrained_costs_say_their_basis(tmp_path, capsys):
    """The TCP-like J is the paper's first-moment value (mean recursion by hand) and leaves out the loss variance;
    its plan's expected cost (enumerated over the 2^8 loss patterns) is reported beside it with basis "realised";
    the UDP-like J is its plan's expected cost."""
    path = _scalar(tmp_path, u_min=[-1.0], u_max=[1.0])
    assert main(["solve", str(path), "--json", "--quiet"]) == 0
    data = json.loads(capsys.readouterr().out)
    bernoulli = lambda v: float(np.prod([0.7 if d else 0.3 for d in v]))      # noqa: E731
    for protocol, basis in (("tcp", "paper"), ("udp", "realised")):
        entry = data[protocol]["constrained"]
        assert "chance_rows" not in entry                 # said behind a chain only
        plan = [row[0] for row in entry["inputs"]]
        x, first_moment = 3.0, 0.0
        for u in plan:
            x = 1.2 * x + 0.7 * u
            first_moment += x * x + 0.7 * u * u
        enumerated = _enumerated_cost(1.2, 1.0, 1.0, 1.0, 3.0, plan, bernoulli)
        assert entry["basis"] == basis
        assert entry["plan_expected_cost"] == pytest.approx(enumerated, rel=1e-12)
        assert entry["cost"] == pytest.approx(first_moment if protocol == "tcp" else enumerated, rel=1e-12)
    assert data["tcp"]["constrained"]["cost"] < data["tcp"]["constrained"]["plan_expected_cost"] - 1.0
    assert main(["solve", str(path), "--quiet"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("constrained")]
    assert "[basis: paper" in lines[0]
    assert "[basis: realised]" in lines[0]
    assert "[basis: realised" in lines[1]


def test_behind_a_chain_the_constrained_block_is_the_plug_in_program_with_its_cost_under_the_chain(tmp_path,
                                                                                                     capsys):
    """The command line solves the plug-in program (its cost on Bernoulli losses at the chain's mu_t, its chance rows
    exact under the chain), says so, and reports its plan's exact expected cost under the chain: enumerated over the
    2^10 delivery patterns with their probabilities under the Gilbert-Elliott chain (HMM forward pass)."""
    text = ('name = "hid"\n[plant]\nA = [[1.3]]\nB = [[0.8]]\n[cost]\nhorizon = 10\nstate_weight = [1.5]\n'
            'input_weight = [0.7]\n[channel]\nmodel = "gilbert-elliott"\np = [0.1]\nr = [0.3]\nh_good = [0.95]\n'
            'h_bad = [0.1]\n[state]\nx0 = [2.0]\n[constraints]\nu_min = [-1.0]\nu_max = [1.0]\nx_max = [3.0]\n')
    path = tmp_path / "hid.toml"
    path.write_text(text)
    P, h, start = np.array([[0.9, 0.1], [0.3, 0.7]]), np.array([0.95, 0.1]), np.array([0.75, 0.25])

    def chain(v):
        belief = start.copy()
        for d in v:
            belief = (belief * (h if d else 1.0 - h)) @ P
        return float(belief.sum())

    assert main(["solve", str(path), "--json", "--quiet"]) == 0
    data = json.loads(capsys.readouterr().out)
    for protocol in ("tcp", "udp"):
        entry = data[protocol]["constrained"]
        assert entry["plug_in"] is True
        assert entry["basis"] == "paper, prior-mean rates"
        assert entry["chance_rows"] == "exact under the chain"
        plan = [row[0] for row in entry["inputs"]]
        assert entry["plan_expected_cost"] == pytest.approx(_enumerated_cost(1.3, 0.8, 1.5, 0.7, 2.0, plan, chain),
                                                            rel=1e-10)
    assert data["udp"]["constrained"]["plan_expected_cost"] > 1.5 * data["udp"]["constrained"]["cost"]
    assert main(["solve", str(path), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "the plug-in program" in out
    assert "its chance rows exact under the chain" in out
    assert "its plan's expected cost under the chain" in out


def test_the_text_says_which_soft_rows_the_plan_violates(tmp_path, capsys):
    """A soft state limit the plan breaks (slack > 0) is printed as violated, by how much, not as binding."""
    path = _scalar(tmp_path, x_max=[0.1], soft=True, soft_weight=1e-3)
    assert main(["solve", str(path), "--json", "--quiet"]) == 0
    violations = json.loads(capsys.readouterr().out)["tcp"]["constrained"]["violations"]
    assert [v["constraint"] for v in violations][:2] == ["x_max[0] at k=1", "x_max[0] at k=2"]
    assert main(["solve", str(path), "--quiet"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("constrained"))
    shown = ", ".join(f"{v['constraint']} by {v['by']:.3g}" for v in violations)
    assert f"soft rows violated: {shown}" in line
    assert "binding: none" in line


@pytest.mark.parametrize(("extra", "field"), [
    (["--mu-schedule", "SCHEDULE"], "--mu-schedule"),
    (["--weights"], "cost.state_weights"),
])
def test_what_the_constrained_loop_cannot_run_is_refused_before_the_open_loop(tmp_path, capsys, monkeypatch, extra,
                                                                              field):
    """A non-stationary --mu-schedule (the loop runs for ever over one channel: it said "mu_schedule: the closed loop
    runs for ever", naming neither the flag nor the way out) and time-varying weights (the loop's stage cost used the
    first weight): exit 2, one line naming the flag or key and --mpc-samples 0 for the schedule, before any
    sampling; with --mpc-samples 0 the open loop runs."""
    import packetloss_cvx.cli.simulate as command

    path = _scalar(tmp_path, u_min=[-1.0], u_max=[1.0])
    if extra == ["--weights"]:
        text = path.read_text().replace("state_weight = [1.0]", "state_weights = [" + ", ".join(
            ["[1.0]"] * 4 + ["[5.0]"] * 4) + "]")
        path.write_text(text)
        extra = []
    else:
        schedule = tmp_path / "schedule.csv"
        schedule.write_text("\n".join(["0.5", "0.6", "0.7", "0.8", "0.9", "0.5", "0.5", "0.5"]) + "\n")
        extra = ["--mu-schedule", str(schedule)]
    real = command.simulate
    monkeypatch.setattr(command, "simulate", lambda *a, **k: (_ for _ in ()).throw(AssertionError("sampled")))
    assert main(["simulate", str(path), "--quiet", "--samples", "10", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert f"error: {field}:" in err[0]
    if field == "--mu-schedule":
        assert "--mpc-samples 0" in err[0]
    monkeypatch.setattr(command, "simulate", real)
    assert main(["simulate", str(path), "--quiet", "--samples", "10", "--mpc-samples", "0", *extra]) == 0
