"""Honest allocation: solver failures are errors, infeasibility needs a proof, lower
bounds are proved, caps give "gap_not_certified", and warnings stay captured."""

import json
import warnings

import numpy as np
import pytest

import packetloss_cvx as pl
import packetloss_cvx.allocation.api as api
import packetloss_cvx.allocation.boxes as boxes
import packetloss_cvx.allocation.tcp as tcp
from packetloss_cvx.allocation import allocate, min_cost, parse_constraint
from packetloss_cvx.allocation.brute_force import brute_force_allocation
from packetloss_cvx.allocation.tcp import tangent
from packetloss_cvx.cli import main
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.qp.convex import ClarabelProgram
from packetloss_cvx.tolerances import CROSS_CHECK_COST_RTOL

# A 3-channel allocation with prices beta = (2, 1, 1) and rows mu1 <= mu2, mu1 + mu2 >= 1.2, whose optimum puts
# mu3 = 0: a case where a solver failure could be read as infeasibility (the UDP-like path) and where the TCP-like
# SOCP is badly conditioned (quad-over-lin terms summed in one constraint) unless built term by term.
THREE_CHANNEL = {"A": [[0.53, 0.52, 0.92], [-0.2, 0.28, -0.19], [-0.72, -0.36, 0.07]],
           "B": [[-0.92, -0.19, 1.12], [0.57, 0.57, 0.35], [-0.18, -1.87, 0.99]], "horizon": 5,
           "state_weight": [[0.91, -1.1, -0.48], [-1.1, 1.68, 0.25], [-0.48, 0.25, 0.94]],
           "input_weight": [1.76, 1.83, 1.93], "mu": [0.5, 0.5, 0.5], "x0": [-1.51, 0.22, -0.11]}
THREE_CHANNEL_ROWS = ["mu1 <= mu2", "mu1 + mu2 >= 1.2"]
THREE_CHANNEL_PRICES = (2.0, 1.0, 1.0)


@pytest.fixture(scope="module")
def three_channel():
    return pl.System(**THREE_CHANNEL), [parse_constraint(t, 3) for t in THREE_CHANNEL_ROWS]


def qp_cost(system, protocol, mu):
    return pl.solve_qp(system.with_mu(mu), protocol, cross_check=False, with_gain=False).cost


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_three_channel_slack_cost_bound_is_met_at_the_cheapest_vertex(three_channel, protocol):
    """alpha = 9.4 is met with room to spare at mu = (0.2, 1, 0), which is also the vertex
    minimising beta'mu over the constraints (by hand: mu3 = 0, mu2 = 1, mu1 = 1.2 - mu2), so
    the optimum is exactly 1.4."""
    system, cons = three_channel
    assert qp_cost(system, protocol, [0.2, 1.0, 0.0]) < 9.4 / 2
    got = allocate(system, protocol, 9.4, THREE_CHANNEL_PRICES, constraints=cons)
    assert got.status == "optimal"
    assert np.allclose(got.mu, [0.2, 1.0, 0.0], atol=1e-8)
    assert got.lower_bound <= 1.4 + 1e-12
    assert got.communication_cost == pytest.approx(1.4, abs=1e-8)


