"""The stabilisable set and critical probabilities (simulation/region.py, region_lmi.py, critical.py).

References: hand values (scalar state: min_k rho = a^2 (1 - mu), and with several channels
a^2 / (1 + sum of odds)), decoupled plants (per-channel thresholds 1 - 1/a_i^2), the second-moment
operator enumerated over all 2^m delivery patterns, and random gains against an infeasibility certificate.
"""


import numpy as np
import pytest

from packetloss_cvx import CrossCheckError, System, load_example
from packetloss_cvx.closedloop import critical as critical_module
from packetloss_cvx.closedloop import region
from packetloss_cvx.closedloop.critical import critical_mu, critical_point
from packetloss_cvx.closedloop.region import certificate_margin, homogeneous_riccati, membership
from packetloss_cvx.closedloop.region_lmi import LmiForm
from packetloss_cvx.tolerances import CRITICAL_MU_TOL, LEAST_RADIUS_ATOL, MEAN_SQUARE_MARGIN

from ..plants import chain, decoupled, scalar, single_input_plant
from ..references import enumerated_radius


@pytest.mark.parametrize("mu", [0.3, 0.74, 0.7499, 0.7501, 0.76, 0.95])
def test_membership_scalar_all_forms_agree_with_the_hand_threshold(mu):
    s = scalar(2.0)
    found = membership(s, [mu])
    assert found.verdict == ("stable" if mu > 0.75 else "unstable")
    assert all(v in (found.verdict, "undecided") for _, v in found.forms)
    assert dict(found.forms)["riccati"] == found.verdict
    assert dict(found.forms)["lmi"] == found.verdict
    if found.stable:   # the gain's radius by enumeration: (a - mu k)^2 + mu (1 - mu) k^2
        k = found.gain[0, 0]
        assert (2.0 - mu * k) ** 2 + mu * (1 - mu) * k * k < 1.0
        assert enumerated_radius(s.A, s.B, found.gain, [mu]) < 1.0
    else:              # P = 1: T = [[a^2 - 1, -a mu], [-a mu, mu]] >= 0 iff mu (a^2 - 1) >= a^2 mu^2
        assert found.certificate[0, 0] == pytest.approx(1.0)
        assert mu * 3.0 - 4.0 * mu * mu >= 0
        assert found.certificate_margin >= 0 or found.certificate_margin > -1e-12


def test_homogeneous_riccati_scalar_is_the_least_radius():
    for a, mu in [(2.0, 0.5), (3.0, 0.9), (1.5, 0.2)]:
        lam, P, K = homogeneous_riccati(np.array([[a]]), np.array([[1.0]]), np.array([mu]))
        assert lam == pytest.approx(a * a * (1 - mu), rel=1e-12)
        assert K[0, 0] == pytest.approx(a, rel=1e-12)


def test_scalar_state_two_channels_region_is_one_plus_sum_of_odds():
    """x+ = a x + b1 v1 u1 + b2 v2 u2: min_K rho = a^2 / (1 + s1 + s2), s_i = mu_i / (1 - mu_i) (the
    mean inputs h_i = b_i mu_i k_i minimise (a - h1 - h2)^2 + sum (1 - mu_i)/mu_i h_i^2)."""
    a = np.sqrt(3.0)
    s = scalar(a, (1.0, 0.5))
    rng = np.random.default_rng(0)
    for mu in rng.uniform(0.05, 0.95, size=(12, 2)):
        odds = mu / (1 - mu)
        lam, _, _ = homogeneous_riccati(s.A, s.B, mu)
        assert lam == pytest.approx(3.0 / (1 + odds.sum()), rel=1e-10)
        if abs(3.0 / (1 + odds.sum()) - 1) > 1e-6:
            assert membership(s, mu).stable == (odds.sum() > 2.0)


def test_the_region_is_not_convex_in_mu():
    """mathematics.md §2: with a^2 = 3 the boundary is s1 + s2 = 2: (0.67, 0) and (0, 0.67) are inside (s = 2.03),
    their midpoint (0.335, 0.335) is outside (s1 + s2 = 1.01)."""
    s = scalar(np.sqrt(3.0), (1.0, 1.0))
    assert membership(s, [0.67, 0.0]).stable
    assert membership(s, [0.0, 0.67]).stable
    assert membership(s, [0.335, 0.335]).stable is False


def test_critical_mu_dp_scalar_meets_its_tolerance_on_both_sides():
    """A = 2, B = 1, Psi = 0.1, Omega = 1 and other scalars: exact 1 - 1/a^2 (0.75 at a = 2), met within the tolerance
    from both sides (a bisection stopped early would report 0.750004768)."""
    for a in (2.0, 1.5, 3.0, 10.0):
        exact = 1 - 1 / a ** 2
        for psi in (0.1, 1.0, 100.0):
            point = critical_point(scalar(a, psi=psi), "dp")
            assert point.lower <= exact <= point.t
            assert point.t - point.lower <= 1e-6
            found = critical_mu(scalar(a, psi=psi), "dp")
            assert found.t == point.t
            assert found.mu.tolist() == [point.t]             # mu beside t: the ray's default direction is 1


