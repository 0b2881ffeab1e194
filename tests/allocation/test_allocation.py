"""Allocation against independent references: feasibility by the Clarabel QP twin (not the
closed form the allocation uses), optimality against the brute-force allocator (grid on mu1,
bisection on mu2), hand values where the optimum is a vertex of the constraints."""

from types import SimpleNamespace

import cvxpy as cp
import numpy as np
import pytest

import packetloss_cvx as pl
import packetloss_cvx.allocation.tcp as tcp_module
import packetloss_cvx.allocation.udp as udp_module
from packetloss_cvx.allocation import allocate, best_cost_within_budget, min_cost, parse_constraint
from packetloss_cvx.allocation.brute_force import brute_force_allocation, brute_force_allocations
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.tolerances import ALLOCATION_LP_FEASIBILITY, CROSS_CHECK_COST_RTOL

#: The brute force and the allocation evaluate J* by separate calls; their feasible sets may
#: differ by the closed form's rounding (about 1e-12 relative), far inside this slack.
ROUNDING = 1e-9


def qp_cost(system, protocol, mu):
    """J*(mu) by the QP twin: cvxpy + Clarabel on the expected cost, not the closed form."""
    return pl.solve_qp(system.with_mu(mu), protocol, cross_check=False, with_gain=False).cost


def _check(system, protocol, alpha, beta, constraints=(), G=None, h=None, gap=1e-4, ref=None):
    """``ref``: the brute force's answer where a fixture computed it (else computed here)."""
    G = np.zeros((0, 2)) if G is None else G
    h = np.zeros(0) if h is None else h
    ref = brute_force_allocation(system, protocol, alpha, beta, G, h) if ref is None else ref
    got = allocate(system, protocol, alpha, beta, constraints=constraints, gap=gap)
    assert got.status == "optimal"
    assert got.cost <= alpha                                      # feasible by the closed form ...
    twin = qp_cost(system, protocol, got.mu)
    assert twin <= alpha * (1 + CROSS_CHECK_COST_RTOL)            # ... and by the independent QP
    assert got.cost == pytest.approx(twin, rel=CROSS_CHECK_COST_RTOL)
    assert np.all(G @ got.mu <= h + ALLOCATION_LP_FEASIBILITY)
    assert np.all((got.mu >= 0) & (got.mu <= 1))
    assert got.lower_bound <= ref[0] + ROUNDING                   # the certificate is a real bound
    assert got.communication_cost <= ref[0] / (1 - gap) + ROUNDING  # lower_bound <= optimum <= ref
    assert got.gap <= gap
    assert got.gap == pytest.approx((got.communication_cost - got.lower_bound) / got.communication_cost)
    return got, ref


TWO_ACTUATOR_BETAS = [(1.0, 1.0), (0.05, 1.0), (1.0, 0.05)]
TWO_ACTUATOR_ALPHAS = [4.78, 8.0]


@pytest.fixture(scope="module")
def two_actuator_references(two_actuator):
    """protocol -> {(alpha, beta): the brute force's answer} for every case below, each protocol's six searches run
    side by side once (brute_force_allocations: each answer the one the case gives alone)."""
    found: dict = {}

    def get(protocol):
        if protocol not in found:
            cases = [(alpha, beta) for beta in TWO_ACTUATOR_BETAS for alpha in TWO_ACTUATOR_ALPHAS]
            answers = brute_force_allocations(two_actuator, protocol, [(a, b, np.zeros((0, 2)), np.zeros(0))
                                                                       for a, b in cases])
            found[protocol] = dict(zip(cases, answers, strict=True))
        return found[protocol]

    return get


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("beta", TWO_ACTUATOR_BETAS)
@pytest.mark.parametrize("alpha", TWO_ACTUATOR_ALPHAS)
def test_two_actuator_against_brute_force(two_actuator, two_actuator_references, protocol, beta, alpha):
    _check(two_actuator, protocol, alpha, beta, ref=two_actuator_references(protocol)[(alpha, beta)])


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_with_linear_constraints(two_actuator, protocol):
    texts = ["mu1 >= mu2", "mu1 + 2*mu2 <= 2.5"]
    pairs = [parse_constraint(t, 2) for t in texts]
    G = np.vstack([p[0] for p in pairs])
    h = np.concatenate([p[1] for p in pairs])
    got, _ = _check(two_actuator, protocol, 6.0, (0.05, 1.0), constraints=pairs, G=G, h=h)
    assert got.mu[0] >= got.mu[1] - 1e-7


@pytest.mark.parametrize(("protocol", "alpha"), [("tcp", 6.0), ("udp", 12.0)])   # J*_udp(0.3, 1) = 10.2
def test_callable_constraint_is_read_into_rows(two_actuator, protocol, alpha):
    """An affine callable is the same constraint as its (G, h) pair, checked against the brute force."""
    G, h = parse_constraint("mu1 <= 0.3", 2)
    got, _ = _check(two_actuator, protocol, alpha, (1.0, 1.0), constraints=[lambda mu: [mu[0] <= 0.3]], G=G, h=h)
    pair = allocate(two_actuator, protocol, alpha, (1.0, 1.0), constraints=[(G, h)])
    assert np.allclose(got.mu, pair.mu, atol=1e-9)