def test_three_channel_active_cost_bound_is_met_with_a_proved_lower_bound(three_channel):
    """At alpha = 2.5 the cost bound is active: both protocols answer, feasibly by the QP twin,
    and the UDP-like cost respects the TCP-like lower bound (Theorem 2)."""
    system, cons = three_channel
    with warnings.catch_warnings():
        warnings.simplefilter("error")        # the tight SOCP attempt ends inaccurate here: captured
        t = allocate(system, "tcp", 2.5, THREE_CHANNEL_PRICES, constraints=cons)
        u = allocate(system, "udp", 2.5, THREE_CHANNEL_PRICES, constraints=cons)
    for got in (t, u):
        assert got.status == "optimal"
        assert qp_cost(system, got.protocol, got.mu) <= 2.5 * (1 + CROSS_CHECK_COST_RTOL)
        assert got.mu[0] <= got.mu[1] + 1e-9
        assert got.mu[0] + got.mu[1] >= 1.2 - 1e-9
    assert u.communication_cost >= t.lower_bound
    assert t.gap <= 1e-6                          # the tangent cuts are tight at the SOCP's optimum
    # A reference for the bounds: with mu3 = 0 the third actuator never acts, so the system
    # without it has the same cost; the brute force over (mu1, mu2) with mu3 = 0 is beta'mu at
    # a feasible point, never below the optimum, so never below a valid lower bound.
    reduced = pl.System(**{**THREE_CHANNEL, "B": np.array(THREE_CHANNEL["B"])[:, :2],
                           "input_weight": THREE_CHANNEL["input_weight"][:2], "mu": [0.5, 0.5]})
    assert qp_cost(reduced, "udp", [0.6, 0.9]) == pytest.approx(qp_cost(system, "udp", [0.6, 0.9, 0.0]), rel=1e-9)
    G = np.vstack([parse_constraint(text, 2)[0] for text in THREE_CHANNEL_ROWS])
    h = np.concatenate([parse_constraint(text, 2)[1] for text in THREE_CHANNEL_ROWS])
    for got in (t, u):
        ref = brute_force_allocation(reduced, got.protocol, 2.5, THREE_CHANNEL_PRICES[:2], G, h)
        assert got.lower_bound <= ref[0] + 1e-9


def test_three_channel_allocation_on_the_command_line_prints_one_answer_and_no_warning(three_channel, tmp_path,
                                                                                      capsys):
    system, _ = three_channel
    path = pl.save_system(system, tmp_path / "three_channel.toml")
    argv = ["allocate", str(path), "--protocol", "tcp", "--alpha", "2.5", "--beta", "2,1,1", "--json"]
    for text in THREE_CHANNEL_ROWS:
        argv += ["--constraint", text]
    assert main(argv) == 0
    out = capsys.readouterr()
    assert out.err == ""
    assert '"status": "optimal"' in out.out


def fail_the_socps(monkeypatch, status):
    """The TCP-like allocation SOCPs (and only they: the QP twin's condensed problems run through the same
    ClarabelProgram) end with ``status`` and no point."""
    solve = ClarabelProgram.solve

    def failing(self, values, what, attempts=()):
        return (status, None) if "SOCP" in what else solve(self, values, what, attempts)
    monkeypatch.setattr(ClarabelProgram, "solve", failing)


@pytest.mark.parametrize("status", ["optimal_inaccurate", "infeasible_inaccurate", "solver_error"])
def test_solver_failure_is_an_error_not_infeasibility(two_actuator, monkeypatch, status):
    fail_the_socps(monkeypatch, status)
    with pytest.raises(pl.SolverError) as info:
        allocate(two_actuator, "tcp", 4.78, (1.0, 1.0))
    assert info.value.status == status


def test_udp_without_the_tcp_bound_still_certifies(two_actuator, monkeypatch):
    """A failed TCP-like relaxation only removes a shortcut: the branch and bound certifies alone
    and says so, and proves infeasibility alone (never from the failure)."""
    fail_the_socps(monkeypatch, "optimal_inaccurate")
    got = allocate(two_actuator, "udp", 8.0, (1.0, 0.05))
    ref = brute_force_allocation(two_actuator, "udp", 8.0, (1.0, 0.05))
    assert got.status == "optimal"
    assert "TCP-like bound unavailable" in got.method
    assert got.lower_bound <= ref[0] + 1e-9
    assert got.communication_cost <= ref[0] / (1 - 1e-4) + 1e-9
    # with mu1 <= 0.5 the least J*_udp is 7.85 at (0.5, 1) (J*_tcp there 2.40): infeasible at 5
    assert qp_cost(two_actuator, "udp", [0.5, 1.0]) > 7.8
    with pytest.raises(pl.InfeasibleError, match=r"every box was proven infeasible"):
        allocate(two_actuator, "udp", 5.0, (1.0, 1.0), constraints=[parse_constraint("mu1 <= 0.5", 2)])