@pytest.mark.parametrize("a", [(2.0, 1.5), (3.0, 1.2, 0.5), (1.1, 4.0)])
def test_critical_mu_dp_decoupled_plants_give_the_per_channel_thresholds(a):
    s = decoupled(a)
    thresholds = np.array([max(0.0, 1 - 1 / x ** 2) for x in a])
    assert critical_mu(s, "dp", direction=np.ones(len(a))).t == pytest.approx(thresholds.max(), abs=1e-6)
    assert critical_mu(s, "dp").mu == pytest.approx(np.full(len(a), thresholds.max()), abs=1e-6)  # default: ones
    d = np.linspace(1.0, 0.8, len(a))
    point = critical_point(s, "dp", direction=d)
    exact = float(np.max(thresholds / d))
    if exact > 1.0:    # the ray ends at t = 1 / max(d) = 1 before the slowest channel's threshold
        assert point.t == np.inf
        assert point.outside.verdict == "unstable"
    else:
        assert point.lower <= exact + 1e-12
        assert exact <= point.t <= exact + 1e-6


def test_a_boundary_point_has_a_gain_inside_and_a_certificate_outside():
    s = load_example("two_actuator")
    point = critical_point(s, "dp", direction=[1.0, 1.0])
    inside, outside = point.inside, point.outside
    assert point.t - point.lower <= 1e-6
    assert inside.verdict == "stable"
    assert enumerated_radius(s.A, s.B, inside.gain, inside.mu) < 1.0
    assert outside.verdict == "unstable"
    P, mu = outside.certificate, outside.mu
    assert np.linalg.eigvalsh(P)[-1] > 0                # a certificate: P not <= 0
    assert np.trace(P) == pytest.approx(1.0)
    # no gain beats the certificate: random gains and the DP gain just inside, all with radius >= 1 at mu
    rng = np.random.default_rng(1)
    gains = [inside.gain, *(inside.gain + rng.normal(scale=x, size=inside.gain.shape) for x in (1e-3, 0.1, 1.0))]
    for K in gains:
        assert enumerated_radius(s.A, s.B, K, mu) >= 1.0 - 1e-9


def test_certificate_margin_is_exact_on_the_scalar_case():
    """The margin is the radius bound P proves, minus one: scalar R(p) = a^2 (1 - mu) p, so a^2 (1 - mu) - 1 (hand);
    two channels on one state: a^2 / (1 + s1 + s2) - 1, s_i the odds (mathematics.md)."""
    A, B = np.array([[2.0]]), np.array([[1.0]])
    for mu in (0.2, 0.5, 0.74, 0.9):
        assert certificate_margin(A, B, np.array([mu]), np.eye(1)) == pytest.approx(4.0 * (1 - mu) - 1, abs=1e-14)
    assert certificate_margin(A, B, np.array([0.5]), -np.eye(1)) == -np.inf
    mu = np.array([0.3, 0.6])
    odds = mu / (1 - mu)
    margin = certificate_margin(np.array([[np.sqrt(3.0)]]), np.array([[1.0, 0.5]]), mu, np.eye(1))
    assert margin == pytest.approx(3.0 / (1 + odds.sum()) - 1, abs=1e-14)


@pytest.mark.parametrize("seed", range(6))
def test_membership_forms_agree_on_random_plants(seed):
    rng = np.random.default_rng(seed)
    n, m = 2 + seed % 2, 2
    A = rng.normal(size=(n, n)) * 1.3
    B = rng.normal(size=(n, m))
    s = System(A=A, B=B, horizon=2, state_weight=[1.0] * n, input_weight=[1.0] * m, mu=[1.0] * m, x0=[1.0] * n)
    form = region.LazyLmi(A, B)
    for mu in rng.uniform(0.0, 1.0, size=(4, m)):
        found = membership(s, mu, lmi=form)   # CrossCheckError if two forms decide differently
        lam = homogeneous_riccati(A, B, mu)[0]
        if found.stable:
            assert enumerated_radius(A, B, found.gain, mu) < 1.0
        elif found.stable is False:
            assert lam >= 1.0 - 1e-9
        if abs(lam - 1) > 1e-3:   # away from the boundary both certificates are checkable
            assert found.verdict == ("stable" if lam < 1 else "unstable")


def test_disagreeing_forms_raise_cross_check_error(monkeypatch):
    """Planted: a certificate check that accepts everything makes "riccati" say unstable where "dp" finds a
    stabilising solution."""
    s = scalar(2.0)
    monkeypatch.setattr(region, "homogeneous_riccati", lambda A, B, mu: (2.0, np.eye(1), np.zeros((1, 1))))
    monkeypatch.setattr(region, "certificate_margin", lambda A, B, mu, P: 0.0)
    monkeypatch.setattr(region, "outside_proved", lambda A, B, mu, P, c: True)
    with pytest.raises(CrossCheckError, match="disagree"):
        membership(s, [0.9], forms=("dp", "riccati"))


def test_a_solver_failure_is_not_a_verdict(monkeypatch):
    from packetloss_cvx import SolverError

    def fail(self, mu):
        raise SolverError("numerical_error", "planted")

    monkeypatch.setattr(LmiForm, "stabilise", fail)
    found = membership(scalar(2.0), [0.5], forms=("lmi",))
    assert found.verdict == "undecided"
    assert found.stable is None
    assert "no form" in found.reason


