"""What a loop attains at an allocation's mu (allocation.attainable): the attainable cost beside the paper's J*,
the mean-square verdict of the best linear law, the warning line, and ``allocate``'s targets.

Independent references, written here: the finite-horizon DP with acknowledgements by enumerating the 2^m delivery
outcomes of each step (not the moment formula of the package's Riccati step), the exact expected cost of that law by
enumerating every delivery path, and the least mean-square radius of any linear law by the power iteration of the
homogeneous modified Riccati map (again over enumerated deliveries) with the radius of its gain by the Kronecker
second-moment matrix.
"""

import itertools
import json

import numpy as np
import pytest
from scipy.linalg import expm

from packetloss_cvx import InputError, System, allocate, closed_form
from packetloss_cvx.allocation import parse_constraint
from packetloss_cvx.allocation.attainable import (
    AttainableEvaluator,
    attainment,
    stabilisable,
    tcp_attainable_cost,
)
from packetloss_cvx.cli.allocate import run
from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.model.files import save_system
from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL, ALLOCATION_GAP_DEFAULT, PATH_AGREEMENT_RTOL

#: the issue's coupled plant: allocate(s, "tcp", 8, [1, 1]) designs mu = (0.131, 0.169) on J*_tcp = 8
COUPLED = System(A=[[1.03, 0.005], [0.35, 1.01]], B=np.eye(2), horizon=10, state_weight=[1, 1],
                 input_weight=[1, 1], mu=[0.9, 0.5], x0=[1, 1])


def spring() -> System:
    """Two masses, a spring between them (k = 1) and a destabilising spring from the wall to the first (k0 = -3:
    one unstable mode), a force on each; zero-order hold at dt = 0.1 (python-control when installed, else the
    block exponential [[A, B], [0, 0]] by scipy: the same discretisation), N = 10."""
    k0, k = -3.0, 1.0
    Ac = np.array([[0, 1, 0, 0], [-(k0 + k), 0, k, 0], [0, 0, 0, 1], [k, 0, -k, 0]], float)
    Bc = np.array([[0, 0], [1, 0], [0, 0], [0, 1]], float)
    try:
        import control
    except ImportError:
        block = expm(np.block([[Ac, Bc], [np.zeros((2, 6))]]) * 0.1)
        A, B = block[:4, :4], block[:4, 4:]
    else:
        d = control.c2d(control.ss(Ac, Bc, np.eye(4), np.zeros((4, 2))), 0.1, "zoh")
        A, B = np.asarray(d.A), np.asarray(d.B)
    return System(A=A, B=B, horizon=10, state_weight=[1, 1, 1, 1], input_weight=[1, 1], mu=[0.9, 0.9],
                  x0=[1, 0, 0, 0], name="two-mass spring")


def outcomes(mu):
    """Every delivery vector v in {0, 1}^m with its probability."""
    for v in itertools.product((0.0, 1.0), repeat=len(mu)):
        v = np.array(v)
        yield v, float(np.prod(np.where(v == 1.0, mu, 1.0 - mu)))


def enumerated_dp(s: System, mu):
    """The finite-horizon DP by enumerating each step's deliveries: gains K_t and the cost x0'P_0 x0 on the paper's
    cost (no weight on x0 here, Q = 0; Omega on x_1..x_N, Psi on the delivered inputs)."""
    A, B = s.A, s.B
    Omega, Psi = s.state_weights[0], np.diag(s.input_weights[0])
    P = Omega.copy()
    gains = []
    for t in reversed(range(s.horizon)):
        H = sum(p * (np.diag(v) @ (Psi + B.T @ P @ B) @ np.diag(v)) for v, p in outcomes(mu))
        g = sum(p * np.diag(v) @ B.T @ P @ A for v, p in outcomes(mu))
        K = np.linalg.lstsq(H, g, rcond=None)[0]                       # mu_i = 0: that input is never applied
        gains.append(K)
        P = A.T @ P @ A - g.T @ K + (Omega if t > 0 else 0.0)
    return gains[::-1], float(s.x0 @ P @ s.x0)


