"""``packetloss_cvx.closed_form`` carries its receding-horizon law's mean-square verdict (closedloop.law_stability),
shown in the repr, the notebook view and ``solve``; a law unstable even with every packet delivered is flagged in
one line. References: hand values on one state, and the Kronecker matrix of the second-moment map over the enumerated
deliveries, written here."""

import itertools
import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.cli.solve import run
from packetloss_cvx.closedloop.law_stability import STABILITY_MAX_N
from packetloss_cvx.lq.costs import closed_form as paper_closed_form
from packetloss_cvx.model.files import save_system
from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

#: x' = 2 x + v u, N = 1, weights 1 and 2: UDP-like u = -2x/3 (E[(2x + v u)^2 + 2 v u^2] least there), so
#: A - B K = 4/3 with every packet delivered, and at mu = 1/2 the second moment grows by (4/3)^2/2 + 4/2 = 26/9
SCALAR = pl.System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[2.0], mu=[0.5], x0=[1.0])


def kronecker_radius(A, B, K, mu):
    """The radius of E_v[(A - B V K) (x) (A - B V K)] over the 2^m delivery vectors v."""
    L = 0.0
    for v in itertools.product((0.0, 1.0), repeat=len(mu)):
        p = np.prod(np.where(np.array(v) == 1.0, mu, 1.0 - mu))
        M = A - B @ np.diag(v) @ K
        L = L + p * np.kron(M, M)
    return float(max(abs(np.linalg.eigvals(L))))


def test_closed_form_attaches_the_verdict_and_keeps_the_paper_numbers():
    s = pl.load_example("two_actuator")
    for protocol in ("tcp", "udp"):
        sol = pl.closed_form(s, protocol)
        plain = paper_closed_form(s, protocol)
        assert sol.cost == plain.cost
        assert np.array_equal(sol.inputs, plain.inputs)
        expected = kronecker_radius(s.A, s.B, sol.gain, s.mu_schedule[0])
        assert sol.stability.radius == pytest.approx(expected, rel=PATH_AGREEMENT_RTOL)
        assert sol.stability.stable == (expected < 1)
        assert sol.to_dict()["stable"] == (expected < 1)


def test_hand_case_unstable_over_the_channel_and_with_every_packet_delivered():
    sol = pl.closed_form(SCALAR, "udp")
    assert sol.gain[0, 0] == pytest.approx(2 / 3, rel=PATH_AGREEMENT_RTOL)
    assert sol.stability.radius == pytest.approx(26 / 9, rel=PATH_AGREEMENT_RTOL)
    assert sol.stability.stable is False
    text = repr(sol)
    assert "loop='NOT mean-square stable, radius 2.88889'" in text
    assert "all_delivered='UNSTABLE even with every packet delivered (radius of A - B K = 1.33333)'" in text
    page = sol._repr_html_()
    assert "UNSTABLE even with every packet delivered" in page
    assert "NOT mean-square stable" in page


def test_the_flag_follows_the_all_delivered_radius_alone():
    sol = pl.closed_form(SCALAR.with_mu([1.0]), "udp")      # mu = 1: u = -2x/3 still, A - B K = 4/3
    assert "all_delivered=" in repr(sol)
    stable = pl.closed_form(pl.load_example("two_actuator"), "tcp")
    assert max(abs(stable.closed_loop_eigenvalues)) < 1
    assert "all_delivered" not in repr(stable)
    assert "loop='mean-square stable, radius" in repr(stable)


def test_the_verdict_is_skipped_on_request_and_beyond_the_cheap_size():
    assert pl.closed_form(SCALAR, "udp", stability=False).stability is None
    n = STABILITY_MAX_N + 1
    big = pl.System(A=0.5 * np.eye(n), B=np.ones((n, 1)), horizon=1, state_weight=np.ones(n), input_weight=[1.0],
                    mu=[0.5], x0=np.ones(n))
    assert pl.closed_form(big, "tcp").stability is None
    assert "not computed" in pl.closed_form(big, "tcp")._repr_html_()


def test_solve_names_the_basis_and_flags_the_all_delivered_instability(tmp_path):
    path = str(save_system(SCALAR, tmp_path / "scalar.toml"))
    result = run(build_parser().parse_args(["solve", path, "--no-qp", "--protocol", "udp"]))
    data = json.loads(json.dumps(result.data))
    assert data["udp"]["basis"] == "paper"
    flagged = [line for line in result.text.splitlines() if "UNSTABLE even with every packet delivered" in line]
    assert len(flagged) == 1
    assert "1.33333" in flagged[0]