def test_lp_failure_propagates(two_actuator, monkeypatch):
    class Failed:
        status, message = 4, "numerical difficulties"

    monkeypatch.setattr(boxes, "highs_optimum", lambda *args: None)     # HiGHS called directly finds no optimum:
    monkeypatch.setattr(boxes, "linprog", lambda *args, **kwargs: Failed())     # linprog reports why
    with pytest.raises(pl.SolverError, match="linprog status 4"):
        allocate(two_actuator, "udp", 6.0, (1.0, 1.0), constraints=[parse_constraint("mu1 >= mu2", 2)])


def test_no_infeasibility_while_a_feasible_point_is_known(two_actuator, monkeypatch):
    """Were a search to claim infeasibility wrongly, the least reachable cost (computed for the
    message) contradicts it, and the answer is a SolverError, not 'infeasible'."""
    def wrong(*args, **kwargs):
        raise pl.InfeasibleError("a search that lost its way", None)

    monkeypatch.setattr(api, "udp_allocate", wrong)
    with pytest.raises(pl.SolverError, match="inconsistent"):
        allocate(two_actuator, "udp", 6.0, (1.0, 1.0))


def test_tcp_lower_bound_does_not_rest_on_the_solver_tolerance(two_actuator, monkeypatch):
    """With Clarabel stopped at a 1e-3 gap the SOCP's point is off; the point is still moved to
    feasibility and the bound (tangent cuts at that point, before the move) is still below the
    brute-force optimum; the status tells whether the requested gap was reached."""
    loose = ({"tol_gap_abs": 1e-3, "tol_gap_rel": 1e-3, "tol_feas": 1e-3, "max_iter": 200},)
    monkeypatch.setattr(tcp, "ALLOCATION_TCP_ATTEMPTS", loose)
    ref = brute_force_allocation(two_actuator, "tcp", 4.78, (1.0, 1.0))
    for gap in (1e-2, 1e-9):
        got = allocate(two_actuator, "tcp", 4.78, (1.0, 1.0), gap=gap)
        assert got.cost <= 4.78
        assert got.lower_bound <= ref[0] + 1e-9
        assert got.status == ("optimal" if got.gap <= gap else "gap_not_certified")
    assert got.status == "gap_not_certified"                  # 1e-9 is out of reach from a 1e-3 solve


@pytest.mark.parametrize("mu", [[0.3, 0.6], [1.0, 0.2], [0.0, 0.5]])
def test_tangent_is_the_gradient(two_actuator, mu):
    """The envelope-theorem gradient against central (one-sided at 0 and 1) finite differences
    of the cost alone (the recursion)."""
    _, grad = tangent(two_actuator, np.array(mu))
    h = 1e-6
    for i in range(2):
        lo, hi = np.array(mu, dtype=float), np.array(mu, dtype=float)
        lo[i], hi[i] = max(mu[i] - h, 0.0), min(mu[i] + h, 1.0)
        diff = (pl.closed_form(two_actuator.with_mu(hi), "tcp", "recursion").cost
                - pl.closed_form(two_actuator.with_mu(lo), "tcp", "recursion").cost) / (hi[i] - lo[i])
        assert grad[i] == pytest.approx(diff, rel=1e-3 if 0 < mu[i] < 1 else 1e-2)


def test_box_cap_gives_gap_not_certified(two_actuator):
    ref = brute_force_allocation(two_actuator, "udp", 4.78, (1.0, 1.0))
    got = allocate(two_actuator, "udp", 4.78, (1.0, 1.0), max_boxes=2)
    assert got.status == "gap_not_certified"
    assert got.boxes == 2
    assert "cap of 2 boxes" in got.method
    assert got.gap > 1e-4
    assert got.gap == pytest.approx((got.communication_cost - got.lower_bound) / got.communication_cost)
    assert got.lower_bound <= ref[0] + 1e-9                       # still a proven bound
    assert qp_cost(two_actuator, "udp", got.mu) <= 4.78 * (1 + CROSS_CHECK_COST_RTOL)


