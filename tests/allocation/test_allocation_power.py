"""Power-limited links (allocation/power.py): the models, the two problems for both protocols,
against hand values (one channel: invert mu(P) at the mu the scalar problem needs), decoupled plants
(a one-dimensional search over the split of the budget), a grid of P, and the mu allocation."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from packetloss_cvx import System, load_system
from packetloss_cvx.allocation import allocate
from packetloss_cvx.allocation.ack import ack_break_even, best_protocol
from packetloss_cvx.allocation.delivery import power_model
from packetloss_cvx.allocation.power import least_cost_within_power, least_power, power_pareto
from packetloss_cvx.cli import main
from packetloss_cvx.errors import InfeasibleError, InputError
from packetloss_cvx.lq.evaluator import CostEvaluator
from tests.allocation.test_allocation_delivery import MODELS, model_of


def scalar() -> System:
    """One step of x' = x + v u from x0 = 1, Q = R = 1: J*_tcp = 1/(1 + mu), J*_udp = 1 - mu/2."""
    return System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])


def decoupled(w=(1.0, 3.0)) -> System:
    """Two such plants side by side, x0_i = sqrt(w_i): J*_tcp = sum w_i/(1 + mu_i), J*_udp = sum w_i (1 - mu_i/2)."""
    return System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
                  mu=[0.5, 0.5], x0=np.sqrt(w))


def hand_cost(protocol, mu, w):
    mu = np.asarray(mu, dtype=float)
    return float(np.sum(np.asarray(w) / (1 + mu))) if protocol == "tcp" else float(np.sum(np.asarray(w) * (1 - mu / 2)))


def hand_costs(protocol, mu, w):
    """hand_cost at each row of mu (k, m) in one pass: the same sums, bit for bit."""
    w = np.asarray(w)
    return np.sum(w / (1 + mu), axis=-1) if protocol == "tcp" else np.sum(w * (1 - mu / 2), axis=-1)


def hand_power(name, mu):
    """The least power reaching mu, by hand from each model's formula."""
    if name == "exponential":
        return -1.5 * np.log(1 - mu)
    if name == "rayleigh":
        return -0.7 / np.log(mu)
    table = np.array(MODELS[name]["table"])
    return float(np.interp(mu, table[:, 1], table[:, 0]))


# ------------------------------------------------------------------ one channel: hand values

@pytest.mark.parametrize("name", ["exponential", "rayleigh", "table", "table-s"])
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_power_one_channel_inverts_the_model(name, protocol):
    alpha = 0.8
    need = 0.25 if protocol == "tcp" else 0.4          # 1/(1 + mu) = 0.8, 1 - mu/2 = 0.8
    out = least_power(scalar(), protocol, model_of(name), alpha, gap=1e-6)
    P = hand_power(name, need)
    assert out.status == "optimal"
    assert out.cost <= alpha
    assert out.lower_bound <= P * (1 + 1e-9)
    assert P <= out.total_power <= P * (1 + 1e-5)


@pytest.mark.parametrize("name", ["exponential", "rayleigh", "table", "table-s"])
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_cost_one_channel_spends_the_budget(name, protocol):
    budget = 1.7
    out = least_cost_within_power(scalar(), protocol, model_of(name), budget, gap=1e-7)
    mu = model_of(name).mu(np.array([budget]))[0]
    assert np.isclose(out.cost, hand_cost(protocol, [mu], [1.0]), rtol=1e-7)
    assert out.lower_bound <= hand_cost(protocol, [mu], [1.0]) * (1 + 1e-12)
    assert out.status == "optimal"


# ------------------------------------------------------------------ decoupled plants: a 1-D reference

def split_reference(protocol, name, budget, w):
    """min over s in [0, B] of the hand cost at powers (s, B - s): the budget is spent (J* falls in P)."""
    model = model_of(name, 2)

    def f(s):
        return hand_cost(protocol, model.mu(np.array([s, budget - s])), w)

    grid = np.linspace(0, budget, 2001)
    k = int(np.argmin(hand_costs(protocol, model.mu(np.stack([grid, budget - grid], axis=1)), w)))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    best = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-10})
    return min(best.fun, f(grid[k]))


@pytest.mark.parametrize("name", ["exponential", "table", "table-s", "rayleigh"])
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_cost_decoupled_against_the_split_of_the_budget(name, protocol):
    w, gap = (1.0, 3.0), 1e-4
    out = least_cost_within_power(decoupled(w), protocol, model_of(name, 2), 2.5, gap=gap)
    ref = split_reference(protocol, name, 2.5, w)
    assert out.lower_bound <= ref * (1 + 1e-9)
    assert out.cost <= ref * (1 + gap)
    assert out.total_power <= 2.5 * (1 + 1e-9)


@pytest.mark.parametrize("name", ["exponential", "table-s"])
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_power_decoupled_against_a_root_per_budget(name, protocol):
    """The least power P is the least budget whose least cost reaches alpha: bisect on the 1-D reference."""
    w, alpha, gap = (1.0, 3.0), 2.9, 1e-4
    out = least_power(decoupled(w), protocol, model_of(name, 2), alpha, gap=gap)
    total = brentq(lambda b: split_reference(protocol, name, b, w) - alpha, 1e-6, 40.0, xtol=1e-10)
    assert out.cost <= alpha
    assert out.lower_bound <= total * (1 + 1e-6)
    assert out.total_power <= total * (1 + gap)


# ------------------------------------------------------------------ the paper's system: a grid of P