def test_critical_mu_dp_never_reads_undecided_as_unstable(monkeypatch):
    """Planted: every form undecided inside (0.7, 0.8): the bisection moves only on decided points and, when a
    bracket wider than tol cannot be decided, returns it with its two proved ends and a note saying so."""
    true_membership = region.membership

    def blind(system, mu, **kw):
        found = true_membership(system, mu, **kw)
        if 0.7 < float(np.asarray(mu)[0]) < 0.8:
            return found.__class__(found.mu, "undecided", None, np.nan, None, np.nan, (), "planted")
        return found

    monkeypatch.setattr(critical_module, "membership", blind)
    wide = critical_mu(scalar(2.0), "dp")
    assert wide.lower <= 0.7
    assert wide.t >= 0.8
    assert wide.outside.verdict == "unstable"
    assert wide.inside.verdict == "stable"
    assert "wider than tol = 1e-06" in wide.note
    assert critical_mu(scalar(2.0), "dp", tol=0.2).note == ""
    point = critical_point(scalar(2.0), "dp", tol=0.2)   # 0.5 out, 0.75 blind, 0.625 out, 0.8125 in
    assert (point.lower, point.t) == (0.625, 0.8125)
    assert point.inside.verdict == "stable"
    assert point.outside.verdict == "unstable"


def test_lmi_gain_is_stabilising_by_enumeration():
    s = load_example("two_actuator")
    form = LmiForm(np.asarray(s.A, float), np.asarray(s.B, float))
    t, K, status = form.stabilise(np.array([0.3, 0.6]))
    assert status == "optimal"
    assert t > 0
    assert enumerated_radius(s.A, s.B, K, [0.3, 0.6]) < 1.0


def test_region_map_laws_side_by_side_on_the_scalar_plant():
    """Hand values: S = {mu > 0.75}; the DP gain fixed at mu = 1 (k = a p / (psi + p), the DARE) is stable iff
    (a - mu k)^2 + mu (1 - mu) k^2 < 1; every law's region lies inside S."""
    from packetloss_cvx.studies.region_map import region_map
    s = scalar(2.0, psi=1.0)
    r = region_map(s, laws=("dp", "fixed", "tcp", "udp"))
    points = dict(zip(r.laws, r.critical, strict=True))
    assert points["dp"].lower <= 0.75 <= points["dp"].t <= 0.75 + 1e-6
    p = 2.0 + np.sqrt(5.0)           # DARE p^2 - 4p - 1 = 0 (a = 2, q = r = 1): p = 2 + sqrt(5), k = 2p / (1 + p)
    k = 2 * p / (1 + p)
    exact = 3.0 / (4 * k - k * k)    # (a - mu k)^2 + mu (1 - mu) k^2 = a^2 - mu (2 a k - k^2) = 1
    assert points["fixed"].lower <= exact <= points["fixed"].t <= exact + 1e-6
    for law in ("tcp", "udp", "fixed"):
        assert points[law].t >= points["dp"].lower


def test_region_map_grid_is_inside_the_stabilisable_set_and_matches_decoupled_thresholds():
    from packetloss_cvx.studies.region_map import region_map
    s = decoupled((2.0, 1.5))
    r = region_map(s, laws=("dp", "tcp"), grid=6)
    axis = r.axis
    expected = (axis[None, :] > 0.75) & (axis[:, None] > 1 - 1 / 2.25)   # rows mu_2, columns mu_1
    assert np.array_equal(r.stable[0] == 1.0, expected)
    assert not np.any((r.stable[1] == 1.0) & (r.stable[0] == 0.0))
    d = r.to_dict()
    assert set(d) == {"dp", "tcp"}
    assert d["dp"]["grid"]["axis"] == axis.tolist()
    assert d["dp"]["critical_mu"] == pytest.approx([0.75, 0.75], abs=1e-6)


@pytest.mark.parametrize(("kwargs", "field"), [({"direction": [1.0, -1.0]}, "direction"),
                                               ({"grid": 3, "channels": (0, 2)}, "channels"),
                                               ({"grid": 3, "channels": (1, 1)}, "channels"),
                                               ({"laws": ("mpc",)}, "law"), ({"grid": 1}, "grid")])
def test_region_map_rejects_bad_input(kwargs, field):
    from packetloss_cvx import InputError
    from packetloss_cvx.studies.region_map import region_map
    with pytest.raises(InputError, match=field):
        region_map(decoupled((2.0, 1.5)), **kwargs)


def test_region_map_refuses_a_huge_grid():
    from packetloss_cvx.errors import BudgetError
    from packetloss_cvx.studies.region_map import region_map
    with pytest.raises(BudgetError, match="PACKETLOSS_CVX_BUDGET_REGION_POINTS") as err:
        region_map(decoupled((2.0, 1.5)), grid=10 ** 4)          # 4e8 law-points, refused before any work
    assert err.value.field == "grid"


def test_region_map_to_xarray_holds_the_same_grid():
    pytest.importorskip("xarray")
    from packetloss_cvx.studies.region_map import region_map
    r = region_map(decoupled((2.0, 1.5)), laws=("dp",), grid=4)
    ds = r.to_xarray()
    assert np.array_equal(ds["stable"].values, r.stable, equal_nan=True)
    assert ds["mu1"].values.tolist() == r.axis.tolist()
    assert float(ds["t"].sel(law="dp")) == r.critical[0].t