def test_time_limit_gives_gap_not_certified(two_actuator):
    got = allocate(two_actuator, "udp", 4.78, (1.0, 1.0), time_limit=1e-9)     # the root box is still visited
    assert got.status == "gap_not_certified"
    assert got.boxes == 1
    assert "time limit" in got.method
    assert got.lower_bound <= brute_force_allocation(two_actuator, "udp", 4.78, (1.0, 1.0))[0] + 1e-9


def test_cap_before_any_feasible_point_is_an_error(two_actuator):
    """On mu1 <= mu2, mu1 + mu2 <= 1 the maximal points (0, 1) and (0.5, 0.5) cost 17.1 and 18.5
    while (0.1, 0.9) costs 16.3: one box finds nothing feasible and proves nothing either."""
    cons = [parse_constraint("mu1 <= mu2", 2), parse_constraint("mu1 + mu2 <= 1", 2)]
    assert qp_cost(two_actuator, "udp", [0.1, 0.9]) < 16.5
    with pytest.raises(pl.SolverError, match="no feasible mu found and infeasibility not proven") as info:
        allocate(two_actuator, "udp", 16.5, (1.0, 1.0), constraints=cons, max_boxes=1)
    assert info.value.status == "gap_not_certified"


def test_min_cost_cap_is_reported(two_actuator):
    cons = [parse_constraint("mu1 + mu2 <= 1.2", 2)]
    capped = min_cost(two_actuator, "udp", constraints=cons, max_boxes=1)
    full = min_cost(two_actuator, "udp", constraints=cons)
    assert capped.status == "gap_not_certified"
    assert full.status == "optimal"
    assert capped.lower_bound <= full.cost
    assert full.lower_bound <= full.cost <= capped.cost
    assert full.cost == pytest.approx(qp_cost(two_actuator, "udp", full.mu), rel=CROSS_CHECK_COST_RTOL)


def test_cli_gap_not_certified_exit_4(capsys):
    code = main(["allocate", "two_actuator", "--protocol", "udp", "--alpha", "4.78", "--beta", "1,1",
                 "--max-boxes", "2", "--json"])
    out = capsys.readouterr()
    assert code == 4
    data = json.loads(out.out)
    assert data["status"] == "gap_not_certified"
    assert data["boxes"] == 2
    assert data["gap"] > 1e-4
    assert data["lower_bound"] <= brute_force_allocation(pl.load_example("two_actuator"), "udp", 4.78, (1, 1))[0] + 1e-9
    assert out.err == ""
    main(["allocate", "two_actuator", "--protocol", "udp", "--alpha", "4.78", "--beta", "1,1", "--max-boxes", "2"])
    assert capsys.readouterr().out.startswith("UDP-like: GAP NOT CERTIFIED")


def test_a_cap_of_one_box_is_singular(capsys):
    # 0ed6b71 made the method line say '1 box'; the same line still said 'stopped at the cap of 1 boxes'
    assert main(["allocate", "two_actuator", "--protocol", "udp", "--alpha", "3", "--beta", "1,1",
                 "--max-boxes", "1", "--quiet"]) == 4
    text = capsys.readouterr().out
    assert "stopped at the cap of 1 box;" in text
    assert "1 boxes" not in text



def test_tcp_gap_not_certified_gives_advice_that_applies(capsys):
    from packetloss_cvx.cli import main

    code = main(["allocate", "two_actuator", "--protocol", "tcp", "--alpha", "8", "--beta", "1,1", "--gap", "1e-9"])
    out = capsys.readouterr().out
    assert code == 4
    assert "ask for a larger --gap" in out
    assert "--max-boxes" not in out    # the caps do not apply to the TCP-like SOCP