@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_cost_two_actuator_against_a_grid_on_the_budget(protocol):
    s, budget = load_system("two_actuator"), 3.0
    model = power_model("exponential", 2, scale=[1.0, 2.0])
    out = least_cost_within_power(s, protocol, model, budget)
    ev = CostEvaluator(s, protocol)
    grid = np.linspace(0, budget, 3001)
    ref = min(ev.costs(model.mu(np.stack([grid, budget - grid], axis=1))))
    assert out.lower_bound <= ref * (1 + 1e-9)
    assert out.cost <= ref * (1 + 1e-4)
    assert np.isclose(out.cost, ev.cost(model.mu(out.power)), rtol=1e-12)


def test_pareto_curve_falls_and_each_point_is_certified():
    s = load_system("two_actuator")
    model = power_model("exponential", 2, scale=[1.0, 2.0])
    curve = power_pareto(s, "tcp", model, [4.0, 0.0, 1.0, 2.0])
    costs = [p.cost for p in curve]
    assert [p.limit for p in curve] == [0.0, 1.0, 2.0, 4.0]
    assert all(np.diff(costs) < 0)
    assert np.isclose(costs[0], CostEvaluator(s, "tcp").cost(np.zeros(2)), rtol=1e-12)
    assert all(p.status == "optimal" and p.lower_bound <= p.cost for p in curve)


# ------------------------------------------------------------------ the mu allocation where the problems coincide

@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_linear_model_is_the_mu_allocation_with_beta_c(protocol):
    """mu = P / c_i up to P = c_i (a two-row table per channel): total power = c' mu, the paper's beta'mu."""
    s, c, alpha = load_system("two_actuator"), np.array([2.0, 0.5]), 8.0
    model = power_model("table", 2, table=[[0.0, 0.0, 0.0], [0.5, 0.25, 1.0], [2.0, 1.0, 1.0]])   # mu_i = P / c_i
    assert np.allclose(model.mu(np.array([1.0, 0.25])), [0.5, 0.5])
    out = least_power(s, protocol, model, alpha, gap=1e-6)
    ref = allocate(s, protocol, alpha, c, gap=1e-6)
    assert np.isclose(out.total_power, ref.communication_cost, rtol=2e-6)
    assert out.lower_bound <= ref.communication_cost * (1 + 1e-9)
    assert ref.lower_bound <= out.total_power


def test_tcp_exponential_optimum_is_the_mu_allocation_at_the_marginal_prices():
    """At the power optimum mu*, the mu allocation with prices beta_i = dP_i/dmu_i = c_i / (1 - mu*_i) (the
    power's linearisation there) has the same KKT conditions with the same multiplier: it returns mu*."""
    s, c, alpha = load_system("two_actuator"), np.array([1.0, 2.0]), 8.0
    out = least_power(s, "tcp", power_model("exponential", 2, scale=c), alpha, gap=1e-7)
    ref = allocate(s, "tcp", alpha, c / (1 - out.mu), gap=1e-7)
    assert np.allclose(ref.mu, out.mu, atol=2e-4)
    assert np.isclose(c @ -np.log1p(-ref.mu), out.total_power, rtol=1e-5)


# ------------------------------------------------------------------ errors

def test_infeasible_and_bad_arguments():
    s = load_system("two_actuator")
    model = power_model("exponential", 2, scale=1.0)
    floor = CostEvaluator(s, "tcp").cost(np.ones(2))
    with pytest.raises(InfeasibleError, match="J\\*_tcp at the largest powers"):
        least_power(s, "tcp", model, floor * 0.99)
    with pytest.raises(InputError, match="budget: expected a total power >= 0"):
        least_cost_within_power(s, "tcp", model, -1.0)
    with pytest.raises(InputError, match="model: the model has 1 channels"):
        least_power(s, "tcp", power_model("exponential", 1, scale=1.0), 8.0)
    with pytest.raises(InputError, match="max_power"):
        least_power(s, "tcp", model, 8.0, max_power=[1.0, 0.0])
    with pytest.raises(InfeasibleError):
        least_cost_within_power(s, "tcp", model, 1.0, constraints=[([[-1.0, 0.0]], [-2.0])])     # P1 >= 2 > budget


def test_constraints_on_power_are_met():
    s = load_system("two_actuator")
    model = power_model("exponential", 2, scale=[1.0, 2.0])
    free = least_power(s, "tcp", model, 8.0)
    out = least_power(s, "tcp", model, 8.0, constraints=[([[1.0, -1.0]], [0.0])], gap=1e-6)     # P1 <= P2
    assert out.power[0] <= out.power[1] + 1e-9
    assert out.cost <= 8.0
    assert out.total_power >= free.lower_bound * (1 - 1e-9)
    capped = least_power(s, "udp", model, 8.0, max_power=3.0)
    assert np.all(capped.power <= 3.0 + 1e-12)
    assert capped.cost <= 8.0


# ------------------------------------------------------------------ the command line

def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_least_power_json_holds_the_contract(capsys):
    code, out, _ = run_cli(capsys, "allocate", "two_actuator", "--protocol", "tcp", "--alpha", "8", "--power",
                           "exponential", "--power-scale", "1,2", "--json")
    data = json.loads(out)
    assert code == 0
    assert data["status"] == "optimal"
    assert {"power", "total_power", "mu", "cost", "status", "gap"} <= set(data)
    model = power_model("exponential", 2, scale=[1.0, 2.0])
    assert np.isclose(sum(data["power"]), data["total_power"])
    assert np.allclose(model.mu(data["power"]), data["mu"])
    assert data["cost"] <= 8.0
    assert np.isclose(data["cost"], CostEvaluator(load_system("two_actuator"), "tcp").cost(
        np.array(data["mu"])), rtol=1e-12)