def path_cost(s: System, mu, gains) -> float:
    """The exact expected cost of u_t = -K_t x_t by enumerating every delivery path (4^N paths at m = 2)."""
    Omega, Psi = s.state_weights[0], np.diag(s.input_weights[0])
    x = s.x0[None, :]
    w = np.ones(1)
    total = 0.0
    for K in gains:
        nxt, ws = [], []
        for v, p in outcomes(mu):
            u = -(x @ K.T) * v
            y = x @ s.A.T + u @ s.B.T
            stage = np.einsum("ij,jk,ik->i", y, Omega, y) + np.einsum("ij,jk,ik->i", u, Psi, u)
            total += float(np.sum(w * p * stage))
            nxt.append(y)
            ws.append(w * p)
        x, w = np.concatenate(nxt), np.concatenate(ws)
    return total


def least_radius(A, B, mu, steps=1000):
    """min_K of the mean-square radius by the power iteration of R(P) = min_K E_v[(A - B V K)' P (A - B V K)] (the
    sum kept in its PSD form: A'PA - g'H^{-1}g loses P's semidefiniteness to cancellation here), and the Kronecker
    radius of the gain it ends at (the two agree at the fixed point). R(P) = lam P with P >= 0 proves every law's
    radius >= lam: L_K^*(P) >= R(P) for every K."""
    P = np.eye(A.shape[0])
    lam = np.nan
    for _ in range(steps):
        H = sum(p * np.diag(v) @ B.T @ P @ B @ np.diag(v) for v, p in outcomes(mu))
        g = sum(p * np.diag(v) @ B.T @ P @ A for v, p in outcomes(mu))
        K = np.linalg.lstsq(H, g, rcond=None)[0]
        R = sum(p * (A - B @ np.diag(v) @ K).T @ P @ (A - B @ np.diag(v) @ K) for v, p in outcomes(mu))
        lam = np.trace(R)
        P = R / np.trace(R)
    L = sum(p * np.kron(A - B @ np.diag(v) @ K, A - B @ np.diag(v) @ K) for v, p in outcomes(mu))
    return lam, float(np.max(np.abs(np.linalg.eigvals(L))))


def test_tcp_attainable_cost_is_the_enumerated_dp_and_the_path_enumeration_on_the_coupled_plant():
    a = allocate(COUPLED, "tcp", 8.0, [1, 1])
    gains, dp = enumerated_dp(COUPLED, a.mu)
    exact = path_cost(COUPLED, a.mu, gains)
    assert np.allclose(a.mu, [0.131, 0.169], atol=5e-4)
    assert a.cost <= 8.0 * (1 + ALLOCATION_COST_RTOL)
    assert dp == pytest.approx(exact, rel=PATH_AGREEMENT_RTOL)
    assert a.attainable_cost == pytest.approx(dp, rel=PATH_AGREEMENT_RTOL)
    assert round(a.attainable_cost, 2) == 38.08                       # the figure
    assert a.basis == "paper"
    assert a.stabilisable is True
    assert a.warning == f"warning: at mu* the attainable cost {a.attainable_cost:.6g} exceeds alpha = 8"


def test_tcp_attainable_cost_with_time_varying_weights_initial_weight_and_noise():
    """One step by hand: E[x'Qx + (x + v u)^2 w + v psi u^2 + w sigma] = q + w + mu u (2 w + (w + psi) u) + w sigma,
    least at u = -w / (w + psi): q + w - mu w^2 / (w + psi) + w sigma. Two steps: the step before sees P_1 =
    Omega_1 + that (with q = 0)."""
    q, w1, w2, psi0, psi1, sigma, mu = 0.5, 2.0, 3.0, 1.0, 4.0, 0.25, 0.6
    s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weights=[[w1], [w2]], input_weights=[[psi0], [psi1]],
               initial_weight=[[q]], noise_cov=[[sigma]], mu=[mu], x0=[1.0])
    p1 = w1 + w2 - mu * w2 ** 2 / (w2 + psi1)                           # cost-to-go at t = 1 (x_1's weight added)
    p0 = q + p1 - mu * p1 ** 2 / (p1 + psi0)
    assert tcp_attainable_cost(s) == pytest.approx(p0 + sigma * w2 + sigma * p1, rel=PATH_AGREEMENT_RTOL)
    # the checked value: the forward second moments of the DP's own law, which must agree
    assert AttainableEvaluator(s).cost(np.array([mu])) == pytest.approx(p0 + sigma * w2 + sigma * p1,
                                                                        rel=PATH_AGREEMENT_RTOL)


def test_attainable_cost_at_full_delivery_is_the_paper_cost():
    """With every packet delivered and no noise the DP law is the deterministic optimum: J*_tcp = J*_udp there."""
    s = COUPLED.with_mu([1.0, 1.0])
    assert tcp_attainable_cost(s) == pytest.approx(closed_form(s, "tcp").cost, rel=PATH_AGREEMENT_RTOL)


