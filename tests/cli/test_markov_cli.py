"""``solve FILE`` on a Gilbert–Elliott system file, and the plug-in-markov claim."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.claims import CLAIMS
from packetloss_cvx.claims.context import Context
from packetloss_cvx.claims.markov import plug_in_markov, plugin_loss
from packetloss_cvx.cli import main
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import dumps_system, system_from_dict
from packetloss_cvx.montecarlo.markov_channels import sample_markov_plan_costs
from packetloss_cvx.qp.markov_solution import markov_solution


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_solve_gilbert_elliott_example(capsys):
    code, out, err = run(capsys, "solve", "pendulum_bursty", "--json")
    assert (code, err) == (0, "")
    data = json.loads(out)
    markov = data["markov"]
    assert markov["channel"]["model"] == "gilbert-elliott"
    assert markov["mean_rate"] == pytest.approx([0.9], rel=1e-15)
    np.testing.assert_allclose(data["mu"], [0.9], rtol=1e-15)         # stationary start: the plug-in mu is 0.9
    for protocol in ("tcp", "udp"):
        entry = markov[protocol]
        assert entry["qp"]["status"] == "optimal"
        assert abs(entry["qp"]["cost"] - entry["exact"]["cost"]) <= 1e-7 * entry["exact"]["cost"]
        assert entry["plugin_cost"] >= entry["exact"]["cost"] * (1 - 1e-9)
    assert markov["tcp"]["exact"]["cost"] == pytest.approx(data["tcp"]["cost"], rel=1e-12)
    assert markov["udp"]["relative_loss"] > 0.05                       # lambda = 0.8 on the pendulum: about 8 %
    code, out, _ = run(capsys, "solve", "pendulum_bursty", "--no-qp")
    assert code == 0
    assert "UDP-like exact: J* =" in out
    assert "plug-in law" in out


def test_solve_refuses_a_bad_channel_file(capsys, tmp_path):
    text = dumps_system(pl.load_example("pendulum_bursty")).replace("p = [0.02]", "p = [1.5]")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code, out, err = run(capsys, "solve", str(path))
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert "channel.p: expected probabilities in [0, 1], found 1.5" in err


def test_example_plan_cost_agrees_with_sampling():
    s = pl.load_example("pendulum_bursty")
    sol = exact_closed_form(s)
    costs = sample_markov_plan_costs(s, sol.inputs, 20_000, np.random.default_rng(4))
    se = costs.std(ddof=1) / np.sqrt(costs.size)
    assert abs(costs.mean() - sol.cost) <= 4 * se


def test_plugin_loss_vanishes_without_correlation_across_steps():
    s = pl.load_example("two_actuator")
    assert abs(plugin_loss(s, 0.0)) <= 1e-12                          # memoryless: the plug-in law is exact
    one = pl.System(A=s.A, B=s.B, horizon=1, state_weight=[1, 1], input_weight=[1, 1], mu=s.mu, x0=s.x0)
    assert abs(plugin_loss(one, 0.9)) <= 1e-12                        # one step: nothing to correlate
    assert plugin_loss(s, 0.9) > 0.2


def test_plug_in_markov_claim_on_a_small_context():
    assert "plug-in-markov" in CLAIMS
    paper = {"two_actuator": pl.load_example("two_actuator")}
    ctx = Context(paper=paper, random=[pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
                                                 input_weight=[1.0], mu=[0.5], x0=[1.0])], seed=0)
    result = plug_in_markov(ctx)
    assert (result.verdict, result.outcomes) == ("fails", "-+")
    assert result.worst == pytest.approx(1e-7 - plugin_loss(paper["two_actuator"], 0.9), rel=1e-12)
    ce = system_from_dict(result.counterexample)
    np.testing.assert_allclose(ce.channel.correlation, 0.9, rtol=1e-12)
    plug_in = pl.closed_form(ce.with_mu(ce.mu_schedule), "udp").inputs
    assert exact_cost(ce, plug_in) > exact_closed_form(ce).cost * (1 + 1e-7)


def test_audit_checks_a_gilbert_elliott_file_behind_its_own_channel(capsys):
    code, out, _ = run(capsys, "audit", "pendulum_bursty", "--claim", "plug-in-markov", "--random", "0", "--json")
    assert code == 0
    (claim,) = json.loads(out)["claims"]
    assert claim["outcomes"] == "---"
    own = markov_solution(pl.load_example("pendulum_bursty"), "udp", qp=False).relative_loss
    assert own == pytest.approx(0.079, abs=5e-4)
    assert claim["worst"] == pytest.approx(1e-7 - plugin_loss(pl.load_example("two_actuator"), 0.9), rel=1e-12)


def test_overflow_of_the_dense_route_says_what_to_do():
    s = pl.System(A=[[3.0]], B=[[1.0]], horizon=800, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.1], r=[0.2]))
    with pytest.raises(pl.NumericalError, match=r"rho\(A\)\^N = 3\^800; use method='recursion'"):
        exact_closed_form(s, method="dense")


def test_overflow_of_the_recursion_is_a_numerical_error_as_for_bernoulli_losses():
    """3^800 is beyond the double range whatever the route: the augmented recursion raises as the Bernoulli
    recursion does on the plug-in schedule, naming the two ways out."""
    s = pl.System(A=[[3.0]], B=[[1.0]], horizon=800, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.1], r=[0.2]))
    with pytest.raises(pl.NumericalError, match="shorten the horizon or stabilise the plant"):
        exact_closed_form(s)
    with pytest.raises(pl.NumericalError, match="shorten the horizon or stabilise the plant"):
        pl.closed_form(s.with_mu(s.mu_schedule), "udp", method="recursion")


def test_plug_in_markov_checks_a_chain_file_behind_its_own_chain():
    """The audit gives the paper's claims a chain file's plug-in mu_t, but plug-in-markov must still see
    the file's own chain (not Gilbert twins of the plug-in rates)."""
    from packetloss_cvx.claims import audit
    from packetloss_cvx.claims.markov import plugin_loss
    from packetloss_cvx.tolerances import CROSS_CHECK_COST_RTOL

    system = pl.load_example("pendulum_bursty")
    (result,) = audit([system], random=0, only=["plug-in-markov"])
    assert result.outcomes[-1] == "-"
    own = CROSS_CHECK_COST_RTOL - plugin_loss(system, None)          # the file's chain: lambda = 0.8
    assert result.worst == pytest.approx(min(own, result.worst), rel=1e-12)
    assert own < -0.05                                                # the plug-in law loses ~7.9 % there