def test_cli_budget_and_the_file_power_table(capsys, tmp_path):
    from packetloss_cvx.model.files import dumps_system
    (tmp_path / "link.csv").write_text("# measured\npower,mu\n0,0\n1,0.5\n3,0.9\n")
    (tmp_path / "s.toml").write_text(dumps_system(scalar()) + '\n[power]\nmodel = "table"\ntable = "link.csv"\n')
    code, out, _ = run_cli(capsys, "allocate", str(tmp_path / "s.toml"), "--protocol", "udp", "--budget", "2",
                           "--json")
    data = json.loads(out)
    assert code == 0
    assert np.isclose(data["power"][0], 2.0)
    assert np.isclose(data["mu"][0], 0.7)
    assert np.isclose(data["cost"], 1 - 0.7 / 2, rtol=1e-9)


@pytest.mark.parametrize(("argv", "match"), [
    (["--alpha", "8", "--power", "exponential", "--power-scale", "0,1"], "--power-scale: expected positive"),
    (["--budget", "-1", "--power", "exponential", "--power-scale", "1"], "--budget: expected a total power >= 0"),
    (["--alpha", "8", "--power", "table", "--power-table", "{bad}"], "--power-table: mu must not fall"),
    (["--alpha", "8", "--power", "table", "--power-table", "{out}"], r"--power-table: mu must lie in \[0, 1\]"),
    (["--alpha", "8", "--power", "exponential"], "--power-scale: the exponential model needs a scale"),
    (["--budget", "2"], "--power: give a model"),
    (["--alpha", "8"], "--beta: required"),
    (["--alpha", "8", "--budget", "2", "--power", "exponential", "--power-scale", "1"], "--budget: give --alpha"),
    (["--alpha", "8", "--power", "exponential", "--power-scale", "1", "--constraint", "mu1 <= 2"],
     "--constraint: cannot parse"),
])
def test_cli_bad_power_input_exits_2_with_one_line(capsys, tmp_path, argv, match):
    (tmp_path / "bad.csv").write_text("0,0\n1,0.5\n2,0.4\n")
    (tmp_path / "out.csv").write_text("0,0\n1,1.5\n")
    argv = [a.format(bad=tmp_path / "bad.csv", out=tmp_path / "out.csv") for a in argv]
    code, out, err = run_cli(capsys, "allocate", "two_actuator", "--protocol", "tcp", *argv)
    assert code == 2
    assert out == ""
    assert len(err.splitlines()) == 1
    assert re.search(match, err), err


def test_cli_infeasible_power_exits_3(capsys):
    code, out, _ = run_cli(capsys, "allocate", "two_actuator", "--protocol", "tcp", "--alpha", "1", "--power",
                           "exponential", "--power-scale", "1,2", "--json")
    assert code == 3
    assert json.loads(out)["status"] == "infeasible"


def test_cli_best_protocol_prices_the_ack_link(capsys):
    """--protocol best: the choice flips where the ack price crosses the break-even price both designs give."""
    argv = ["allocate", "two_actuator", "--protocol", "best", "--alpha", "8", "--beta", "1,1", "--json"]
    code, out, _ = run_cli(capsys, *argv, "--ack-price", "0")
    free = json.loads(out)
    tcp = allocate(load_system("two_actuator"), "tcp", 8.0, [1.0, 1.0])
    udp = allocate(load_system("two_actuator"), "udp", 8.0, [1.0, 1.0])
    assert code == 0
    assert free["choice"] == "tcp"
    assert np.isclose(free["break_even_ack_price"], udp.communication_cost - tcp.communication_cost, rtol=1e-3)
    code, out, _ = run_cli(capsys, *argv, "--ack-price", str(free["break_even_ack_price"] * 1.01))
    assert code == 0
    assert json.loads(out)["choice"] == "udp"
    code, out, _ = run_cli(capsys, "allocate", "two_actuator", "--protocol", "best", "--alpha", "8", "--power",
                           "exponential", "--power-scale", "1,2", "--ack-power", "0.5", "--json")
    data = json.loads(out)
    assert code == 0
    assert np.isclose(data["tcp_total"], data["tcp"]["total_power"] + 0.5)


# ------------------------------------------------------------------ the acknowledgement link priced

def test_ack_break_even_one_channel_against_hand_values():
    """One step of x' = x + v u: TCP-like needs mu = 1/alpha - 1, UDP-like mu = 2 (1 - alpha) (beta = 1)."""
    alphas = np.array([0.6, 0.75, 0.9])
    study = ack_break_even(scalar(), alphas, [1.0], gap=1e-8)
    assert np.allclose(study["tcp_total"], 1 / alphas - 1, rtol=1e-6)
    assert np.allclose(study["break_even"], 2 * (1 - alphas) - (1 / alphas - 1), atol=1e-6)
    power = ack_break_even(scalar(), [0.8], model=power_model("exponential", 1, scale=1.0), gap=1e-8)
    assert np.isclose(power["break_even"][0], -np.log1p(-0.4) - -np.log1p(-0.25), rtol=1e-5)