def test_results_pickle_and_to_dict_are_plain():
    import json
    import pickle

    from packetloss_cvx.studies.region_map import region_map
    r = region_map(decoupled((2.0, 1.5)), laws=("dp", "fixed"), grid=3)
    back = pickle.loads(pickle.dumps(r))
    assert np.array_equal(back.stable, r.stable)
    assert back.critical[0].inside.verdict == "stable"
    json.dumps(r.to_dict(), allow_nan=False)
    json.dumps(r.critical[0].to_dict(), allow_nan=False)
    assert r.stable.flags.writeable is False


@pytest.mark.parametrize("mu", [[1.0, 0.22], [1.0, 0.44], [0.33, 1.0], [1.0, 1.0]])
def test_riccati_form_decides_where_a_deadbeat_law_exists(mu):
    """B = I and mu_i = 1: min_K rho can be 0 and R(P) vanishes to rounding; a power iteration that divides by that
    rounding (lambda = -6.4 at (1, 0.44)) would leave these points undecided."""
    s = load_example("two_actuator")
    found = membership(s, mu, forms=("riccati",))
    assert found.verdict == "stable"
    assert enumerated_radius(s.A, s.B, found.gain, mu) < 1.0


@pytest.mark.parametrize("law", ["tcp", "udp"])
def test_critical_mu_of_the_paper_laws_against_their_hand_gains(law):
    """Horizon 1, x+ = 2x + v u, Omega = 1, Psi = 0.1: Theorem 1's first gain is k = a / (mu + psi) (TCP-like;
    Hessian mu^2 + mu psi) and k = a / (1 + psi) (UDP-like; + mu (1 - mu)); the law is proved stable iff
    a^2 - 2 a mu k + mu k^2 < 1 - MEAN_SQUARE_MARGIN. Root by brentq, both bracket ends checked."""
    from scipy.optimize import brentq

    from packetloss_cvx.tolerances import MEAN_SQUARE_MARGIN
    a, psi = 2.0, 0.1
    s = System(A=[[a]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[psi], mu=[1.0], x0=[1.0])

    def gain(mu):
        return a / (mu + psi) if law == "tcp" else a / (1 + psi)

    def excess(mu):
        k = gain(mu)
        return a * a - 2 * a * mu * k + mu * k * k - (1 - MEAN_SQUARE_MARGIN)

    exact = brentq(excess, 0.5, 1.0, xtol=1e-14)
    point = critical_point(s, law)
    assert point.lower <= exact <= point.t <= point.lower + 1e-6
    assert point.inside.gain[0, 0] == pytest.approx(gain(point.t), rel=1e-9)
    assert point.inside.radius < 1 - MEAN_SQUARE_MARGIN <= point.outside.radius


def test_region_map_on_dask_is_bit_identical():
    distributed = pytest.importorskip("distributed")
    import logging

    from packetloss_cvx.studies.region_map import region_map
    s = load_example("two_actuator")
    here = region_map(s, laws=("dp", "tcp", "fixed"), grid=7)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp",
                                  host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR) as cluster:
        there = region_map(s, laws=("dp", "tcp", "fixed"), grid=7, dask=cluster.scheduler_address)
    assert np.array_equal(here.stable, there.stable, equal_nan=True)
    assert np.array_equal(here.radius, there.radius, equal_nan=True)
    from packetloss_cvx import InputError
    with pytest.raises(InputError, match="dask"):
        region_map(s, laws=("dp",), grid=3, dask="no address")


def test_homogeneous_riccati_batch_agrees_with_its_points_and_the_hand_values():
    """A stack of channels is one batch (the region map's DP radius): each point agrees with the same point alone
    to RICCATI_RTOL, the scalar two-channel points with a^2 / (1 + sum of odds), and a positive lambda is the
    mean-square radius of its own gain (the Perron eigenpair, enumerated over the delivery patterns)."""
    rng = np.random.default_rng(3)
    s = scalar(np.sqrt(3.0), (1.0, 0.5))
    mus = rng.uniform(0.05, 0.95, size=(25, 2))
    lam, P, K = homogeneous_riccati(s.A, s.B, mus)
    odds = mus / (1 - mus)
    assert lam == pytest.approx(3.0 / (1 + odds.sum(axis=1)), rel=1e-10)
    two = load_example("two_actuator")
    axis = np.linspace(0.0, 1.0, 9)
    cases = [(two.A, two.B, np.array([[a, b] for b in axis for a in axis]))]
    for _ in range(6):
        n, m = rng.integers(1, 4, size=2)
        cases.append((rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.uniform(size=(12, m))))
    for A, B, mus in cases:
        A, B = np.asarray(A, float), np.asarray(B, float)
        lam, P, K = homogeneous_riccati(A, B, mus)
        assert lam.shape == (len(mus),)
        assert P.shape == (len(mus), *A.shape)
        assert K.shape == (len(mus), *B.T.shape)
        for g, mu in enumerate(mus):
            one = homogeneous_riccati(A, B, mu)
            scale = max(1.0, abs(one[0]))
            assert abs(lam[g] - one[0]) <= 1e-12 * scale
            assert np.allclose(K[g], one[2], rtol=1e-10, atol=1e-12 * max(1.0, float(np.abs(one[2]).max())))
            if lam[g] > 1e-6:
                assert enumerated_radius(A, B, K[g], mu) == pytest.approx(lam[g], rel=1e-8)