@pytest.mark.parametrize("seed", range(3))
def test_udp_certificate_survives_wrong_probes(two_actuator, monkeypatch, seed):
    """The UDP-like search steers by unchecked probes (CostEvaluator.cost / line with checked=False) and takes
    its three certificate decisions (discard a box, raise an edge's lower end, offer an incumbent) on checked
    values only: with every probe off by a factor 0.5 or 2 at random, the answer is still feasible and the
    bound still below the brute-force optimum (the TCP-like bound switched off, so the boxes must prove it)."""
    from packetloss_cvx.lq.evaluator import CostEvaluator

    rng = np.random.default_rng(seed)
    cost, line = CostEvaluator.cost, CostEvaluator.line

    def wrong_cost(self, mu, x0=None, checked=True):
        value = cost(self, mu, x0, checked)
        return value if checked else value * rng.choice([0.5, 2.0])

    def wrong_line(self, mu, i, checked=True):
        f = line(self, mu, i, checked)
        return f if checked else (lambda s: f(s) * rng.choice([0.5, 2.0]))

    # the TCP-like bound switched off: its SOCP never ends 'optimal' (SolverError), so the boxes must prove it
    fail_the_socps(monkeypatch, "optimal_inaccurate")
    ref = brute_force_allocation(two_actuator, "udp", 8.0, (1.0, 0.05))
    monkeypatch.setattr(CostEvaluator, "cost", wrong_cost)
    monkeypatch.setattr(CostEvaluator, "line", wrong_line)
    got = allocate(two_actuator, "udp", 8.0, (1.0, 0.05))
    assert qp_cost(two_actuator, "udp", got.mu) <= 8.0 * (1 + 1e-7)          # feasible, by the QP twin
    assert got.lower_bound <= ref[0] + 1e-9
    assert got.status == "optimal"
    assert got.communication_cost <= ref[0] / (1 - 1e-4) + 1e-9


@pytest.mark.parametrize(("slope", "curve"), [(1e-3, 0.0), (1e-3, 0.45), (2.0, 0.25)])
def test_line_search_reaches_alpha_within_tol_in_few_evaluations(slope, curve):
    """allocation.boxes.bracket aims at alpha (1 - ALLOCATION_AIM_RTOL): where alpha's own crossing lies far more
    than tol beyond that aim (a shallow J*: here 1e-7 away at tol = 1e-9), it still ends with the contract
    (f(s_in) <= alpha < f(s_out), s_in - s_out <= tol; the crossing by hand between them) in at most
    4 log2((b - a) / tol) evaluations, as its docstring says (it crept by tol / 4: 300-800 evaluations)."""
    def f(t):
        calls.append(t)
        return 1.0 - slope * t + curve * slope * t * t

    for crossing in (0.25, 0.4, 0.7):
        calls: list = []
        alpha = 1.0 - slope * crossing + curve * slope * crossing ** 2
        s_in, s_out = boxes.bracket(f, alpha, 0.0, 1.0, 1e-9)
        assert f(s_in) <= alpha < f(s_out)
        assert 0.0 < s_in - s_out <= 1e-9
        assert s_out < crossing * (1 + 1e-12)
        assert crossing * (1 - 1e-12) < s_in
        assert len(calls) - 2 <= 4 * np.log2(1.0 / 1e-9)