def test_best_protocol_refuses_a_price_below_zero_and_proves_infeasibility():
    with pytest.raises(InputError, match="ack_price"):
        best_protocol(scalar(), 0.8, [1.0], ack_price=-1.0)
    with pytest.raises(InfeasibleError, match="no TCP-like design"):
        best_protocol(scalar(), 0.4, [1.0])                            # J*_tcp >= 1/2
    dear = best_protocol(scalar(), 0.55, [1.0], ack_price=5.0)        # a dear link: UDP-like (mu = 0.9) wins
    assert dear.choice == "udp"
    assert dear.certified
    only = best_protocol(scalar(), 0.54, [1.0], bounds=(0.0, 0.9))      # TCP-like mu = 0.852, UDP-like 0.92 > 0.9
    assert only.udp is None
    assert only.choice == "tcp"
    assert np.isinf(only.break_even)


# ------------------------------------------------------------------ the water-filling conjecture (claims/power.py)

def kkt_powers(w, budget):
    """TCP-like, decoupled one-step plants, mu = 1 - exp(-P): w_i y_i / (2 - y_i)^2 = lambda, y_i = exp(-P_i),
    sum P = B; each y_i the root in (0, 1] of lambda y^2 - (4 lambda + w) y + 4 lambda = 0, lambda by bisection."""
    w = np.asarray(w, dtype=float)

    def powers(lam):
        b = 4 * lam + w
        y = (b - np.sqrt(b * b - 16 * lam * lam)) / (2 * lam)
        return -np.log(np.clip(y, 1e-300, 1.0))

    lam = brentq(lambda t: powers(t).sum() - budget, 1e-12, w.min() / 1.0 - 1e-12, xtol=1e-15)
    return powers(lam)


def test_water_filling_fails_for_the_tcp_like_cost_by_the_hand_kkt():
    from packetloss_cvx.claims.power import BUDGETS, level_shift, water_cases

    _, system, protocol = water_cases()[1]
    shift, powers = level_shift(system, protocol)
    for budget, P in zip(BUDGETS, powers, strict=True):
        assert np.allclose(P, kkt_powers((1.0, 3.0), budget), atol=1e-4)
    hand = [np.diff(kkt_powers((1.0, 3.0), b))[0] for b in BUDGETS]
    assert np.isclose(hand[0], 0.7473, atol=1e-4)                      # the note's hand value
    assert np.isclose(shift, abs(hand[1] - hand[0]), atol=2e-4)
    assert shift > 0.2


def test_water_filling_holds_where_the_cost_is_affine_in_mu():
    """UDP-like, decoupled one-step plants: J* = sum w_i (1 - mu_i/2) = sum w_i (1 + exp(-P_i))/2, KKT
    (w_i / 2) exp(-P_i) = lambda: P_i = nu - a_i with a_i = -ln(w_i / 2), so P_2 - P_1 = ln 3 at every budget."""
    from packetloss_cvx.claims.power import level_shift, water_cases

    _, system, _ = water_cases()[1]
    shift, powers = level_shift(system, "udp", gap=1e-5)
    assert shift < 1e-3
    for P in powers:
        assert np.isclose(P[1] - P[0], np.log(3.0), atol=1e-3)


def test_water_filling_claim_verdict_and_counterexample():
    from packetloss_cvx.claims import CLAIMS
    from packetloss_cvx.claims.context import Context

    result = CLAIMS["power-water-filling"][1](Context(paper={}, random=[], seed=0))
    assert result.verdict == "fails"
    assert result.outcomes == "+--"
    assert result.counterexample["name"] == "decoupled w = (1, 3)"


def test_max_boxes_is_counted_against_its_budget():
    from packetloss_cvx.errors import BudgetError

    model = power_model("exponential", 1, scale=1.0)
    with pytest.raises(BudgetError, match="max_boxes"):
        least_power(scalar(), "udp", model, 0.8, max_boxes=10**9)
    with pytest.raises(BudgetError, match="max_boxes"):
        least_cost_within_power(scalar(), "udp", model, 1.0, max_boxes=10**9)


def test_a_row_beyond_the_first_search_box_is_no_verdict():
    """The cap is found by doubling a box from a small one: a row no small box meets (P1 >= 30) must not read
    as infeasible."""
    s = load_system("two_actuator")
    out = least_power(s, "tcp", power_model("exponential", 2, scale=1.0), 8.0, constraints=[([[-1.0, 0.0]], [-30.0])])
    assert out.power[0] >= 30.0 - 1e-6
    assert out.cost <= 8.0


def test_a_row_beyond_saturation_is_no_verdict():
    """exponential c = 1 saturates at P = 40 (mu = 1 in double precision): a row P1 >= 50 is not infeasible,
    the search box is; without a cap that is an InputError naming max_power, with one the search reaches it."""
    s, model = load_system("two_actuator"), power_model("exponential", 2, scale=1.0)
    row = [([[-1.0, 0.0]], [-50.0])]
    with pytest.raises(InputError, match="max_power"):
        least_power(s, "tcp", model, 8.0, constraints=row)
    out = least_power(s, "tcp", model, 8.0, constraints=row, max_power=60.0)
    assert out.power[0] >= 50.0 - 1e-6
    assert out.cost <= 8.0
    with pytest.raises(InfeasibleError):
        least_cost_within_power(s, "tcp", model, 30.0, constraints=row)       # P1 <= 30 < 50: proven


def test_a_budget_beyond_saturation_with_a_row_beyond_it_asks_for_a_cap():
    s, model = load_system("two_actuator"), power_model("exponential", 2, scale=1.0)
    row = [([[-1.0, 0.0]], [-50.0])]                                    # P1 >= 50 > 40, the saturation
    with pytest.raises(InputError, match="max_power"):
        least_cost_within_power(s, "tcp", model, 100.0, constraints=row)
    out = least_cost_within_power(s, "tcp", model, 100.0, constraints=row, max_power=100.0)
    assert out.power[0] >= 50.0 - 1e-6