def test_homogeneous_riccati_deadbeat_point_handed_over_early_resumes_its_power_steps():
    """A point the power iteration hands to the policy iteration early (its steps shrink too slowly) whose first
    policy step is degenerate (lambda = 0: a deadbeat law, its Perron eigenvector not PSD) resumes its power steps,
    as without the hand-off. Reference by hand: A diagonal with distinct eigenvalues, B with no zero entry
    (controllable, one input), every packet delivered: the deadbeat gain (Ackermann) makes A - BK nilpotent, so
    min_K rho(L_K) = rho(A - BK)^2 = 0. Stopping at the hand-off instead leaves lambda = 0.0019."""
    A, B, mu = np.diag([-0.5, -0.1, 0.2]), np.array([[1.0], [2.0], [0.5]]), np.array([1.0])
    C = np.hstack([B, A @ B, A @ A @ B])                          # Ackermann: K = e_n' C^-1 A^3
    deadbeat = np.linalg.solve(C, np.linalg.matrix_power(A, 3))[-1:]
    assert np.allclose(np.linalg.matrix_power(A - B @ deadbeat, 3), 0.0, atol=1e-12)
    lam, P, K = homogeneous_riccati(A, B, mu)
    assert lam == 0.0                                             # (A, b) controllable, delivered always: exactly 0
    assert enumerated_radius(A, B, K, mu) <= 1e-6                 # the gain found is (nearly) deadbeat too
    batch = homogeneous_riccati(A, B, np.array([[1.0], [0.5]]))   # the same point inside a batch: the same steps
    assert batch[0][0] == 0.0
    assert enumerated_radius(A, B, batch[2][0], mu) <= 1e-6


def test_membership_runs_the_dp_form_only_where_a_gain_could_pass(monkeypatch):
    """The "dp" form proves only "stable" (radius < 1 - 1e-9). Scalar a = 2 at mu = 0.75, by hand: every gain's
    radius is (a - mu k)^2 + mu (1 - mu) k^2 >= a^2 (1 - mu) = 1, and the "riccati" form's P = 1 shows it (R(1) = 1),
    so the DP is not run there (its value iteration would crawl to its step cap) and the verdict stays undecided;
    nor where the "riccati" form proved "unstable" (mu = 0.6: radius >= 1.6). Where it proved "stable" (0.9) the DP
    still runs as the cross-check."""
    s = scalar(2.0)
    ran = []
    real = region.dp_riccati
    monkeypatch.setattr(region, "dp_riccati",
                        lambda system, mu, **start: ran.append(float(mu[0])) or real(system, mu, **start))
    found = membership(s, [0.75], forms=("riccati", "dp"))
    assert ran == []
    assert found.verdict == "undecided"
    assert dict(found.forms) == {"riccati": "undecided", "dp": "undecided"}
    assert membership(s, [0.6], forms=("riccati", "dp")).verdict == "unstable"
    assert membership(s, [0.9], forms=("riccati", "dp")).verdict == "stable"
    assert ran == [0.9]


def test_membership_checks_a_given_eigenpair_at_its_own_mu():
    """The region map hands its batch's eigenpair to the membership's "riccati" form: a pair from another mu is
    checked at this mu, so its certificate P proves nothing there and its gain only what it proves at this mu
    (scalar a = 2: S = {mu > 0.75}; the pair at 0.5 has P = 1 and the gain k = a, whose radius a^2 (1 - mu) is 0.4 at
    mu = 0.9 by hand: a proved "stable" there, never "unstable")."""
    s = scalar(2.0)
    outside = homogeneous_riccati(s.A, s.B, np.array([0.5]))      # lambda 2, its P a certificate at 0.5
    inside = homogeneous_riccati(s.A, s.B, np.array([0.9]))       # lambda 0.4, gain k = 2
    found = membership(s, [0.9], forms=("riccati",), riccati=outside)
    assert found.verdict == "stable"
    assert found.radius == pytest.approx(4 * (1 - 0.9), rel=1e-12)
    assert membership(s, [0.5], forms=("riccati",), riccati=inside).verdict == "undecided"
    assert membership(s, [0.9], forms=("riccati",), riccati=inside).verdict == "stable"
    assert membership(s, [0.5], forms=("riccati",), riccati=outside).verdict == "unstable"


@pytest.mark.parametrize("mu", [[0.9, 1.0], [0.5, 1.0], [0.0, 1.0], [1.0, 0.9], [1.0, 0.0], [1.0, 1.0]])
def test_least_radius_is_zero_where_one_always_delivered_channel_deadbeats_the_plant(mu):
    """two_actuator with mu_2 = 1: (A, b_2) is controllable (A_12 = 0.005), so u_2 = -k x with
    k = (0.35 + 1.03^2 / 0.005, 2.04) makes A - b_2 k nilpotent (trace 0, determinant 0, by hand) and u_1 = 0:
    L_K(X) = F X F' with F^2 = 0, so min_K rho(L_K) = 0 (not a^2 (1 - mu_1) = 0.106, the channel-1 value); the
    same by symmetry through b_1 (A_21 = 0.35). Rounding can make the eigenvalue -9e-7 here (planted: the trace of
    A'PA - A'PBM K fails the sign check)."""
    s = load_example("two_actuator")
    A = np.asarray(s.A, float)
    k2 = np.array([A[1, 0] + A[0, 0] ** 2 / A[0, 1], A[0, 0] + A[1, 1]])
    F = A - np.outer([0.0, 1.0], k2)
    assert np.allclose(F @ F, 0.0, atol=1e-9)
    lam, P, K = homogeneous_riccati(A, np.asarray(s.B, float), np.array(mu))
    assert lam == 0.0