def test_non_affine_callable_refused(two_actuator):
    with pytest.raises(pl.InputError, match=r"constraints\[0\]: a callable's constraints must be affine"):
        allocate(two_actuator, "tcp", 6.0, (1.0, 1.0), constraints=[lambda mu: [cp.norm(mu) <= 1]])


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_random_systems_against_brute_force(seed, protocol):
    rng = np.random.default_rng(100 + seed)
    s = random_system(rng, n=2, m=2, horizon=4, non_stationary=False, edge_mu=False)
    full = qp_cost(s, protocol, [1.0, 1.0])
    none = qp_cost(s, protocol, [0.0, 0.0])
    alpha = full + 0.25 * (none - full)
    beta = rng.uniform(0.1, 1.0, 2)
    G, h = parse_constraint("mu1 + mu2 <= 1.8", 2)
    _check(s, protocol, alpha, beta)
    if qp_cost(s, protocol, [0.9, 0.9]) <= alpha:
        _check(s, protocol, alpha, beta, constraints=[(G, h)], G=G, h=h)


def test_infeasible_alpha_reports_min_cost(two_actuator):
    least = qp_cost(two_actuator, "udp", [1.0, 1.0])              # J* falls in mu: the corner (1, 1)
    with pytest.raises(pl.InfeasibleError, match="below the least reachable udp-like cost") as info:
        allocate(two_actuator, "udp", least * 0.99, (1.0, 1.0))
    assert info.value.min_cost == pytest.approx(least, rel=CROSS_CHECK_COST_RTOL)
    capped = qp_cost(two_actuator, "tcp", [0.5, 1.0])             # the best point with mu1 <= 0.5
    with pytest.raises(pl.InfeasibleError, match="Clarabel certificate") as info:
        allocate(two_actuator, "tcp", capped * 0.99, (1.0, 1.0), constraints=[parse_constraint("mu1 <= 0.5", 2)])
    assert info.value.min_cost == pytest.approx(capped, rel=1e-6)


def test_budget_side_of_the_tradeoff(two_actuator):
    """min J* s.t. beta'mu <= b, then allocating at that cost spends about b."""
    for protocol in ("tcp", "udp"):
        best = best_cost_within_budget(two_actuator, protocol, (1.0, 1.0), 1.2)
        assert best.status == "optimal"
        assert best.lower_bound <= best.cost <= best.lower_bound * (1 + 1e-6)
        assert best.mu.sum() <= 1.2 + ALLOCATION_LP_FEASIBILITY
        assert best.cost == pytest.approx(qp_cost(two_actuator, protocol, best.mu), rel=CROSS_CHECK_COST_RTOL)
        back = allocate(two_actuator, protocol, best.cost * (1 + 1e-6), (1.0, 1.0))
        ref = brute_force_allocation(two_actuator, protocol, best.cost * (1 + 1e-6), (1.0, 1.0))
        assert back.lower_bound <= ref[0] + ROUNDING
        assert back.communication_cost <= 1.2 + 1e-3
        assert back.communication_cost >= 1.2 * 0.98
    corner = min_cost(two_actuator, "udp")
    assert corner.cost == pytest.approx(qp_cost(two_actuator, "udp", [1.0, 1.0]), rel=CROSS_CHECK_COST_RTOL)
    assert corner.mu.tolist() == [1.0, 1.0]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"alpha": -1.0}, "alpha: expected a positive"),
        ({"beta": (1.0,)}, "beta: expected 2"),
        ({"beta": (1.0, -1.0)}, "beta: expected finite non-negative"),
        ({"bounds": (0.5, 0.2)}, "bounds: expected 0 <= lo <= hi <= 1"),
        ({"constraints": [(np.ones((1, 3)), [1.0])]}, r"constraints\[0\]: expected G of shape"),
        ({"gap": 0.0}, r"gap: expected a number in \[1e-09, 1\)"),
    ],
)
def test_bad_allocation_input(two_actuator, kwargs, match):
    args = {"protocol": "tcp", "alpha": 5.0, "beta": (1.0, 1.0), **kwargs}
    with pytest.raises(pl.InputError, match=match):
        allocate(two_actuator, **args)


@pytest.mark.parametrize(
    ("text", "G", "h"),
    [
        ("mu1 + 2*mu2 <= 1.5", [[1, 2]], [1.5]),
        ("mu1 >= mu2", [[-1, 1]], [0.0]),
        ("mu2 <= 0.8", [[0, 1]], [0.8]),
        ("0.5 mu1 - mu2 + 0.1 >= 0.2", [[-0.5, 1]], [-0.1]),
        ("mu1 == 0.3", [[1, 0], [-1, 0]], [0.3, -0.3]),
    ],
)
def test_parse_constraint(text, G, h):
    g, c = parse_constraint(text, 2)
    assert np.allclose(g, G)
    assert np.allclose(c, h)


@pytest.mark.parametrize(
    ("text", "match"),
    [("mu3 <= 1", "unknown channel 'mu3'"), ("mu1 <=", "expression on both sides"), ("mu1 + <= 1", "cannot parse"),
     ("mu1 mu2 <= 1", "expected '\\+' or '-'"), ("mu1 <= 1 <= 2", "one comparison"), ("1 <= 2", "does not involve"),
     ("__import__('os') <= 1", "cannot parse")],
)
def test_parse_constraint_errors(text, match):
    with pytest.raises(pl.InputError, match=match):
        parse_constraint(text, 2)