def test_udp_attainable_cost_is_its_own_cost():
    a = allocate(COUPLED, "udp", 8.0, [1, 1])
    assert a.attainable_cost == a.cost
    assert a.warning is None
    assert a.stabilisable is True


def test_spring_allocation_that_no_linear_law_stabilises_says_so():
    s = spring()
    alpha = 1.5 * closed_form(s, "tcp").cost
    a = allocate(s, "tcp", alpha, [1, 2], constraints=[parse_constraint("mu2 >= mu1 + 0.05", 2)])
    lam, radius = least_radius(s.A, s.B, a.mu)
    assert a.status == "optimal"
    assert a.cost <= alpha * (1 + ALLOCATION_COST_RTOL)
    assert lam == pytest.approx(radius, rel=PATH_AGREEMENT_RTOL)       # converged: 1.04919 both
    assert lam > 1.04
    assert a.stabilisable is False
    assert "no linear law" in a.stability_note
    assert a.warning.startswith("warning: at mu* no linear law holds the loop mean-square stable")


def test_stabilisable_verdicts_on_the_scalar_plant_either_side_of_the_critical_rate():
    """x' = 2 x + v u: some law holds the loop iff 4 (1 - mu) < 1."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    assert [stabilisable(s, np.array([mu]))[0] for mu in (0.74, 0.76)] == [False, True]


def test_behind_a_chain_the_tcp_attainable_cost_is_the_dp_with_acknowledgements_behind_it():
    """pendulum_bursty at its own rate: the issue's 10668.7 (the DP behind the Gilbert channel), not J*_tcp's 9111.31
    at the prior mean; the verdict of the best linear law is over the laws on the chain state the acknowledgements
    reveal (a Gilbert channel), as the enumerated least radius of tests/allocation/test_allocation_chain_stability.py
    says."""
    from packetloss_cvx import load_example

    from .test_allocation_chain_stability import least_radius_enumerated

    s = load_example("pendulum_bursty")
    found = attainment(s, "tcp", np.array([0.9]), 1.0)
    assert round(found.cost, 1) == 10668.7
    assert found.cost_note.startswith("exact: finite-horizon DP with acknowledgements")
    reference = least_radius_enumerated(s.A, s.B, list(s.channel.transition), list(s.channel.delivery))
    assert found.stabilisable is bool(reference < 1)
    assert "acknowledgements reveal" in found.stability_note


def test_tcp_allocation_behind_a_chain_carries_the_chain_dp_at_mu_star_with_burstiness_held():
    """The reference chain is written out here: a Gilbert channel with lambda = 1 - p - r = 0.8 held and mean rate
    r / (p + r) = mu*, i.e. p = (1 - mu)(1 - lambda), r = mu (1 - lambda); its DP by the brute-force enumeration
    of tests/closedloop/test_chain_dp.py over a short horizon."""
    import sys
    from pathlib import Path

    from packetloss_cvx.model.channel import GilbertElliott
    sys.path.insert(0, str(Path(__file__).parents[1] / "closedloop"))
    from test_chain_dp import brute_force_dp

    s = System(A=[[1.2]], B=[[1.0]], horizon=4, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.02], r=[0.18]))
    a = allocate(s, "tcp", 2.0, [1.0])
    mu = float(a.mu[0])
    reference = brute_force_dp(s.with_channel(GilbertElliott(p=[(1 - mu) * 0.2], r=[mu * 0.2])))
    assert a.attainable_cost == pytest.approx(reference, rel=PATH_AGREEMENT_RTOL)
    assert a.attainable_cost > a.cost                   # the paper's J*_tcp at mu* is below what any law attains


def test_behind_a_hidden_chain_beyond_the_budget_the_note_gives_both_bounds(monkeypatch):
    from packetloss_cvx.model.channel import GilbertElliott

    s = System(A=[[1.2]], B=[[1.0]], horizon=12, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.1], r=[0.3], h_good=[0.9], h_bad=[0.2]))
    exact = attainment(s, "tcp", s.channel.mean_rate, 1.0).cost
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_CHAIN_DP_NODES", "2000")
    found = attainment(s, "tcp", s.channel.mean_rate, 1.0)
    assert found.cost is None
    lower, upper = (float(found.cost_note.split(f"{word} ")[1].split(",")[0]) for word in ("lower", "upper"))
    assert lower <= exact * (1 + 1e-9)               # the note prints 10 significant digits
    assert exact <= upper * (1 + 1e-9)


def test_allocate_targets_match_stability_allocate_and_refuse_what_is_not_there():
    from packetloss_cvx.allocation.stability import stability_allocate

    s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    a = allocate(s, "tcp", None, [1.0], target="stable", margin=0.5)
    assert a.mu[0] == pytest.approx(0.875, abs=1e-4)                   # 4 (1 - mu) < 0.5
    assert np.array_equal(a.mu, stability_allocate(s, "stable", [1.0], margin=0.5).mu)
    d = allocate(s, "tcp", 10.0, [1.0], target="dp-cost")
    assert d.dp_cost <= 10.0
    with pytest.raises(InputError, match="expected one of paper, stable, dp-cost, attainable"):
        allocate(s, "tcp", 10.0, [1.0], target="cheap")
    with pytest.raises(InputError, match="margin"):
        allocate(s, "tcp", 10.0, [1.0], margin=0.5)


def test_cli_prints_one_warning_line_and_the_json_keys(tmp_path):
    path = str(save_system(spring(), tmp_path / "spring.toml"))
    alpha = 1.5 * closed_form(spring(), "tcp").cost
    result = run(build_parser().parse_args(["allocate", path, "--protocol", "tcp", "--alpha", repr(alpha), "--beta",
                                            "1,2", "--constraint", "mu2 >= mu1 + 0.05"]))
    warnings = [line for line in result.text.splitlines() if line.startswith("warning:")]
    assert result.code == 0
    assert len(warnings) == 1
    assert "no linear law" in warnings[0]
    data = json.loads(json.dumps(result.data))
    assert data["basis"] == "paper"
    assert data["stabilisable"] is False
    assert data["attainable_cost"] > alpha
    assert {"mu", "cost", "lower_bound", "status", "min_cost"} <= set(data)       # today's keys kept
    assert "J*(mu*), paper" in result.text
    assert "attainable cost" in result.text


def test_power_allocation_carries_the_enumerated_dp_at_its_mu():
    from packetloss_cvx.allocation.delivery import power_model
    from packetloss_cvx.allocation.power import least_power

    p = least_power(COUPLED, "tcp", power_model("rayleigh", 2, scale=1.0), 8.0)
    _, dp = enumerated_dp(COUPLED, p.mu)
    assert p.attainable_cost == pytest.approx(dp, rel=PATH_AGREEMENT_RTOL)
    assert p.to_dict()["attainable_cost"] == p.attainable_cost
    assert p.warning == f"warning: at mu* the attainable cost {p.attainable_cost:.6g} exceeds alpha = 8"


def test_ack_price_designs_carry_their_attainable_costs():
    from packetloss_cvx.allocation.ack import best_protocol

    c = best_protocol(COUPLED, 8.0, [1, 1])
    _, dp = enumerated_dp(COUPLED, c.tcp.mu)
    assert c.tcp.attainable_cost == pytest.approx(dp, rel=PATH_AGREEMENT_RTOL)
    assert c.udp.attainable_cost == c.udp.cost
    assert c.to_dict()["tcp"]["basis"] == "paper"


def test_stability_target_carries_the_finite_horizon_attainable_cost():
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    a = allocate(s, "tcp", None, [1.0], target="stable", margin=0.5)
    _, dp = enumerated_dp(s, a.mu)
    assert a.attainable_cost == pytest.approx(dp, rel=PATH_AGREEMENT_RTOL)
    assert a.stabilisable is True
    assert a.to_dict()["basis"] == "loop"


def least_mu2(mu1: float, alpha: float) -> float:
    """The least mu2 with the enumerated DP's cost <= alpha at (mu1, mu2), by bisection (the cost falls in mu2);
    1.5 where even mu2 = 1 is above alpha. The upper end of the final bracket: a feasible point."""
    if enumerated_dp(COUPLED, np.array([mu1, 1.0]))[1] > alpha:
        return 1.5
    lo, hi = 0.0, 1.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if enumerated_dp(COUPLED, np.array([mu1, mid]))[1] <= alpha else (mid, hi)
    return hi


def test_target_attainable_meets_alpha_on_the_enumerated_dp_and_matches_a_grid_search():
    a = allocate(COUPLED, "tcp", 8.0, [1, 1], target="attainable")
    assert a.status == "optimal"
    assert a.basis == "attainable"
    assert enumerated_dp(COUPLED, a.mu)[1] <= 8.0 * (1 + ALLOCATION_COST_RTOL)
    coarse = np.linspace(0.0, 1.0, 41)
    best = coarse[int(np.argmin([m + least_mu2(m, 8.0) for m in coarse]))]
    fine = np.linspace(max(best - 0.025, 0.0), min(best + 0.025, 1.0), 51)
    reference = min(m + least_mu2(m, 8.0) for m in fine)        # feasible points: at least the optimum
    assert a.lower_bound <= reference
    assert a.communication_cost <= reference * (1 + ALLOCATION_GAP_DEFAULT)     # the certified gap
    assert a.communication_cost >= reference - 1e-3            # the grid's step: the reference is that close
    # the acknowledgement price on the attainable basis: the UDP-like design against this one (the 0.345)
    udp = allocate(COUPLED, "udp", 8.0, [1, 1])
    assert round(udp.communication_cost - a.communication_cost, 3) == 0.345


@pytest.mark.parametrize("seed", range(5))
def test_the_attainable_cost_falls_in_every_delivery_probability(seed):
    """The property the attainable design's branch and bound rests on (docs/mathematics.md): with mu <= mu' the DP at
    mu' can emulate mu by sending zero with probability 1 - mu_i / mu'_i. Checked on the enumerated DP."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(2, 2)) * 0.8
    s = System(A=A, B=rng.normal(size=(2, 2)), horizon=6, state_weight=[1, 2], input_weight=[0.5, 1],
               mu=[0.5, 0.5], x0=rng.normal(size=2))
    for _ in range(20):
        mu = rng.uniform(size=2)
        more = mu + rng.uniform(size=2) * (1 - mu)
        assert enumerated_dp(s, more)[1] <= enumerated_dp(s, mu)[1] * (1 + PATH_AGREEMENT_RTOL)