def test_least_radius_is_zero_at_a_single_input_deadbeat_point_handed_over_early():
    """x+ = diag(-0.39, 1.05, -0.13) x + b u, b = (1.5, 1.4, 2.3), mu = 1: (A, b) is controllable (distinct
    eigenvalues, no zero in b), so Ackermann's gain k = e3' C^-1 A^3 (C the controllability matrix) makes A - b k
    nilpotent (F^3 = 0) and min_K rho(L_K) = 0. simulation.region hands this point to the policy iteration after 4
    power steps (they shrink too slowly); the policy steps stop at rounding there (lambda 1.3e-7, not a fixed point
    of R), so the power iteration must take the point back, as without the hand-off."""
    A, b = np.diag([-0.39, 1.05, -0.13]), np.array([1.5, 1.4, 2.3])
    C = np.column_stack([b, A @ b, A @ A @ b])
    F = A - np.outer(b, np.linalg.solve(C.T, np.eye(3)[2]) @ np.linalg.matrix_power(A, 3))
    assert np.allclose(np.linalg.matrix_power(F, 3), 0.0, atol=1e-9)
    lam, P, K = homogeneous_riccati(A, b[:, None], np.array([1.0]))
    assert lam == 0.0


def test_region_map_radius_is_the_least_radius_never_negative_and_matches_the_lmi():
    """The "dp" radius grid is min_K rho(L_K) >= 0 (rounding gives -1.2e-9 and -9e-7 at deadbeat points), and
    at interior points it is bracketed by the LMI form run on the scaled plant A / sqrt(rho) (S_rho = S of
    A / sqrt(rho), the gain scaled back by sqrt(rho)): infeasible at 0.999 lambda, feasible at 1.001 lambda with
    a gain whose radius (enumerated over the delivery patterns) is below 1.001 lambda."""
    from packetloss_cvx.studies.region_map import region_map
    s = load_example("two_actuator")
    result = region_map(s, laws=("dp",), grid=11)
    radius = result.radius[0]
    assert np.all(np.isfinite(radius))
    assert np.all(radius >= 0.0)
    assert np.all(radius[-1] == 0.0)                  # mu_2 = 1 or mu_1 = 1: deadbeat, exactly 0
    assert np.all(radius[:, -1] == 0.0)
    A, B = np.asarray(s.A, float), np.asarray(s.B, float)
    for row, col in [(2, 6), (9, 9), (8, 2), (5, 0)]:
        mu = np.array([result.axis[col], result.axis[row]])
        lam = radius[row, col]
        below = LmiForm(A / np.sqrt(0.999 * lam), B).stabilise(mu)
        above = LmiForm(A / np.sqrt(1.001 * lam), B).stabilise(mu)
        assert below[0] < 0
        assert above[0] > 0
        assert enumerated_radius(A, B, np.sqrt(1.001 * lam) * above[1], mu) < 1.001 * lam
    assert "least mean-square radius" in result.to_dict()["dp"]["grid"]["radius_meaning"]


def test_least_radius_of_a_decoupled_plant_is_its_worst_block():
    """diag(a), B = I: min_K rho(L_K) = max_i a_i^2 (1 - mu_i), each block's scalar value (hand)."""
    a = np.array([2.0, 1.5, 0.5])
    rng = np.random.default_rng(4)
    mus = rng.uniform(0.0, 1.0, size=(10, 3))
    lam, _, _ = homogeneous_riccati(np.diag(a), np.eye(3), mus)
    assert lam == pytest.approx(np.max(a * a * (1 - mus), axis=1), rel=1e-9)


@pytest.mark.parametrize("mu2", [0.075947, 0.0759469])
def test_membership_with_large_gains_near_the_boundary_decides_instead_of_raising(mu2):
    """A = [[1.03, 5e-5], [0.35, 1.01]], B = I, mu = (0, mu2) about 1e-6 inside S: the least-radius gain is about
    620 and its radius 1 - 6e-7 (enumerated). The LMI's certificate there proves only rho >= 1 - 3.5e-6 for every
    law, but the least eigenvalue of T_mu(P) over its scale shrinks like 1 / ||K||^2 and passes CERTIFICATE_RTOL: a
    check with that margin raises CrossCheckError at both points (planted). The margin is the radius bound itself,
    so the LMI's P is refused and the point is decided by the forms that check."""
    A, B = np.array([[1.03, 5e-5], [0.35, 1.01]]), np.eye(2)
    s = System(A=A, B=B, horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0], mu=[0.5, 0.5], x0=[1.0, 1.0])
    mu = np.array([0.0, mu2])
    found = membership(s, mu)
    assert found.verdict == "stable"
    assert dict(found.forms)["lmi"] in ("stable", "undecided")
    assert np.abs(found.gain).max() > 100
    assert 1 - 1e-5 < enumerated_radius(A, B, found.gain, mu) < 1.0
    _, P, _ = LmiForm(A, B).certify(mu)
    assert -1e-4 < certificate_margin(A, B, mu, P) < -1e-7