def test_best_protocol_break_even_does_not_depend_on_the_ack_price():
    """The break-even price is a property of the two designs: a dear link (1e12) must not round it away
    (it came out as udp - ((tcp + 1e12) - 1e12), 0.93711 -> 0.93705 on two_actuator at alpha = 8).
    Hand reference: one step of x' = x + v u, TCP-like mu = 1/alpha - 1, UDP-like mu = 2 (1 - alpha)."""
    alpha = 0.75
    hand = 2 * (1 - alpha) - (1 / alpha - 1)
    for price in (0.0, 1e12):
        c = best_protocol(scalar(), alpha, [1.0], ack_price=price, gap=1e-9)
        assert c.choice == ("tcp" if price == 0.0 else "udp")
        assert np.isclose(c.break_even, hand, rtol=1e-7, atol=0)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_power_is_zero_where_silent_channels_meet_alpha(protocol):
    """alpha at or above J* of silent channels (mu(0)): zero power, proved by P >= 0, not a SolverError of the
    conic program (whose scale 1 / (alpha - C) vanishes there). Hand value: J*(mu = 0) = 1 on the one-step plant; on
    two_actuator the cost of the uncontrolled plan, sum_k x_k' x_k with x_{k+1} = A x_k, k = 1..N."""
    model = power_model("exponential", 1, scale=1.0)
    for alpha in (1.0, 1e9):
        out = least_power(scalar(), protocol, model, alpha)
        assert out.status == "optimal"
        assert out.total_power == 0.0
        assert out.lower_bound == 0.0
    s = load_system("two_actuator")
    x, free = np.array(s.x0, dtype=float), 0.0
    for _ in range(s.horizon):
        x = np.array(s.A) @ x
        free += float(x @ x)
    out = least_power(s, protocol, power_model("exponential", 2, scale=[1.0, 2.0]), 1e9)
    assert out.total_power == 0.0
    assert np.isclose(out.cost, free, rtol=1e-9)
    # a row asking for power: the least the rows admit, P1 = 0.5, is the answer
    out = least_power(s, protocol, power_model("exponential", 2, scale=[1.0, 2.0]), 1e9,
                      constraints=[([[-1.0, 0.0]], [-0.5])])
    assert np.isclose(out.total_power, 0.5, rtol=1e-7)
    assert out.status == "optimal"


@pytest.mark.parametrize(("argv", "match"), [
    (["--protocol", "tcp", "--alpha", "8", "--beta", "1,1", "--ack-price", "5"], "--ack-price: .*--protocol best"),
    (["--protocol", "udp", "--alpha", "8", "--power", "exponential", "--power-scale", "1,2", "--ack-power", "5"],
     "--ack-power: .*--protocol best"),
    (["--target", "stable", "--beta", "1,1", "--ack-price", "3"], "--ack-price: --target designs"),
    (["--target", "stable", "--beta", "1,1", "--power", "exponential", "--power-scale", "1,2"],
     "--power: --target designs"),
    (["--target", "dp-cost", "--alpha", "10", "--beta", "1,1", "--budget", "3"], "--budget: --target designs"),
])
def test_cli_options_a_command_would_ignore_exit_2(capsys, argv, match):
    """An option the chosen question does not use was ignored (the answer came back without the link's price, or a
    beta'mu design for a power question): now exit 2 with one line naming it."""
    code, out, err = run_cli(capsys, "allocate", "two_actuator", *argv)
    assert code == 2
    assert out == ""
    assert len(err.splitlines()) == 1
    assert re.search(match, err), err


# ------------------------------------------------------------------ the unit of power: every scale in [1e-12, 1e12]

def scaled_model(name, m, s):
    """MODELS[name] with every power multiplied by s: P = s P' maps it onto the model at s = 1 exactly."""
    kw = MODELS[name]
    if "scale" in kw:
        return power_model(name, m, scale=np.array(kw["scale"] * m) * s)
    table = np.array(kw["table"])
    table[:, 0] *= s
    return power_model("table", m, table=table)


def face_kkt_power(system, c, budget):
    """Reference for the budget problem on two channels with only sum P = B active: the KKT condition
    g_1 phi_1'(P_1) = g_2 phi_2'(P_2) on the face, solved for P_1 by brentq in units of c_1 (the envelope gradient
    g of the closed form, tcp.tangent; exponential phi = 1 - exp(-P / c_i))."""
    from packetloss_cvx.allocation.tcp import tangent

    c = np.asarray(c, dtype=float)
    unit = c[0]

    def h(p1):
        P = np.array([p1, budget / unit - p1]) * unit
        _, g = tangent(system, -np.expm1(-P / c))
        d = -g * np.exp(-P / c) / c * unit
        return d[0] - d[1]

    p1 = brentq(h, 1e-9 * budget / unit, budget / unit * (1 - 1e-9), xtol=1e-14)
    return np.array([p1 * unit, budget - p1 * unit])