# ------------------------------------------------------------------ the TCP-like SOCP, compiled once

def _tcp_case(seed, N=12):
    """Three channels behind a near-identity B (benchmarks/run.py's allocation case, shorter)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3, 3))
    A *= 1.02 / max(abs(np.linalg.eigvals(A)))
    s = pl.System(A=A, B=np.eye(3) + 0.3 * rng.normal(size=(3, 3)), horizon=N, state_weight=np.ones(3),
                  input_weight=rng.uniform(0.5, 1.5, 3), mu=[0.5] * 3, x0=rng.normal(size=3))
    full, none = (pl.closed_form(s.with_mu([v] * 3), "tcp").cost for v in (1.0, 0.0))
    return s, [(full + f * (none - full), rng.uniform(0.5, 1.5, 3)) for f in (0.3, 0.1)]


def _alone(system, alpha, beta):
    """The call in a system of its own: a pickled copy is rebuilt by the constructor, with an empty
    store, so its SOCP is compiled anew and has seen no other data."""
    import pickle

    a = allocate(pickle.loads(pickle.dumps(system)), "tcp", alpha, beta)
    return a.mu, a.lower_bound, a.status


def test_tcp_program_is_dpp_and_kept_with_the_system_structure():
    from packetloss_cvx.allocation.tcp import TCPProgram

    s, _ = _tcp_case(1)
    program = TCPProgram.of(s, "allocate", 0)
    assert program.problem.is_dpp()
    assert TCPProgram.of(s.with_mu([0.9] * 3).with_x0([1.0, 0.0, 0.0]), "allocate", 0) is program
    assert TCPProgram.of(s, "allocate", 1) is not program and TCPProgram.of(s, "min_cost", 0) is not program


def test_tcp_calls_alternating_on_one_system_answer_as_each_alone():
    """Re-solves assign every Parameter and run Clarabel on their own data (the first attempt on a kept solver
    without equilibration, updated; an equilibrated warm re-solve would keep the scaling of the data it saw
    first, answers up to 42 % off across systems), so each answer must be exactly the one the call gets in a
    program of its own, whatever ran before it."""
    s, calls = _tcp_case(1)
    expected = [_alone(s, *call) for call in calls]
    for _ in range(2):
        for call, (mu, lower, status) in zip(calls, expected, strict=True):
            got = allocate(s, "tcp", *call)
            assert np.array_equal(got.mu, mu) and got.lower_bound == lower and got.status == status


def test_tcp_calls_alternating_between_two_systems_answer_as_each_alone():
    (s, calls_s), (t, calls_t) = _tcp_case(2), _tcp_case(3)
    expected = {id(s): _alone(s, *calls_s[0]), id(t): _alone(t, *calls_t[0])}
    for system, call in [(s, calls_s[0]), (t, calls_t[0])] * 2:
        got = allocate(system, "tcp", *call)
        mu, lower, status = expected[id(system)]
        assert np.array_equal(got.mu, mu) and got.lower_bound == lower and got.status == status


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_allocation_is_invariant_to_the_scale_of_the_prices(protocol):
    """beta = (1e-16, 5e-18) was certified 'optimal' at 7.6x (TCP) and 1.63x (UDP) the true optimum."""
    system = pl.load_example("two_actuator")
    unit = allocate(system, protocol, 8.0, [1.0, 0.05])
    tiny = allocate(system, protocol, 8.0, [1e-16, 5e-18])
    assert np.allclose(tiny.mu, unit.mu, atol=1e-9)
    assert tiny.gap == pytest.approx(unit.gap, rel=1e-6, abs=1e-12)
    assert tiny.lower_bound == pytest.approx(unit.lower_bound * 1e-16, rel=1e-9)
    assert tiny.status == unit.status == "optimal"


def test_tcp_min_cost_when_the_socp_point_misses_a_row():
    """benchmarks/run.py's seed-2 system (N = 40) with mu1 + mu2 + mu3 <= 0.6: Clarabel's point exceeds the
    row by 3.2e-9, beyond the LP tolerance, and min_cost raised SolverError. The cut LP's point (in the
    polytope) is taken instead; reference: SLSQP over the closed form, an independent minimiser."""
    from scipy.optimize import minimize

    s, _ = _tcp_case(2, N=40)
    got = min_cost(s, "tcp", constraints=[([[1.0, 1.0, 1.0]], [0.2 * 3])])     # the benchmark's 0.6000000000000001
    assert got.status == "optimal"
    assert got.mu.sum() <= 0.6 + ALLOCATION_LP_FEASIBILITY and np.all((got.mu >= 0) & (got.mu <= 1))
    assert got.cost == pytest.approx(pl.closed_form(s.with_mu(got.mu), "tcp").cost, rel=1e-12)

    def J(mu):
        return pl.closed_form(s.with_mu(np.clip(mu, 0.0, 1.0)), "tcp").cost

    ref = minimize(J, np.full(3, 0.2), method="SLSQP", bounds=[(0.0, 1.0)] * 3,
                   constraints=[{"type": "ineq", "fun": lambda mu: 0.6 - mu.sum()}], options={"ftol": 1e-14})
    assert ref.success and ref.x.sum() <= 0.6 + 1e-9
    assert got.lower_bound <= ref.fun * (1 + 1e-9)
    assert got.cost <= ref.fun * (1 + 1e-6)


@pytest.mark.parametrize("seed", [1, 3])
def test_tcp_allocation_reports_the_closed_form_cost_of_its_point(seed):
    """allocate's cost comes from the solver's own evaluations (each point once); reference: closed_form at the
    returned mu (method "auto", built afresh) and the QP twin, which shares none of that code."""
    s, calls = _tcp_case(seed)
    for alpha, beta in calls:
        a = allocate(s, "tcp", alpha, beta)
        assert a.cost == pytest.approx(pl.closed_form(s.with_mu(a.mu), "tcp").cost, rel=1e-12)
        assert a.cost == pytest.approx(pl.solve_qp(s.with_mu(a.mu), "tcp", cross_check=False, with_gain=False).cost,
                                       rel=CROSS_CHECK_COST_RTOL)
        assert a.cost <= alpha


def _least_mu_by_bisection(s, alpha, a, b):
    """Reference for one channel: sequential bisection of closed_form's J* <= alpha on [a, b] to 1e-14."""
    def J(mu):
        return pl.closed_form(s.with_mu([mu]), "tcp").cost

    if J(a) <= alpha:
        return a
    while b - a > 1e-14 * b:
        mid = 0.5 * (a + b)
        if not a < mid < b:
            break
        a, b = (a, mid) if J(mid) <= alpha else (mid, b)
    return b