def test_homogeneous_riccati_started_from_another_blocks_eigenvector_finds_the_dominant_block():
    # decoupled: lambda = max_i a_i^2 (1 - mu_i) by hand = 1.44 * 0.5 = 0.72 (block 1); a start concentrated on
    # block 2 (another channel's P) has no weight on block 1, which the mix with I / n restores
    a = np.array([1.2, 2.0, 0.5])
    A, B, mu = np.diag(a), np.eye(3), np.array([0.5, 0.9, 0.2])
    lam, P, K = homogeneous_riccati(A, B, mu, start=np.diag([0.0, 1.0, 0.0]))
    assert lam == pytest.approx(float(np.max(a**2 * (1 - mu))), rel=1e-10)
    assert P[0, 0] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_homogeneous_riccati_started_near_the_eigenvector_is_the_least_radius(seed, two_actuator):
    # a start from a nearby channel's P (as the design-for-stability search passes): lambda is its own gain's
    # radius (the operator's, enumerated over the delivery patterns) and the cold start's, and scalar by hand
    rng = np.random.default_rng(seed)
    mu = rng.uniform(0.05, 0.95, 2)
    A, B = two_actuator.A, two_actuator.B
    near = homogeneous_riccati(A, B, np.clip(mu + rng.normal(scale=0.02, size=2), 0.0, 1.0))[1]
    lam, _, K = homogeneous_riccati(A, B, mu, start=near)
    assert lam == pytest.approx(enumerated_radius(A, B, K, mu), rel=1e-9)
    assert lam == pytest.approx(homogeneous_riccati(A, B, mu)[0], rel=1e-10)
    scalar_lam = homogeneous_riccati(np.array([[2.0]]), np.array([[1.0]]), np.array([mu[0]]), start=np.eye(1))[0]
    assert scalar_lam == pytest.approx(4 * (1 - mu[0]), rel=1e-12)


def test_a_started_eigenpair_that_misses_the_dominant_block_is_no_verdict():
    # decoupled, mode 4 not actuated: every law leaves it x4' = a4 x4, so every radius is >= a4^2 = 4.58 by hand and
    # the plant is unstable at every mu. Started from the eigenpair at a nearby-in-the-search mu (as design for
    # stability passes it), the candidate may end on another block (lambda below 1): its gain must not pass, and the
    # forms together still find the certificate of instability
    A = np.diag([2.2328375202156794, 1.8467869759883448, 2.3686199262347265, 2.13978466512856])
    B = np.eye(4)[:, :3]
    before = np.array([0.49593374634389376, 0.4820853325965151, 0.7344779211378196])
    mu = np.array([0.9401060489353833, 0.4949396686027038, 0.5799140883727022])
    s = System(A=A, B=B, horizon=2, state_weight=np.ones(4), input_weight=np.ones(3), mu=mu, x0=np.ones(4))
    started = homogeneous_riccati(A, B, mu, start=homogeneous_riccati(A, B, before)[1])
    assert membership(s, mu, forms=("riccati",), riccati=started).verdict != "stable"
    found = membership(s, mu, riccati=started)
    assert found.verdict == "unstable"
    assert found.gain is None


def test_membership_of_a_chain_of_integrators_inside_s_is_never_unstable():
    """A = I4 + N, b = e4, mu = 0.0124: mu is in S (Elia: (1 - mu) |1|^8 < 1), the least radius is (1 - mu)^(1/4) =
    0.99689. A float-checked certificate claims "every law's radius >= 1.000664" ("unstable"); the verdict must be
    "stable" with a gain whose enumerated radius is below 1. Given the unscaled iteration's eigenpair (lambda
    1.0014, its P the float-checked certificate), the "riccati" form is not "unstable" either: the exact check
    refuses that P, and the pair's own gain (enumerated radius 0.9996) is what it proves."""
    s, mu = chain(1.0), np.array([0.0124])
    A, B = np.asarray(s.A, float), np.asarray(s.B, float)
    found = membership(s, mu, forms=("riccati", "dp"))
    assert found.verdict == "stable"
    assert enumerated_radius(A, B, found.gain, mu) < 1.0
    saved = region._GRADED
    try:
        region._GRADED = 0.0                                  # the iteration without its graded refinement
        wrong = homogeneous_riccati(A, B, mu)
    finally:
        region._GRADED = saved
    assert wrong[0] > 1.0
    given = membership(s, mu, forms=("riccati",), riccati=wrong)
    assert given.verdict != "unstable"
    if given.stable:
        assert enumerated_radius(A, B, given.gain, mu) < 1.0


@pytest.mark.parametrize(("a0", "mu"), [(1.0, 0.0124), (1.001, 0.002), (1.001, 0.0079), (1.001, 0.0186),
                                        (1.3, 0.5)])
def test_least_radius_of_a_jordan_chain_is_the_single_input_value(a0, mu):
    """One Jordan block of size 4, one input: S_rho (the set of mu with a law of radius < rho) is, by Elia's
    single-input theorem on A / sqrt(rho), (1 - mu) (a0^2 / rho)^4 < 1, so min_K rho(L_K) = a0^2 (1 - mu)^(1/4)
    (rho below a0^2). The P of this plant is graded (its diagonal spans 1e-14 ... 1): unscaled, the iteration had
    stopped 1e-2 off (1.0101 for 1.0015 at mu = 0.002); on the plant scaled by powers of two it agrees to the
    margin a radius is trusted to."""
    s = chain(a0)
    lam = homogeneous_riccati(np.asarray(s.A, float), np.asarray(s.B, float), np.array([mu]))[0]
    assert lam == pytest.approx(a0 ** 2 * (1 - mu) ** 0.25, rel=MEAN_SQUARE_MARGIN)