@pytest.mark.parametrize("s", [1e-12, 1e12])
@pytest.mark.parametrize("name", ["exponential", "rayleigh", "table", "table-s"])
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_one_channel_answers_at_extreme_units_of_power(s, name, protocol):
    """Hand values times s (the model's formula inverted at the mu the scalar problem needs). With P the conic
    program's variable, c = 1e-12 gave 'optimal_inaccurate' and c = 1e12 an InfeasibleError read from Clarabel."""
    alpha = 0.8
    need = 0.25 if protocol == "tcp" else 0.4
    out = least_power(scalar(), protocol, scaled_model(name, 1, s), alpha, gap=1e-6)
    P = s * hand_power(name, need)
    assert out.status == "optimal"
    assert out.cost <= alpha
    assert out.lower_bound <= P * (1 + 1e-9)
    assert P <= out.total_power <= P * (1 + 1e-5)
    budget = 1.7
    out = least_cost_within_power(scalar(), protocol, scaled_model(name, 1, s), budget * s, gap=1e-7)
    hand = hand_cost(protocol, [model_of(name).mu(np.array([budget]))[0]], [1.0])
    assert out.status == "optimal"
    assert np.isclose(out.cost, hand, rtol=1e-7)
    assert out.lower_bound <= hand * (1 + 1e-12)


@pytest.mark.parametrize("s", [1e-12, 1e12])
def test_two_actuator_tcp_at_extreme_units_of_power_against_the_kkt_root(s):
    """Least cost within a budget (exponential c = s (1, 2), B = 3 s) against the KKT root on the budget's face,
    and the least power for alpha = 8 against a nested 1-D reference (P_2 from J* = alpha by brentq for each
    P_1, the sum minimised over P_1), both in units of s. Each answer certified to the gap 1e-6 in its objective."""
    t, c = load_system("two_actuator"), np.array([1.0, 2.0]) * s
    model = power_model("exponential", 2, scale=c)
    ev = CostEvaluator(t, "tcp")
    ref_P = face_kkt_power(t, c, 3.0 * s)
    ref = ev.cost(model.mu(ref_P))
    out = least_cost_within_power(t, "tcp", model, 3.0 * s, gap=1e-6)
    assert out.status == "optimal"
    assert out.lower_bound <= ref * (1 + 1e-9)
    assert out.cost <= ref * (1 + 1e-6)
    assert out.total_power <= 3.0 * s * (1 + 1e-9)
    assert np.allclose(out.power / s, ref_P / s, atol=1e-3)

    def second(p1):                      # the least P_2 / s with J*(mu(s p1, s p2)) <= 8, J* falling in p2
        return brentq(lambda p2: ev.cost(model.mu(np.array([p1, p2]) * s)) - 8.0, 0.0, 80.0, xtol=1e-13)

    best = minimize_scalar(lambda p1: p1 + second(p1), bounds=(0.0, 3.0), method="bounded",
                           options={"xatol": 1e-10})
    out = least_power(t, "tcp", model, 8.0, gap=1e-6)
    assert out.status == "optimal"
    assert out.cost <= 8.0
    assert out.lower_bound / s <= best.fun * (1 + 1e-9)
    assert out.total_power / s <= best.fun * (1 + 1e-6)


@pytest.mark.parametrize("s", [1e-12, 1e12])
def test_udp_least_power_at_extreme_units_of_power_against_the_split(s):
    """UDP-like, decoupled w = (1, 3), exponential c = 1.5 s: the least power is s times the least budget whose
    hand-cost split reaches alpha (the 1-D reference at s = 1). The branch and bound prices x by top / max(top),
    so neither its gap floor nor its split weights see s."""
    w, alpha, gap = (1.0, 3.0), 2.9, 1e-4
    out = least_power(decoupled(w), "udp", scaled_model("exponential", 2, s), alpha, gap=gap)
    total = brentq(lambda b: split_reference("udp", "exponential", b, w) - alpha, 1e-6, 40.0, xtol=1e-10)
    assert out.status == "optimal"
    assert out.cost <= alpha
    assert out.lower_bound / s <= total * (1 + 1e-6)
    assert out.total_power / s <= total * (1 + gap)


def test_a_failed_conic_program_is_no_verdict(monkeypatch):
    """Clarabel's infeasibility certificate (false at c = 1e12 before the program was written in P / c) and any
    other failure hand the problem to the branch and bound, which answers (hand value log(4/3) on the one-step
    plant) or proves infeasibility by discarding every box."""
    from packetloss_cvx.qp.convex import ClarabelProgram

    def fails(self, values, what, attempts=()):
        return "infeasible", None

    monkeypatch.setattr(ClarabelProgram, "solve", fails)
    model = power_model("exponential", 1, scale=1.0)
    out = least_power(scalar(), "tcp", model, 0.8, gap=1e-6)
    assert out.status == "optimal"
    assert np.log(4 / 3) <= out.total_power <= np.log(4 / 3) * (1 + 1e-6)
    assert "the convex program failed" in out.method
    out = least_cost_within_power(scalar(), "tcp", model, 1.7, gap=1e-7)
    assert np.isclose(out.cost, hand_cost("tcp", [-np.expm1(-1.7)], [1.0]), rtol=1e-7)
    with pytest.raises(InfeasibleError, match="every box was proven infeasible"):     # P <= 0.01 misses alpha
        least_power(scalar(), "tcp", model, 0.8, constraints=[([[1.0]], [0.01])])


def test_cli_power_scale_1e12_answers(capsys):
    code, out, err = run_cli(capsys, "allocate", "two_actuator", "--protocol", "tcp", "--alpha", "8", "--power",
                             "exponential", "--power-scale", "1e12,2e12", "--json")
    assert code == 0, err
    data = json.loads(out)
    ref = least_power(load_system("two_actuator"), "tcp", power_model("exponential", 2, scale=[1.0, 2.0]), 8.0)
    assert data["status"] == "optimal"
    assert np.isclose(data["total_power"] / 1e12, ref.total_power, rtol=2e-4)     # each certified to 1e-4