def _one_channel_cases():
    rng = np.random.default_rng(19)
    systems = [pl.load_example("pendulum")]
    systems += [random_system(rng, n=int(rng.integers(1, 5)), m=1, horizon=int(rng.integers(2, 30)),
                              non_stationary=False) for _ in range(6)]
    return systems


@pytest.mark.parametrize("k", range(7))
def test_one_channel_tcp_allocation_finds_the_least_feasible_mu(k):
    """m = 1 takes no SOCP: the crossing of alpha by Newton and chord steps. Reference: sequential bisection of
    closed_form; also the SOCP (the m > 1 path) on the same call, which must sit inside the certificate."""
    from packetloss_cvx.allocation.grammar import read_polytope
    from packetloss_cvx.allocation.tcp import TCPProgram, constant_cost

    s = _one_channel_cases()[k]
    full, none = (pl.closed_form(s.with_mu([v]), "tcp").cost for v in (1.0, 0.0))
    for f, row in ((0.3, None), (0.05, None), (0.5, 0.2)):          # row: mu >= 0.2
        alpha = full + f * (none - full)
        constraints = [([[-1.0]], [-row])] if row is not None else []
        a = allocate(s, "tcp", alpha, [2.0], constraints=constraints)
        ref = _least_mu_by_bisection(s, alpha, row or 0.0, 1.0)
        assert a.method.startswith("one channel") and "moved" not in a.method
        assert a.status == ("optimal" if a.gap <= 1e-4 else "gap_not_certified")
        assert a.communication_cost - a.lower_bound <= 1e-8 + 1e-6 * a.communication_cost   # the cuts' loosening
        assert a.cost <= alpha
        assert a.lower_bound <= 2.0 * ref * (1 + 1e-12)
        assert ref * (1 - 1e-12) - ALLOCATION_LP_FEASIBILITY <= a.mu[0] <= ref * (1 + 1e-7)
        if row is None:
            poly = read_polytope([], 1, 0.0, 1.0)
            socp = TCPProgram.of(s, "allocate", 0).solve(s.x0, poly, 1.0 / (alpha - constant_cost(s)), np.ones(1))
            # the SOCP's point is no better than the proof allows, nor than ours, to Clarabel's accuracy (5e-8 seen)
            assert a.lower_bound / 2.0 * (1 - 1e-7) - 1e-9 <= socp[0] and a.mu[0] <= socp[0] * (1 + 1e-7) + 1e-9


def test_one_channel_tcp_infeasible_and_min_cost_at_the_upper_end():
    """J* falls in mu: with mu <= 0.01 an alpha below J*(0.01) is infeasible (proved by monotonicity), and
    the least cost under mu <= 0.4 is J*(0.4), by closed_form."""
    s = pl.load_example("pendulum")
    low = pl.closed_form(s.with_mu([0.01]), "tcp").cost
    with pytest.raises(pl.InfeasibleError, match="largest admissible mu"):
        allocate(s, "tcp", low * 0.999, [1.0], constraints=[([[1.0]], [0.01])])
    got = min_cost(s, "tcp", constraints=[([[1.0]], [0.4])])
    assert got.mu.tolist() == [0.4] and got.status == "optimal"
    assert got.cost == pytest.approx(pl.closed_form(s.with_mu([0.4]), "tcp").cost, rel=1e-12)
    assert got.lower_bound <= got.cost