def test_udp_incumbent_line_starts_from_the_checked_value_after_a_wrong_probe(two_actuator, monkeypatch):
    """Each box's LP point p is probed, then checked where the probe says feasible; where the check says not, the line
    from p toward the box's maximal point must start from p's checked value (the probe asked again answers from the
    checked memory). Here every probe at an LP point not yet checked says 'feasible' (min(J, alpha)), and the search
    has no start and no bound from elsewhere: it still ends optimal, feasible and within its gap of the brute-force
    optimum. (Taking the first, wrong probe as the line's value at p ended every such line at p itself: no incumbent,
    SolverError 'gap_not_certified'.)"""
    from packetloss_cvx.allocation import udp
    from packetloss_cvx.allocation.grammar import read_polytope
    from packetloss_cvx.lq.evaluator import CostEvaluator

    alpha, beta, lp_points = 8.0, np.array([1.0, 0.05]), set()
    box_bound = udp.box_bound

    def recording_box_bound(*args, **kwargs):
        out = box_bound(*args, **kwargs)
        if out is not None:
            lp_points.add(np.asarray(out[3], dtype=float).clip(0.0, 1.0).tobytes())
        return out

    class OptimisticAtLpPoints(udp.MonotoneCost):
        def probe(self, x):
            key = np.asarray(x, dtype=float).clip(0.0, 1.0).tobytes()
            value = super().probe(x)
            return min(value, alpha) if key in lp_points and key not in self.known else value

    ref = brute_force_allocation(two_actuator, "udp", alpha, tuple(beta))
    monkeypatch.setattr(udp, "box_bound", recording_box_bound)
    got = udp.udp_allocate(two_actuator, read_polytope([], 2, 0.0, 1.0), alpha, beta, 1e-4, -np.inf, 3000, None,
                           cost=OptimisticAtLpPoints(CostEvaluator(two_actuator, "udp")))
    assert lp_points                                                          # the wrong probes were asked
    assert got.status == "optimal"
    assert qp_cost(two_actuator, "udp", got.mu) <= alpha * (1 + 1e-7)        # feasible, by the QP twin
    assert got.lower_bound <= ref[0] + 1e-9
    assert got.value <= ref[0] / (1 - 1e-4) + 1e-9


def test_a_relaxation_whose_cuts_are_not_finite_is_a_numerical_error_and_the_udp_search_goes_without_it():
    """An input weight of 1e-300 beside 1 makes J*_tcp's tangent cuts nan near the SOCP's point: the TCP-like
    allocation raises a typed NumericalError (it was SciPy's ValueError from linprog, an untyped 'bad input'); the
    UDP-like search proceeds without that bound, as it does when the SOCP fails, and its answer is certified."""
    data = pl.load_example("two_actuator").to_dict()
    data["cost"]["input_weight"] = [1e-300, 1.0]
    system = system_from_dict(data)
    with pytest.raises(pl.NumericalError, match="not finite at a tangent point"):
        allocate(system, "tcp", 5.0, (1.0, 1.0))
    got = allocate(system, "udp", 5.0, (1.0, 1.0))
    assert got.status == "optimal"
    assert "TCP-like bound unavailable" in got.method
    assert got.cost <= 5.0 * (1 + 1e-9)
    assert got.lower_bound <= got.communication_cost
    worse = got.mu * (1 - 1e-3)                          # a cheaper channel pair just below the answer is infeasible
    assert pl.closed_form(system.with_mu(worse), "udp", method="recursion").cost > 5.0


@pytest.mark.parametrize(("alpha", "tol"), [(0.5, 1e-9), (0.5, 1e-6), (0.25, 1e-6)])
def test_line_search_aims_allocation_aim_rtol_inside_alpha(alpha, tol):
    """allocation.boxes.bracket interpolates toward alpha (1 - ALLOCATION_AIM_RTOL), not alpha: on a straight line
    f(t) = 1 - t the first secant lands on that level exactly, and every later step is above alpha (outside), so the
    point it returns inside is ALLOCATION_AIM_RTOL alpha below alpha (by hand; to 1e-6 of that margin)."""
    from packetloss_cvx.allocation.boxes import bracket
    from packetloss_cvx.tolerances import ALLOCATION_AIM_RTOL

    s_in, s_out = bracket(lambda t: 1.0 - t, alpha, 0.0, 1.0, tol)
    assert 0.0 < s_in - s_out <= tol
    assert (alpha - (1.0 - s_in)) / alpha == pytest.approx(ALLOCATION_AIM_RTOL, rel=1e-6)