def test_behind_a_chain_the_udp_cost_is_the_attainable_one_and_the_tcp_one_is_the_chain_dp():
    from packetloss_cvx.closedloop.chain_dp import chain_dp
    from packetloss_cvx.lq.markov_cost import exact_closed_form
    from packetloss_cvx.model.channel import GilbertElliott

    s = System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[0.0, 1.0], [1.0, 0.3]], horizon=4, state_weight=[1.0, 1.0],
               input_weight=[0.5, 0.5], x0=[1.0, 1.0], channel=GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35]))
    alpha = 1.1 * exact_closed_form(s, "udp").cost
    udp = allocate(s, "udp", alpha, [1.0, 2.0])
    assert udp.basis == "attainable"
    assert udp.attainable_cost == udp.cost
    from .test_allocation_chain_stability import gilbert, least_radius_enumerated

    lam0 = np.array([1 - 0.08 - 0.32, 1 - 0.35 - 0.35])
    at = gilbert(lam0, udp.mu)                                     # the chain at mu*, burstiness held
    reference = least_radius_enumerated(s.A, s.B, list(at.transition), list(at.delivery))
    assert abs(reference - 1) > 0.02
    if reference > 1:                     # no law holds the loop, whatever it knows
        assert udp.stabilisable is False
    else:                                 # a UDP-like loop gets no acknowledgements: only a state-free gain counts
        assert udp.stabilisable is not False
        assert udp.stabilisable is None or "ignores the chain state" in udp.stability_note
    tcp = allocate(s, "tcp", alpha, [1.0, 2.0])
    assert tcp.basis == "paper"
    lam = np.array([1 - 0.08 - 0.32, 1 - 0.35 - 0.35])            # each channel's burstiness, held at mu*
    held = GilbertElliott(p=(1 - tcp.mu) * (1 - lam), r=tcp.mu * (1 - lam))
    assert tcp.attainable_cost == pytest.approx(chain_dp(s.with_channel(held)).cost, rel=PATH_AGREEMENT_RTOL)
    assert tcp.attainable_note.startswith("exact: finite-horizon DP with acknowledgements")
    designed = allocate(s, "tcp", alpha, [1.0, 2.0], target="attainable")     # the chain DP along the family
    assert designed.basis == "attainable"
    at = GilbertElliott(p=(1 - designed.mu) * (1 - lam), r=designed.mu * (1 - lam))
    assert chain_dp(s.with_channel(at)).cost <= alpha * (1 + ALLOCATION_COST_RTOL)