@pytest.mark.parametrize("protocol", ["udp"])        # TCP-like: the SOCP raises SolverError here (no verdict)
def test_min_cost_at_tiny_costs_against_a_grid(protocol):
    # x0 = 1e-10: every cost is 1e-20 times the x0 = 1 plant's, below the gap's absolute floor 1e-12; the minimiser
    # does not move. Reference: the closed form on a grid of the row mu_1 + mu_2 = 1 (J* falls in mu: the minimum is
    # on it), refined around its best point
    s = pl.System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[0.0, 1.0], [1.0, 0.3]], horizon=5, state_weight=[1.0, 1.0],
                  input_weight=[0.5, 0.5], x0=[1e-10, 1e-10], mu=[0.5, 0.5])

    def on_row(t):
        return pl.closed_form(s.with_mu([t, 1.0 - t]), protocol).cost

    grid = np.linspace(0.0, 1.0, 201)
    t0 = grid[int(np.argmin([on_row(t) for t in grid]))]
    best = min(on_row(t) for t in np.linspace(max(t0 - 0.005, 0.0), min(t0 + 0.005, 1.0), 201))
    r = min_cost(s, protocol, constraints=[(np.array([[1.0, 1.0]]), np.array([1.0]))])
    assert r.status == "optimal"
    assert r.cost == pytest.approx(best, rel=1e-5, abs=0.0)       # (approx's default abs 1e-12 would pass anything)
    assert r.lower_bound <= best * (1 + 1e-9)
    assert r.gap <= 1e-5


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_min_cost_reports_the_gap_it_certified(protocol):
    """min_cost's gap is the one definition (allocation.udp.reported_gap): (cost - lower bound) / cost wherever the
    cost is above 1e-12 times J* at the box's lower corner (the floor's unit; the closed form at mu = 0 here)."""
    s = pl.System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[0.0, 1.0], [1.0, 0.3]], horizon=5, state_weight=[1.0, 1.0],
                  input_weight=[0.5, 0.5], x0=[1.0, 1.0], mu=[0.5, 0.5])
    r = min_cost(s, protocol, constraints=[(np.array([[1.0, 1.0]]), np.array([1.0]))])
    assert r.cost > 1e-12 * pl.closed_form(s.with_mu([0.0, 0.0]), protocol).cost
    assert r.lower_bound < r.cost                                   # a gap to report
    assert r.gap == pytest.approx((r.cost - r.lower_bound) / r.cost, rel=1e-12, abs=0.0)


@pytest.mark.parametrize("scale", [1e-20, 1.0, 1e20])
@pytest.mark.parametrize(("factor", "floored"), [(3.0, False), (0.3, True)])
def test_gap_unit_floors_values_below_allocation_gap_floor_times_the_problem_scale(scale, factor, floored):
    """The unit a gap is taken of (allocation.udp.gap_unit: the searches' certificate and every reported minimum-cost
    gap) is |value|, floored at ALLOCATION_GAP_FLOOR times the problem's own scale: a value 3 times the floor is its
    own unit, one 0.3 times the floor gets the floor, at every scale (the floor is relative to the problem)."""
    from packetloss_cvx.allocation.udp import gap_unit, reported_gap
    from packetloss_cvx.tolerances import ALLOCATION_GAP_FLOOR

    floor = ALLOCATION_GAP_FLOOR * scale
    value = factor * floor
    assert gap_unit(value, scale) == (floor if floored else value)
    assert reported_gap(value, 0.0, scale) == pytest.approx(factor if floored else 1.0, rel=1e-15)
    assert gap_unit(value, None) == value                       # no problem scale: a plain relative gap


def _scalar_lq(a: float, horizon: int, omega: float, psi: float, mu: float) -> float:
    """J*_tcp of x+ = a x + v u, x0 = 1, state weight omega, input weight psi, at mu in {0, 1} by hand: sum_t omega
    a^(2t) with nothing delivered, the scalar LQ Riccati recursion with everything delivered."""
    if mu == 0.0:
        return sum(omega * a ** (2 * t) for t in range(1, horizon + 1))
    value = omega                                        # weight of x_N
    for t in range(horizon - 1, -1, -1):
        value = a * a * value * psi / (value + psi) + (omega if t >= 1 else 0.0)
    return value