# ------------------------------------------------------------------ rayleigh, TCP-like: the tangent relaxation

def rayleigh_face_reference(system, c, budget):
    """min over P_1 in [0, B] of J*_tcp(exp(-c / P)) at (P_1, B - P_1) (the budget is spent: J* falls in P):
    a grid, then a bounded scalar search around its best point, on the hand formula of the curve."""
    ev, c = CostEvaluator(system, "tcp"), np.asarray(c, dtype=float)

    def f(p1):
        P = np.array([p1, budget - p1])
        return ev.cost(np.where(P > 0, np.exp(-c / np.maximum(P, 1e-300)), 0.0))

    grid = np.linspace(0, budget, 3001)
    k = int(np.argmin([f(p) for p in grid]))
    best = minimize_scalar(f, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, 3000)]), method="bounded",
                           options={"xatol": 1e-10})
    return min(best.fun, f(grid[k]))


@pytest.mark.parametrize("budget", [6.0, 12.0])
def test_rayleigh_tcp_least_cost_by_the_tangent_relaxation(budget):
    """Where the optimum has every P_i >= c_i, the conic programs on the tangent majorant certify the answer
    alone (no box), against a 1-D search on the budget's face with the hand formula of the curve."""
    s, c = load_system("two_actuator"), [1.0, 2.0]
    out = least_cost_within_power(s, "tcp", power_model("rayleigh", 2, scale=c), budget)
    ref = rayleigh_face_reference(s, c, budget)
    assert out.status == "optimal"
    assert out.lower_bound <= ref * (1 + 1e-9)
    assert out.cost <= ref * (1 + 1e-4)
    assert np.all(out.power >= np.array(c))
    assert out.boxes == 0
    assert "tangents above the rayleigh curve" in out.method


def test_rayleigh_tcp_least_power_by_the_tangent_relaxation():
    """alpha = 3 on two_actuator (optimum P_i >= c_i) against the nested 1-D reference (P_2 from J* = alpha by
    brentq for each P_1, the sum minimised over P_1); and alpha = 8 (P_i < c_i: the branch and bound finishes
    from the relaxation's floor), the same reference."""
    s, c = load_system("two_actuator"), np.array([1.0, 2.0])
    ev = CostEvaluator(s, "tcp")

    def mu(P):
        return np.where(P > 0, np.exp(-c / np.maximum(P, 1e-300)), 0.0)

    for alpha in (3.0, 8.0):
        def second(p1, alpha=alpha):
            return brentq(lambda p2: ev.cost(mu(np.array([p1, p2]))) - alpha, 1e-9, 200.0, xtol=1e-13)

        best = minimize_scalar(lambda p1: p1 + second(p1), bounds=(1e-6, 6.0), method="bounded",
                               options={"xatol": 1e-10})
        out = least_power(s, "tcp", power_model("rayleigh", 2, scale=c), alpha)
        assert out.status == "optimal"
        assert out.cost <= alpha
        assert out.lower_bound <= best.fun * (1 + 1e-9)
        assert out.total_power <= best.fun * (1 + 1e-4)
        assert (out.boxes == 0) == (alpha == 3.0)        # P_i >= c_i at alpha = 3 only


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("last", [1e12, 1e24])
def test_least_power_with_a_table_far_beyond_its_action(protocol, last):
    # the table acts at P ~ 1 and ends at 1e12 or 1e24: the search box must come down to the answer's scale, or the
    # gap's absolute floor (in x = P / top) certifies any point; by hand mu = 0.75 is on the segment (1, 0.6)-(2, 0.9)
    model = power_model("table", 1, table=[[0.0, 0.0], [1.0, 0.6], [2.0, 0.9], [last, 0.99]])
    alpha = hand_cost(protocol, [0.75], [1.0])
    a = least_power(scalar(), protocol, model, alpha, gap=1e-6)
    assert a.status == "optimal"
    assert a.total_power == pytest.approx(1.5, rel=1e-5)
    assert a.lower_bound <= 1.5 * (1 + 1e-9)
    assert a.lower_bound >= 1.5 * (1 - 2e-6)
    assert a.cost <= alpha * (1 + 1e-9)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_cost_within_power_at_tiny_costs(protocol):
    # x0 scaled by 1e-10: every cost is 1e-20 times the decoupled plant's, below the gap's absolute floor 1e-12; the
    # optimal powers do not move. Reference: the split of B = 2 between the channels (exponential, c = 1) by a scalar
    # search on the hand costs (UDP-like by hand: w_i e^-P_i equal, P_1 = 1 - log(3) / 2)
    w = np.array([1.0, 3.0])
    tiny = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
                  mu=[0.5, 0.5], x0=1e-10 * np.sqrt(w))
    model = power_model("exponential", 2, scale=1.0)

    def hand(p1):
        return hand_cost(protocol, model.mu(np.array([p1, 2.0 - p1])), w)

    split = minimize_scalar(hand, bounds=(0.0, 2.0), method="bounded", options={"xatol": 1e-10})
    if protocol == "udp":
        assert split.x == pytest.approx(1.0 - np.log(3.0) / 2.0, abs=1e-6)
    a = least_cost_within_power(tiny, protocol, model, 2.0, gap=1e-5)
    assert a.status == "optimal"
    assert a.cost / 1e-20 == pytest.approx(split.fun, rel=2e-5)
    assert a.lower_bound / 1e-20 <= split.fun * (1 + 1e-9)
    assert a.lower_bound / 1e-20 >= split.fun * (1 - 2e-5)
    assert a.gap <= 1e-5


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_least_cost_within_power_reports_the_gap_it_certified(protocol):
    """The power problem's gap is allocation.udp.reported_gap, as min_cost's: (cost - lower bound) / cost where the
    cost is above 1e-12 times J* at P = 0 (the floor's unit; by hand sum w_i for both protocols)."""
    w = (1.0, 3.0)
    out = least_cost_within_power(decoupled(w), protocol, model_of("exponential", 2), 2.5, gap=1e-4)
    assert out.cost > 1e-12 * hand_cost(protocol, [0.0, 0.0], w)
    assert out.lower_bound < out.cost
    assert out.gap == pytest.approx((out.cost - out.lower_bound) / out.cost, rel=1e-12, abs=0.0)


