"""The audit: counterexamples recomputed (not stored verdicts), and the CLI."""

import json

import numpy as np

import packetloss_cvx as pl
from packetloss_cvx.claims import CLAIMS, audit, markdown_report
from packetloss_cvx.cli import main
from packetloss_cvx.io import system_from_dict
from packetloss_cvx.montecarlo import closed_loop_costs, sample_plan_costs


def test_theorem_1_cost_counterexample_by_hand():
    """docs/claims.md: n = 1, m = 2, N = 1; the minimum is 5/12, the printed formula gives 29/60."""
    s = pl.System(A=[[1.0]], B=[[1.0, 1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0, 1.0],
                  mu=[0.9, 0.5], x0=[1.0])
    assert np.isclose(pl.closed_form(s, "tcp").cost, 5 / 12, rtol=1e-12)
    assert np.isclose(pl.solve_qp(s, "tcp", with_gain=False).cost, 5 / 12, rtol=1e-8)
    assert np.isclose(pl.paper_optimal_cost(s, "tcp"), 29 / 60, rtol=1e-12)


def test_expected_cost_tcp_counterexample_scalar():
    """n = m = N = 1: the sampled cost of a plan exceeds J_tcp by omega mu (1 - mu) u^2."""
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    U = np.array([[-0.5]])  # realised cost 0.5 if delivered, 1.0 if lost: mean 0.75
    costs = sample_plan_costs(s, U, 100_000, np.random.default_rng(5))
    se = costs.std(ddof=1) / np.sqrt(costs.size)
    assert abs(costs.mean() - pl.expected_cost(s, U, "udp")) < 4 * se
    assert costs.mean() - pl.expected_cost(s, U, "tcp") > 20 * se
    assert np.isclose(pl.expected_cost(s, U, "udp"), 0.75)
    assert np.isclose(pl.expected_cost(s, U, "tcp"), 0.6875)  # (1 - 0.25)^2 + 0.5 * 0.25


def test_corollary_1_counterexample():
    s = pl.System(A=[[-1.0, 1.0], [1.0, -1.0]], B=[[0.5, 1.0], [-1.0, -0.5]], horizon=4,
                  state_weight=[1.0, 1.0], input_weight=[1.0, 1.0], mu=[0.3, 0.6], x0=[-2.0, 1.0])
    tcp = np.linalg.norm(pl.solve_qp(s, "tcp", with_gain=False).inputs)
    udp = np.linalg.norm(pl.solve_qp(s, "udp", with_gain=False).inputs)
    assert udp > tcp * 1.2


def _exact_scalar_closed_loop(a, b, k, mu, steps):
    """E[sum x_t^2 + (v u_t)^2] + x_T^2 for x_{t+1} = a x + b v (-k x), x_0 = -1, by second moments."""
    m2, total = 1.0, 0.0
    for _ in range(steps):
        total += m2 * (1 + mu * k * k)
        m2 *= mu * (a - b * k) ** 2 + (1 - mu) * a * a
    return total + m2


def test_protocol_ranking_counterexample_exact():
    """A = -0.5, B = 1, N = 1, mu = 0.4: the UDP-like law is cheaper in closed loop (exact moments)."""
    s = pl.System(A=[[-0.5]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.4], x0=[-1.0])
    k_tcp = pl.closed_form(s, "tcp").gain[0, 0]
    k_udp = pl.closed_form(s, "udp").gain[0, 0]
    assert np.isclose(k_tcp, -0.5 / 1.4)
    assert np.isclose(k_udp, -0.5 / 2.0)
    tcp = _exact_scalar_closed_loop(-0.5, 1.0, k_tcp, 0.4, 40)
    udp = _exact_scalar_closed_loop(-0.5, 1.0, k_udp, 0.4, 40)
    assert udp < tcp
    sampled = closed_loop_costs(s, [np.array([[k_tcp]]), np.array([[k_udp]])], 40, 20000, np.random.default_rng(0))
    assert np.allclose(sampled.mean(axis=1), [tcp, udp], rtol=0.02)


def test_audit_recomputes_verdicts():
    results = {r.id: r for r in audit(random=12, seed=3)}
    assert set(results) == set(CLAIMS)
    for r in results.values():
        assert r.verdict in ("holds", "fails", "not-reproduced")
        assert r.checked > 0
        assert (r.violations == 0) == (r.verdict == "holds")
    for claim_id in ("theorem-1-costs", "lemma-3", "theorem-4", "expected-cost-tcp"):
        r = results[claim_id]
        assert r.verdict == "fails"
        assert r.counterexample is not None
        system_from_dict(r.counterexample)  # a valid System
    for claim_id in ("theorem-1-laws", "theorem-3", "lemma-2", "lemma-quad-expectation"):
        assert results[claim_id].verdict == "holds"
    assert "### theorem-4: fails" in markdown_report(list(results.values()))


def test_theorem_1_costs_counterexample_is_shrunk():
    r = audit(random=0, seed=1, only=["theorem-1-costs"])[0]
    s = system_from_dict(r.counterexample)
    assert s.n + s.m + s.horizon <= 4
    assert abs(pl.paper_optimal_cost(s, "tcp") - pl.closed_form(s, "tcp").cost) > 1e-3


def test_audit_cli_json(capsys):
    code = main(["audit", "--random", "3", "--seed", "2", "--json", "--claim", "theorem-2", "--claim", "lemma-2"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0
    assert [c["id"] for c in data["claims"]] == ["theorem-2", "lemma-2"]
    for c in data["claims"]:
        assert set(c) == {"id", "statement", "verdict", "checked", "violations", "worst", "counterexample", "note"}


def test_audit_cli_bad_claim(capsys):
    assert main(["audit", "--claim", "theorem-9"]) == 2
    assert "claim: unknown claim id" in capsys.readouterr().err