@pytest.mark.parametrize("scale", [1e-20, 1.0, 1e20])
@pytest.mark.parametrize(("a", "horizon", "psi", "certified"), [(1.0, 1, 1e-3, False), (10.0, 12, 1.0, True)])
def test_the_tcp_like_least_cost_takes_its_gap_relative_to_the_problem(monkeypatch, scale, a, horizon, psi,
                                                                       certified):
    """The least J*_tcp over mu in [0, 1] of a scalar plant (at mu = 1), with the cut LP's lower bound planted 1e-3
    (relative) below it. The problem's size is J*(0), its largest cost. Above the band (a = 1, N = 1: the least cost
    is 1e-3 of J*(0), far above ALLOCATION_GAP_FLOOR of it) the gap is 1e-3 > MIN_COST_RTOL, not certified, at every
    scale of the weights; below it (a = 10, N = 12: the least cost is 1e-22 of J*(0)) the gap is taken of the floor,
    1e-12 J*(0), and certified, at every scale. The absolute floor 1e-12 certified the first at scale 1e-20 and
    refused the second at 1e20."""
    from packetloss_cvx.allocation import tcp as tcp_module
    from packetloss_cvx.allocation.grammar import read_polytope
    from packetloss_cvx.allocation.udp import reported_gap

    real = tcp_module.small_lp

    def loose(c, *args, **kwargs):              # the cut LP (min t) proves 1e-3 less than it does
        point, lower = real(c, *args, **kwargs)
        if c[-1] == 1.0 and not np.any(c[:-1]) and point is not None:
            lower -= 1e-3 * abs(lower)
        return point, lower

    monkeypatch.setattr(tcp_module, "small_lp", loose)
    s = pl.System(A=[[a]], B=[[1.0]], horizon=horizon, state_weight=[scale], input_weight=[psi * scale], mu=[0.5],
                  x0=[1.0])
    out = tcp_module.tcp_min_cost(s, read_polytope([], 1, 0.0, 1.0))
    least, size = _scalar_lq(a, horizon, scale, psi * scale, 1.0), _scalar_lq(a, horizon, scale, psi * scale, 0.0)
    assert out.value == pytest.approx(least, rel=1e-9)
    assert out.scale == pytest.approx(size, rel=1e-9)
    expected = 1e-3 * least / max(least, 1e-12 * size)      # the planted 1e-3, and the LP's own 1e-6 at most
    assert reported_gap(out.value, out.lower_bound, out.scale) == pytest.approx(expected, rel=1e-3)
    assert (expected < 1e-6) == certified
    assert out.status == ("optimal" if certified else "gap_not_certified")


def test_a_failed_cut_lp_proves_only_the_constant_cost(monkeypatch):
    """The cut LP of the TCP-like least cost is feasible by construction ((mu, ceiling) meets every tangent cut), so
    its 'infeasible' is a failure: the bound is then the constant cost C (here 0: no noise, no initial weight), not
    the least cost itself (a gap of 0, certified, before)."""
    from packetloss_cvx.allocation import tcp as tcp_module
    from packetloss_cvx.allocation.grammar import read_polytope

    real = tcp_module.small_lp

    def failing(c, *args, **kwargs):
        if c[-1] == 1.0 and not np.any(c[:-1]):
            return None, np.inf                 # what small_lp returns for an LP it finds infeasible
        return real(c, *args, **kwargs)

    monkeypatch.setattr(tcp_module, "small_lp", failing)
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1e-3], mu=[0.5], x0=[1.0])
    out = tcp_module.tcp_min_cost(s, read_polytope([], 1, 0.0, 1.0))
    assert out.value == pytest.approx(_scalar_lq(1.0, 1, 1.0, 1e-3, 1.0), rel=1e-9)
    assert out.lower_bound == 0.0
    assert out.status == "gap_not_certified"
    assert "the cut LP failed" in out.note


@pytest.mark.parametrize(("protocol", "bounds"), [("tcp", (0.0, 1.0)), ("udp", (0.0, 1.0)), ("udp", (0.0, 0.9))])
@pytest.mark.parametrize(("factor", "proved"), [(3.0, True), (0.3, False)])
def test_infeasibility_is_proved_only_beyond_allocation_cost_rtol(two_actuator, protocol, bounds, factor, proved):
    """alpha just below the least reachable cost, J* at the upper corner of the bounds (J* falls in every mu_i,
    Theorem 3): the allocation proves infeasibility only where J*(corner) > alpha (1 + ALLOCATION_COST_RTOL), the
    accuracy it trusts the closed form to. At 3 times the band below: InfeasibleError; at 0.3 times: no proof either
    way (SolverError), never an answer. Bounds (0, 1) are decided by the TCP-like relaxation's corner (both
    protocols), (0, 0.9) by the UDP-like boxes (the relaxation is feasible there)."""
    from packetloss_cvx.errors import InfeasibleError, SolverError
    from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL

    corner = pl.closed_form(two_actuator.with_mu([bounds[1]] * 2), protocol).cost
    alpha = corner / (1 + factor * ALLOCATION_COST_RTOL)
    by = "at the upper corner of the bounds" if bounds[1] == 1.0 else "every box was proven infeasible"
    with pytest.raises(InfeasibleError if proved else SolverError, match=by if proved else "solver status"):
        allocate(two_actuator, protocol, alpha, [1.0, 1.0], bounds=bounds, max_boxes=50)


@pytest.mark.parametrize(("factor", "accepted"), [(3.0, True), (0.3, False)])
def test_a_gap_finer_than_allocation_gap_min_is_refused_naming_gap(two_actuator, factor, accepted):
    """The smallest gap an allocation may be asked to certify is ALLOCATION_GAP_MIN (finer would be finer than the
    closed form's trusted accuracy): 3 times it is taken, 0.3 times it is refused before any work, naming gap."""
    from packetloss_cvx.tolerances import ALLOCATION_GAP_MIN

    gap = factor * ALLOCATION_GAP_MIN
    if accepted:
        got = allocate(two_actuator, "tcp", 8.0, [1.0, 1.0], gap=gap)
        assert got.gap <= gap or got.status == "gap_not_certified"
    else:
        with pytest.raises(pl.InputError, match=r"^gap: expected a number in \["):
            allocate(two_actuator, "tcp", 8.0, [1.0, 1.0], gap=gap)