def test_the_compiled_power_program_is_kept_by_content(monkeypatch):
    """PowerProgram.of keeps one compiled program per content of what the program is built from: an equal fresh
    system (or one with another x0, a Parameter) shares it; another A, B, horizon, state or input weight, model
    scale or table, kind or row count gets its own. A kept program answers as a new one does, bit for bit."""
    from packetloss_cvx.allocation import power

    model = power_model("exponential", 2, scale=[1.0, 2.0])

    def plant(**change):
        fields = dict(A=np.eye(2), B=np.eye(2), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
                      mu=[0.5, 0.5], x0=[1.0, 1.0])
        return System(**{**fields, **change})

    kept = power.PowerProgram.of(plant(), model, "cost", 1)
    assert power.PowerProgram.of(plant(), model, "cost", 1) is kept
    assert power.PowerProgram.of(plant(x0=[3.0, -1.0]), model, "cost", 1) is kept
    others = [(plant(A=[[1.0, 0.1], [0.0, 1.0]]), model, "cost", 1),
              (plant(B=[[1.0, 0.0], [0.5, 1.0]]), model, "cost", 1),
              (plant(horizon=3), model, "cost", 1), (plant(state_weight=[1.0, 2.0]), model, "cost", 1),
              (plant(input_weight=[1.0, 2.0]), model, "cost", 1),
              (plant(), power_model("exponential", 2, scale=[1.0, 3.0]), "cost", 1),
              (plant(), model_of("table", 2), "cost", 1), (plant(), model_of("table-s", 2), "cost", 1),
              (plant(), model, "power", 1), (plant(), model, "cost", 2)]
    assert all(power.PowerProgram.of(*args) is not kept for args in others)
    fresh = least_cost_within_power(plant(x0=[0.5, 2.0]), "tcp", model, 2.0)
    monkeypatch.setattr(power, "PROGRAMS_KEPT", 0)                     # every program new
    new = least_cost_within_power(plant(x0=[0.5, 2.0]), "tcp", model, 2.0)
    assert (fresh.power.tolist(), fresh.cost, fresh.lower_bound) == (new.power.tolist(), new.cost, new.lower_bound)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize(("factor", "proved"), [(3.0, True), (0.3, False)])
def test_least_power_proves_infeasibility_only_beyond_allocation_cost_rtol(two_actuator, protocol, factor, proved):
    """alpha just below J* at the largest powers allowed (max_power 2 on the exponential model: mu = 1 - e^-2 on each
    channel, J* falls as any power rises): infeasibility is proved only where J* there exceeds alpha (1 +
    ALLOCATION_COST_RTOL). At 3 times the band below: InfeasibleError; at 0.3 times: no proof (SolverError)."""
    from packetloss_cvx.errors import SolverError
    from packetloss_cvx.lq.costs import closed_form
    from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL

    mu = 1 - np.exp(-2.0)
    alpha = closed_form(two_actuator.with_mu([mu, mu]), protocol).cost / (1 + factor * ALLOCATION_COST_RTOL)
    with pytest.raises(InfeasibleError if proved else SolverError,
                       match="at the largest powers searched" if proved else "infeasibility not proven"):
        least_power(two_actuator, protocol, power_model("exponential", 2, scale=1.0), alpha, max_power=2.0,
                    max_boxes=50)


def test_a_power_cut_is_loosened_by_allocation_cost_rtol_of_the_value_and_gradient():
    """As the TCP-like tangent cuts (test_allocation.py): a cut of x -> J*_tcp(mu(top x)) lies ALLOCATION_COST_RTOL
    (|J| + ||g||_1) below J at its touching point. Scalar J*_tcp = 1 / (1 + mu), exponential model mu = 1 - e^-P,
    top T = 2, x = 1/2: P = 1, J = 1 / (2 - e^-1), g = -e^-1 T / (2 - e^-1)^2 (by hand, the chain rule)."""
    from packetloss_cvx.allocation.power import _Setup
    from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL

    setup = _Setup(scalar(), "tcp", power_model("exponential", 1, scale=1.0), np.array([2.0]), ())
    g, r = setup.cuts(np.array([0.5]), setup.evaluator)
    J = 1 / (2 - np.exp(-1.0))
    slope = -np.exp(-1.0) * 2.0 / (2 - np.exp(-1.0)) ** 2
    assert g[0, 0] == pytest.approx(slope, rel=1e-9)
    below = J - (r[0] + g[0, 0] * 0.5)
    assert below == pytest.approx(ALLOCATION_COST_RTOL * (J + abs(slope)), rel=1e-6)