@pytest.mark.parametrize("seed", range(5))
def test_critical_mu_of_single_input_plants_is_one_minus_the_inverse_mahler_measure(seed):
    """Elia (2005): over one input erased with probability 1 - mu, mu is in S iff (1 - mu) prod |lambda_i(A)|^2 < 1
    over the unstable eigenvalues (Jordan blocks counted with their size). The DP law's critical point, bracketed
    by an exact stability witness and an exact infeasibility certificate, holds 1 - 1 / prod within
    CRITICAL_MU_TOL. (The 1.001 chain is the hard case: false "unstable" verdicts give 0.01866 for 0.00796.)"""
    s, mahler = single_input_plant(np.random.default_rng(seed)) if seed else (chain(1.001), 1.001 ** 8)
    exact = 1.0 - 1.0 / mahler
    point = critical_point(s, "dp")
    assert point.lower <= exact <= point.t
    assert point.t - point.lower <= CRITICAL_MU_TOL
    assert point.inside.verdict == "stable"
    assert point.outside is None or point.outside.verdict == "unstable"


def test_a_mode_no_input_reaches_is_decided_by_the_split():
    """A = [[0.5, 1], [0, 1.2]], b = e1: x2+ = 1.2 x2 whatever the law, so every law's radius is >= 1.44 and the
    least radius is 1.44 (the reached part's own, 0.25 (1 - mu), is smaller): "unstable" with margin 0.44 at every mu
    (hand). The eigenpair of the reached part (0.72) must not leave the form "undecided": both plants are decided
    alike, and the least radius is the unreached mode's."""
    for A in ([[0.5, 1.0], [0.0, 1.2]], [[0.5, 0.0], [0.0, 1.2]]):
        s = System(A=A, B=[[1.0], [0.0]], horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0], mu=[1.0],
                   x0=[1.0, 1.0])
        for mu in (0.1, 0.5, 1.0):
            found = membership(s, [mu], forms=("riccati",))
            assert found.verdict == "unstable"
            assert found.certificate_margin == pytest.approx(0.44, rel=1e-8)
            lam = homogeneous_riccati(np.asarray(s.A, float), np.asarray(s.B, float), np.array([mu]))[0]
            assert lam == pytest.approx(1.44, rel=1e-15)
    # two unreached modes, the 1.2 one coupled in: the least radius is still 1.44 (the unscaled and the balanced
    # iterations had ended on another eigenvector, 0.576 at mu = 0.6)
    A, b = np.array([[0.5, 1.0, 0.3], [0.0, 1.2, 1.0], [0.0, 0.0, 0.3]]), np.array([[1.0], [0.0], [0.0]])
    assert homogeneous_riccati(A, b, np.array([0.6]))[0] == pytest.approx(1.44, rel=1e-15)


@pytest.mark.parametrize("seed", range(4))
def test_least_radius_of_a_nilpotent_plant_is_zero_to_its_registered_floor(seed):
    """A = Q N Q' (N strictly upper triangular, Q orthogonal): K = 0 gives L_K = A (.) A', nilpotent, so
    min_K rho(L_K) = 0 at every mu (hand); no channel always delivers, so no structural rule applies and the power
    iteration's zero test ends it. Its value is zero to the absolute floor LEAST_RADIUS_ATOL ||A||_2^2 (the test's
    own bound). The PSD part of the last iterate had given up to 1e-5 ||A||^2 (and digits that moved with the BLAS
    kernel)."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    A, B = Q @ np.triu(2.0 * rng.normal(size=(3, 3)), 1) @ Q.T, rng.normal(size=(3, 1))
    lam, _, _ = homogeneous_riccati(A, B, np.array([[0.3], [0.7]]))
    assert np.all(lam >= 0.0)
    assert np.all(lam <= LEAST_RADIUS_ATOL * np.linalg.norm(A, 2) ** 2)


def test_a_gain_whose_float_radius_is_below_one_outside_s_is_not_proved_stable():
    """A = Q (1.01 I5 + N) Q' (one Jordan block, rotated), b = Q e5, mu = 3e-4 below Elia's critical 1 - 1.01^-10:
    no law stabilises. The gain below (the unscaled iteration's there, under the Haswell kernel) has a computed
    radius (the Kronecker matrix's eigenvalues, inaccurate on this near-defective operator) of 0.99809 under the
    Haswell and Zen kernels, 1.0053 under Prescott and Sandybridge, 1.0062 under Nehalem, 1.0111 under SkylakeX: a
    float check had called such points "stable" on some machines. Its exact witness fails under every kernel, so
    the law is "unstable" (not proved stable), and the membership is never "stable"."""
    Q, _ = np.linalg.qr(np.random.default_rng(4).normal(size=(5, 5)))
    A, B = Q @ (1.01 * np.eye(5) + np.eye(5, k=1)) @ Q.T, Q[:, 4:]
    mu = np.array([1.0 - 1.01 ** -10 - 3e-4])
    K = np.array([[-0.3534089184782489, -0.045768897755073895, 0.4469970598266664, 0.10674279979866828,
                   0.8780697419034694]])
    s = System(A=A, B=B, horizon=2, state_weight=[1.0] * 5, input_weight=[1.0], mu=[1.0], x0=[1.0] * 5)
    assert critical_module.law_membership(s, K, mu).verdict == "unstable"
    assert membership(s, mu, forms=("riccati", "dp")).verdict != "stable"