def test_a_tangent_cut_is_loosened_by_allocation_cost_rtol_of_the_value_and_gradient():
    """Each tangent cut of J*_tcp is lowered by ALLOCATION_COST_RTOL (|J*| + ||grad||_1) for the closed form's
    rounding: at its own touching point the cut lies exactly that far below J*. One step of x' = x + v u from x0 = 1:
    J*_tcp = 1 / (1 + mu), gradient -1 / (1 + mu)^2 (by hand), so at mu = 1/2 the cut is 10/9 ALLOCATION_COST_RTOL
    below 2/3 (to 1e-6 of that amount: a band moved 10x either way fails)."""
    from packetloss_cvx.allocation.tcp import tangent_cuts
    from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL

    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    S, r = tangent_cuts(s, np.array([0.5]))
    below = 2 / 3 - (r[0] + S[0, 0] * 0.5)
    assert S[0, 0] == pytest.approx(-4 / 9, rel=1e-12)
    assert below == pytest.approx(ALLOCATION_COST_RTOL * (2 / 3 + 4 / 9), rel=1e-6)


@pytest.mark.parametrize(("factor", "status"), [(3.0, "gap_not_certified"), (0.3, "optimal")])
def test_tcp_min_cost_is_optimal_only_within_min_cost_rtol(monkeypatch, factor, status):
    """The TCP-like least cost is certified ("optimal") when its gap to the tangent cuts' bound is within
    MIN_COST_RTOL. One step of x' = x + v u from x0 = 1 with mu <= 0.6: the least is J*_tcp(0.6) = 1 / 1.6 (by hand,
    J* falls in mu); the cuts planted lower by factor MIN_COST_RTOL J* make the gap that (plus their own 1e-9
    loosening): "gap_not_certified" at 3, "optimal" at 0.3, the reported gap the planted one either way."""
    import packetloss_cvx.allocation.tcp as tcp_module
    from packetloss_cvx.tolerances import MIN_COST_RTOL

    least = 1 / 1.6
    real = tcp_module.tangent_cuts

    def lowered(*args, **kwargs):
        S, r = real(*args, **kwargs)
        return S, r - factor * MIN_COST_RTOL * least

    monkeypatch.setattr(tcp_module, "tangent_cuts", lowered)
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    got = min_cost(s, "tcp", constraints=[(np.array([[1.0]]), np.array([0.6]))])
    assert got.status == status
    assert got.cost == pytest.approx(least, rel=1e-12)
    assert got.gap == pytest.approx(factor * MIN_COST_RTOL, rel=0.01)


def test_udp_min_cost_certifies_min_cost_rtol_and_stops_there(two_actuator):
    """The UDP-like least cost is certified to MIN_COST_RTOL: the reported gap is within it, and the search stops at
    the first box that certifies it (on this problem the gap halves every other box, measured 2e-6, 2e-6, 9.9e-7,
    so it ends within (MIN_COST_RTOL / 2, MIN_COST_RTOL]); a search aiming 10 times finer ends below a tenth, one
    aiming 10 times coarser above it."""
    from packetloss_cvx.tolerances import MIN_COST_RTOL

    rows = [(np.array([[1.0, 1.0]]), np.array([1.2]))]
    got = min_cost(two_actuator, "udp", constraints=rows)
    assert got.status == "optimal"
    assert MIN_COST_RTOL / 10 < got.gap <= MIN_COST_RTOL
    assert got.gap == pytest.approx((got.cost - got.lower_bound) / got.cost, rel=1e-9)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_constraints_contradictory_by_less_than_the_solver_tolerance_are_infeasible(two_actuator, protocol):
    """mu1 + mu2 >= 1.5 and mu1 + mu2 <= 1.5 - 1e-12 admit no channel: proved exactly, not 'optimal' within the LP
    tolerance (both protocols returned status optimal, the TCP-like one 4.6e-10 below the first row)."""
    tight = [parse_constraint("mu1 + mu2 >= 1.5", 2), parse_constraint("mu1 + mu2 <= 1.499999999999", 2)]
    with pytest.raises(pl.InfeasibleError, match="contradiction proved in exact rational arithmetic"):
        allocate(two_actuator, protocol, alpha=8.0, beta=[1.0, 1.0], constraints=tight)
    touching = [parse_constraint("mu1 + mu2 >= 1.5", 2), parse_constraint("mu1 + mu2 <= 1.5", 2)]
    result = allocate(two_actuator, protocol, alpha=8.0, beta=[1.0, 1.0], constraints=touching)
    assert result.status == "optimal"
    assert result.mu.sum() == pytest.approx(1.5, abs=1e-8)


def test_exact_emptiness_is_decided_against_an_enumeration_of_vertices():
    """Random 2-channel polytopes: empty exactly when no point of a fine grid plus every pairwise row intersection
    satisfies the rows (an independent test of feasibility in the plane)."""
    from itertools import combinations

    from packetloss_cvx.allocation.grammar import _proved_empty

    rng = np.random.default_rng(3)
    for _ in range(200):
        G = rng.normal(size=(3, 2))
        h = rng.normal(size=3) * 0.5
        lines = [*zip(G, h, strict=True), (np.array([1.0, 0.0]), 1.0), (np.array([-1.0, 0.0]), 0.0),
                 (np.array([0.0, 1.0]), 1.0), (np.array([0.0, -1.0]), 0.0)]
        points = []
        for (g1, c1), (g2, c2) in combinations(lines, 2):
            M = np.vstack([g1, g2])
            if abs(np.linalg.det(M)) > 1e-9:
                points.append(np.linalg.solve(M, [c1, c2]))
        feasible = any(np.all(G @ p <= h + 1e-9) and np.all(p >= -1e-9) and np.all(p <= 1 + 1e-9) for p in points)
        assert _proved_empty(G, h, 0.0, 1.0) == (not feasible)


