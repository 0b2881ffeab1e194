"""The audit: counterexamples recomputed (not stored verdicts), and the CLI."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.claims import CLAIMS, audit, channel_allocation, markdown_report, markdown_table
from packetloss_cvx.claims.context import Context, paper_systems
from packetloss_cvx.claims.evaluate import evaluate, verdict
from packetloss_cvx.claims.ordering import optimal_plan
from packetloss_cvx.cli import main
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.montecarlo.sampling import closed_loop_costs, sample_plan_costs


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
    # the geometric series by hand: stage cost (1 + mu k^2) over 1 - (mu (a - b k)^2 + (1 - mu) a^2)
    assert np.isclose(tcp, (1 + 0.4 * k_tcp**2) / (1 - 0.4 / 49 - 0.15), rtol=1e-12)   # 1.2485
    assert np.isclose(udp, (1 + 0.4 * k_udp**2) / (1 - 0.4 / 16 - 0.15), rtol=1e-12)   # 1.2424
    assert udp < tcp  # by 0.5 %
    samples = 20000
    sampled = closed_loop_costs(s, [np.array([[k_tcp]]), np.array([[k_udp]])], 40, samples,
                                np.random.default_rng(0))
    se = sampled.std(axis=1, ddof=1) / np.sqrt(samples)
    assert np.all(np.abs(sampled.mean(axis=1) - [tcp, udp]) < 4 * se)
    # both laws see the same losses, so the difference is sampled far more finely than either cost
    d = sampled[1] - sampled[0]
    se_d = d.std(ddof=1) / np.sqrt(samples)
    assert abs(d.mean() - (udp - tcp)) < 4 * se_d
    assert d.mean() + 4 * se_d < 0  # the sampled ranking is resolved, not noise


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
        assert set(c) == {"id", "statement", "verdict", "checked", "violations", "errors", "worst", "counterexample",
                          "note", "outcomes"}
        assert c["errors"] == 0
        assert len(c["outcomes"]) == 2 + 3  # the paper's two systems, then the random ones


def test_audit_cli_bad_claim(capsys):
    assert main(["audit", "--claim", "theorem-9"]) == 2
    assert "claim: unknown claim id" in capsys.readouterr().err


# ---------------------------------------------------------------- honest verdicts
# A case whose check raises is *errored*: counted, named, never read as agreement.

def _overflowing_system() -> pl.System:
    """rho(A) = 10 over N = 400 steps with noise: every optimal cost is about 1e800, beyond double
    precision, so every closed form must raise (NumericalError) instead of answering."""
    return pl.System(A=[[10.0]], B=[[1.0]], horizon=400, state_weight=[1.0], input_weight=[1.0], mu=[0.5],
                     x0=[1.0], noise_cov=[[1.0]])


def test_verdict_rule():
    assert verdict(checked=3, violations=0, errors=0) == "holds"
    assert verdict(checked=3, violations=1, errors=0) == "fails"
    assert verdict(checked=3, violations=1, errors=2) == "fails"        # a proven violation stands
    assert verdict(checked=3, violations=0, errors=1) == "inconclusive"
    assert verdict(checked=0, violations=0, errors=0) == "inconclusive"  # nothing checked proves nothing


def test_claim_whose_every_case_errors_is_inconclusive():
    """Regression: this read "holds, checked 0" when the errored case was dropped like a skipped one."""
    bad = _overflowing_system()
    ctx = Context(paper={}, random=[bad], seed=0, extra=1)
    r = CLAIMS["theorem-3"][1](ctx)
    assert (r.verdict, r.checked, r.violations, r.errors, r.outcomes) == ("inconclusive", 0, 0, 1, "E")
    assert "system 1: NumericalError" in r.note


def test_audit_of_files_counts_the_system_that_errors():
    """Regression: audit FILE checked 2 systems of 3 without a word when one raised."""
    results = audit([_overflowing_system()], random=0, only=["theorem-3", "corollary-1"])
    for r in results:
        assert r.verdict == "inconclusive"
        assert (r.checked, r.errors) == (2, 1)          # pendulum and two_actuator checked, the file errored
        assert r.outcomes == "++E"
        assert "system 1: NumericalError" in r.note
    assert "| theorem-3 | inconclusive | 2 | 0 | 1 |" in markdown_table(results)
    assert "errors 1" in markdown_report(results)


def test_audit_cli_reports_the_errored_file(tmp_path, capsys):
    path = pl.save_system(_overflowing_system(), tmp_path / "overflow.toml")
    code = main(["audit", str(path), "--random", "0", "--json", "--claim", "theorem-3"])
    claim = json.loads(capsys.readouterr().out)["claims"][0]
    assert code == 0
    assert (claim["verdict"], claim["checked"], claim["errors"], claim["outcomes"]) == ("inconclusive", 2, 1, "++E")


def test_not_applicable_and_errored_are_distinct():
    ctx = Context(paper=paper_systems(), random=[], seed=0)
    pendulum, two_actuator = ctx.paper["pendulum"], ctx.paper["two_actuator"]

    def margin(s):
        if s is pendulum:
            return None                                   # the check says: does not apply
        raise np.linalg.LinAlgError("singular matrix")

    r = evaluate("theorem-2", ctx, [pendulum, two_actuator], margin, "note.")
    assert (r.verdict, r.checked, r.errors, r.outcomes) == ("inconclusive", 0, 1, ".E")
    assert r.note == "note. Errored (1, not counted as checked): two_actuator: LinAlgError: singular matrix."
    skipped = evaluate("theorem-2", ctx, [pendulum, two_actuator], lambda s: None, "note.")
    assert (skipped.verdict, skipped.checked, skipped.errors, skipped.outcomes) == ("inconclusive", 0, 0, "..")
    assert skipped.note == "note."


def test_violation_beside_an_error_fails_and_a_nan_margin_errors():
    ctx = Context(paper=paper_systems(), random=[], seed=0)
    pendulum, two_actuator = ctx.paper["pendulum"], ctx.paper["two_actuator"]
    r = evaluate("theorem-2", ctx, [pendulum, two_actuator], lambda s: -0.5 if s is pendulum else float("nan"),
                 "", shrinkable=False)
    assert (r.verdict, r.checked, r.violations, r.errors, r.worst, r.outcomes) == ("fails", 1, 1, 1, -0.5, "-E")
    assert "two_actuator: ArithmeticError: the margin is NaN" in r.note


def test_a_check_that_raises_outside_its_cases_is_inconclusive(monkeypatch):
    def broken(ctx):
        raise pl.NumericalError("overflow while building the table")

    monkeypatch.setitem(CLAIMS, "table-1", (CLAIMS["table-1"][0], broken))
    (r,) = audit(random=0, only=["table-1"])
    assert (r.verdict, r.checked, r.errors) == ("inconclusive", 0, 1)
    assert "NumericalError: overflow while building the table" in r.note


def test_holds_needs_something_checked_and_nothing_errored():
    with pytest.raises(ValueError, match="checked > 0"):
        pl.ClaimResult("x", "s", "holds", 0, 0, None, None, "")
    with pytest.raises(ValueError, match="checked > 0"):
        pl.ClaimResult("x", "s", "holds", 2, 0, 0.1, None, "", errors=1)
    with pytest.raises(ValueError, match="verdict"):
        pl.ClaimResult("x", "s", "maybe", 2, 0, 0.1, None, "")


def test_audit_refuses_a_negative_seed(capsys):
    """Regression: --seed -1 ended in numpy's ValueError, exit 1."""
    assert main(["audit", "--seed", "-1", "--random", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "--seed: expected an integer >= 0, found -1" in err
    with pytest.raises(pl.InputError, match="seed: expected an integer >= 0"):
        audit(random=0, seed=-1)
    with pytest.raises(pl.InputError, match="random: expected a count >= 0"):
        audit(random=-2)


def test_allocation_claim_counts_each_pair(monkeypatch):
    """The allocation claim's 18 (beta, alpha) cases through a stand-in allocator (the real one takes 7 s):
    a perfect channel holds, none violates, no feasible point is not applicable, a solver failure errors."""
    def stand_in_one(alpha, beta):
        if alpha == 6.0:
            return pl.SolverError("numerical trouble")       # the searches side by side hand errors back
        if alpha == 8.0:
            return None
        return (1.68, 1.0, 0.68) if (alpha, tuple(beta)) == (4.78, (1.0, 1.0)) else (0.5, 0.5, 0.0)

    def stand_in(system, protocol, cases, coarse, fine, tol):
        assert (protocol, coarse, fine, tol) == ("udp", 101, 21, 1e-8)
        return [stand_in_one(*case) for case in cases]

    monkeypatch.setattr(channel_allocation, "brute_force_allocations", stand_in)
    (r,) = audit(random=0, only=["allocation-udp-perfect-channel"])
    assert r.outcomes == "+E.---" + "-E.---" * 2
    assert (r.verdict, r.checked, r.violations, r.errors) == ("fails", 12, 11, 3)
    assert "beta=(1.0, 1.0), alpha=4.78: mu*=(1.000, 0.680)" in r.note
    assert "Errored (3, not counted as checked): beta=(1.0, 1.0), alpha=6.0: SolverError" in r.note

    def failing(*args, **kwargs):
        raise pl.SolverError("always")

    monkeypatch.setattr(channel_allocation, "brute_force_allocations", failing)
    (r,) = audit(random=0, only=["allocation-udp-perfect-channel"])
    assert (r.verdict, r.checked, r.errors, r.counterexample) == ("inconclusive", 0, 18, None)


def test_errored_cases_are_named_by_file_order_and_name():
    named = pl.System(A=[[10.0]], B=[[1.0]], horizon=400, state_weight=[1.0], input_weight=[1.0], mu=[0.5],
                      x0=[1.0], noise_cov=[[1.0]], name="overflow")
    (r,) = audit([pl.load_example("two_actuator"), named], random=1, only=["theorem-3"])
    assert r.outcomes == "++" + "+E" + "+"      # paper systems, the caller's two, one random
    assert "system 2 (overflow): NumericalError" in r.note


def _scalar(a: float, N: int, mu: float, x0: float = 1.0, noise: float | None = None) -> pl.System:
    extra = {} if noise is None else {"noise_cov": [[noise]]}
    return pl.System(A=[[a]], B=[[1.0]], horizon=N, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[x0],
                     **extra)



@pytest.mark.parametrize(("system", "claim"), [
    (_scalar(1.5, 30, 0.5), "lemma-2"),                                       # dense round-off: -2.3e-5
    (pl.load_example("two_actuator").with_x0([1e-12, 1e-12]), "theorem-3"),   # a 1e-9 floor on J*
    (_scalar(1.0, 3, 0.5, noise=1e17), "theorem-3"),                          # noise dwarfs the mu part
    (pl.load_example("two_actuator").with_x0([1e9, 1e9]), "theorem-1-laws"),  # absolute 1e-6 on inputs ~1e9
    (_scalar(0.5, 2, 1e-4), "lemma-1"),                                       # 2 deliveries in the sample
    (_scalar(0.5, 2, 1e-6), "lemma-quad-expectation"),                        # none: a "-inf" margin
])
def test_true_claims_are_not_reported_as_failing(system, claim):
    for seed in (1, 2):
        (result,) = audit([system], random=0, seed=seed, only=[claim])
        assert result.outcomes[-1] in "+.", (result.verdict, result.outcomes, result.note[-200:])
        assert result.verdict != "fails"
        assert result.to_dict()["worst"] is None or np.isfinite(result.to_dict()["worst"])



def test_cli_claim_flag_is_named_and_deduplicated(capsys):
    from packetloss_cvx.cli import main

    assert main(["audit", "--random", "0", "--claim", "nope"]) == 2
    assert capsys.readouterr().err.startswith("packetloss-cvx: error: --claim: unknown claim id 'nope'")
    assert main(["audit", "--random", "0", "--claim", "table-2", "--claim", "table-2", "--json"]) == 0
    import json

    assert [c["id"] for c in json.loads(capsys.readouterr().out)["claims"]] == ["table-2"]



def test_a_chain_file_is_audited_at_its_plug_in_rates_without_errors(capsys):
    """The paper's claims are stated for independent losses: a caller's Gilbert–Elliott system is audited
    at its plug-in mu_t (the closed-loop claims errored or were inconclusive on it)."""
    from packetloss_cvx.claims import audit

    results = audit([pl.load_example("pendulum_bursty")], random=0,
                    only=["mpc-vs-dp", "protocol-ranking-closed-loop", "theorem-2"])
    for result in results:
        assert result.errors == 0, (result.id, result.outcomes)
        assert result.outcomes[-1] in "+-.", (result.id, result.outcomes)


def test_stability_region_claim_bisects_each_paper_system_once(monkeypatch):
    """claims.region: the margin and the note's row come from one set of bisections per system (they ran twice),
    against the hand threshold of a scalar plant (1 - 1/a^2 along the ray); an error is still counted and named."""
    from packetloss_cvx.claims import region as claim
    from packetloss_cvx.errors import NumericalError

    s = pl.System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    calls = []
    real = claim.critical_shared_mu
    monkeypatch.setattr(claim, "critical_shared_mu", lambda system: calls.append(system) or real(system))
    result = claim.stability_region(Context(paper={"scalar": s}, random=[], seed=0))
    assert len(calls) == 1
    assert result.checked == 1
    assert "dp mu > 0.75000" in result.note

    def fails(system):
        raise NumericalError("no bracket")

    monkeypatch.setattr(claim, "critical_shared_mu", fails)
    result = claim.stability_region(Context(paper={"scalar": s}, random=[], seed=0))
    assert result.errors == 1
    assert "scalar: NumericalError" in result.note


@pytest.mark.parametrize(("factor", "checked"), [(3.0, 0), (0.3, 1)])
def test_lemma_2_skips_a_case_above_dense_max_condition_and_checks_one_below(factor, checked):
    """lemma-2 evaluates eq:cost-diff-deriv with dense inverses, so a case whose condition estimate is beyond
    DENSE_MAX_CONDITION is skipped (not checked, not an error); the integrator of tests/lq/test_costs.py puts the
    estimate at factor times the band: skipped at 3, checked (and holding) at 0.3."""
    from packetloss_cvx.claims.cost_difference import lemma_2
    from packetloss_cvx.tolerances import DENSE_MAX_CONDITION

    psi = 55.0 / (factor * DENSE_MAX_CONDITION - 1.0)
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=10, state_weight=[1.0], input_weight=[psi], mu=[0.7], x0=[1.0])
    r = lemma_2(Context(paper={}, random=[s], seed=0))
    assert (r.checked, r.errors, r.violations) == (checked, 0, 0)
    assert r.verdict == ("holds" if checked else "inconclusive")


@pytest.mark.parametrize(("factor", "verdict"), [(3.0, "fails"), (0.3, "holds")])
def test_plug_in_markov_holds_within_cross_check_cost_rtol_and_fails_beyond(monkeypatch, factor, verdict):
    """plug-in-markov's margin is CROSS_CHECK_COST_RTOL less the plug-in law's largest relative loss (the QP
    twin's cost agreement: a loss below it is not told apart from none): a planted loss of 3 times the band fails
    the claim, 0.3 times holds."""
    import packetloss_cvx.claims.markov as markov_claim
    from packetloss_cvx.tolerances import CROSS_CHECK_COST_RTOL

    monkeypatch.setattr(markov_claim, "_losses", lambda system: [0.0, factor * CROSS_CHECK_COST_RTOL])
    s = pl.System(A=[[1]], B=[[1]], horizon=2, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    r = markov_claim.plug_in_markov(Context(paper={}, random=[s], seed=0))
    assert (r.verdict, r.checked, r.errors) == (verdict, 1, 0)
    assert r.worst == pytest.approx((1 - factor) * CROSS_CHECK_COST_RTOL, rel=1e-12)


def test_the_audits_plans_come_from_its_cached_evaluators(two_actuator):
    ctx = Context(paper={"two_actuator": two_actuator}, random=[], seed=0)
    plan = optimal_plan(ctx, two_actuator, "udp")
    assert plan is ctx.evaluator(two_actuator, "udp").optimum()
    assert ctx.evaluator(two_actuator, "tcp").weights is ctx.evaluator(two_actuator, "udp").weights   # built once
    other = two_actuator.with_mu([0.3, 0.6])                                 # not a case: closed_form's answer
    assert optimal_plan(ctx, other, "udp").closed_loop_eigenvalues is not None
    assert abs(plan.cost - pl.closed_form(two_actuator, "udp").cost) <= 1e-12 * plan.cost