class _PerCall:
    """J*(mu) by closed_form on every call, as the allocation did before the cached evaluator."""

    def __init__(self, system, protocol):
        self.system, self.protocol = system, protocol

    def cost(self, mu, x0=None, checked=True):      # closed_form checks every value anyway
        return pl.closed_form(self.system.with_mu(np.clip(mu, 0.0, 1.0)), self.protocol).cost

    def solve(self, mus):
        sols = [pl.closed_form(self.system.with_mu(mu), self.protocol) for mu in mus]
        return SimpleNamespace(costs=np.array([s.cost for s in sols]), inputs=np.array([s.inputs for s in sols]))

    def line(self, mu, i, checked=True):
        def at(value, base=np.array(mu, dtype=float)):  # noqa: B008
            point = base.copy()
            point[i] = value
            return self.cost(point)
        return at


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_allocation_through_the_evaluator_equals_the_per_call_closed_form(two_actuator, protocol, monkeypatch):
    cached = pl.allocate(two_actuator, protocol, 6.0, [1.0, 0.5])

    def per_call(system, p):
        ev = _PerCall(system, p)
        return ev.cost, ev

    monkeypatch.setattr(udp_module, "cost_function", per_call)
    monkeypatch.setattr(tcp_module, "cost_function", per_call)
    reference = pl.allocate(two_actuator, protocol, 6.0, [1.0, 0.5])
    assert np.allclose(cached.mu, reference.mu, rtol=0, atol=1e-9)
    assert abs(cached.lower_bound - reference.lower_bound) <= 1e-9 * reference.lower_bound
    assert (cached.status, cached.boxes) == (reference.status, reference.boxes)


def test_tcp_allocation_takes_a_point_of_the_polytope_where_the_socp_meets_a_row_only_to_its_tolerance():
    """The two-mass spring at N = 5 with mu2 >= mu1 + 0.05: Clarabel's point missed the row by 1.4e-9 (its own
    feasibility tolerance, scaled), more than the LP's ALLOCATION_LP_FEASIBILITY, and the allocation raised
    'constraint_violation'. Every mu of the polytope meets alpha here (J*_tcp(0, 0) < alpha), so by hand the
    cheapest is the polytope's least beta'mu point, (0, 0.05), beta'mu = 0.1."""
    from .test_allocation_attainable import spring

    s0 = spring()
    s = pl.System(A=s0.A, B=s0.B, horizon=5, state_weight=[1, 1, 1, 1], input_weight=[1, 1], mu=[0.9, 0.9],
                  x0=[1, 0, 0, 0])
    alpha = 1.5 * pl.closed_form(s.with_mu([1.0, 1.0]), "tcp").cost
    assert pl.closed_form(s.with_mu([0.0, 0.0]), "tcp").cost < alpha          # every mu is feasible
    a = allocate(s, "tcp", alpha, [1, 2], constraints=[parse_constraint("mu2 >= mu1 + 0.05", 2)])
    assert a.mu[0] + 0.05 - a.mu[1] <= ALLOCATION_LP_FEASIBILITY
    assert np.allclose(a.mu, [0.0, 0.05], atol=1e-8)
    assert a.communication_cost == pytest.approx(0.1, abs=2e-8)
    assert a.lower_bound <= a.communication_cost
    assert a.status == "optimal"
    assert pl.closed_form(s.with_mu(a.mu), "tcp").cost <= alpha


def test_an_alpha_just_below_the_least_cost_prints_the_two_apart():
    """alpha 2e-8 (relative) below the least reachable cost (J* at the upper corner, every packet delivered: the
    closed form) is refused with both numbers printed to the digits that tell them apart: "alpha = 1.92192 is below
    the least reachable udp-like cost 1.92192" read as a contradiction."""
    import re

    from packetloss_cvx.allocation.boxes import cost_at
    system = pl.load_example("two_actuator")
    least = cost_at(system, "udp", np.ones(system.m))
    alpha = float(f"{least * (1 - 2e-8):.10g}")
    with pytest.raises(pl.InfeasibleError, match="below the least reachable udp-like cost") as info:
        allocate(system, "udp", alpha, [1.0, 1.0])
    text = str(info.value)
    shown_alpha = re.search(r"alpha = ([0-9.e+-]+) is below", text).group(1)
    shown_least = re.search(r"udp-like cost ([0-9.e+-]+) within", text).group(1)
    assert shown_alpha != shown_least
    assert float(shown_alpha) < float(shown_least)
    assert float(shown_least) == pytest.approx(least, rel=1e-8)
    corner = re.search(r"upper corner of the bounds, ([0-9.e+-]+), exceeds alpha = ([0-9.e+-]+),", text)
    assert float(corner.group(2)) < float(corner.group(1))
