"""``solve`` on a Gilbert–Elliott file: the section under its heading reads as sentences, and its stability
verdicts follow the proven rule (is_mean_square_stable), with the radius recomputed independently."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx import load_example
from packetloss_cvx.cli import main
from packetloss_cvx.closedloop.stability import is_mean_square_stable
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.lq.markov_cost import exact_closed_form

from ..conftest import EXAMPLES


def enumerated_radius(system, gain):
    """The coupled operator of a one-channel Gilbert loop written out by hand (rows: next mode)."""
    ch = system.channel
    p, r = ch.p[0], ch.r[0]
    G = system.A - system.B @ gain
    kg, kb = np.kron(G, G), np.kron(system.A, system.A)             # good: delivered; bad: lost
    op = np.block([[(1 - p) * kg, r * kb], [p * kg, (1 - r) * kb]])
    return float(max(abs(np.linalg.eigvals(op))))


def test_solve_section_reads_and_uses_the_proven_rule(capsys):
    assert main(["solve", "pendulum_bursty", "--no-qp", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)["markov"]
    s = load_example("pendulum_bursty")
    for protocol in ("tcp", "udp"):
        gains = {"plug_in": closed_form(s.with_mu(s.mu_schedule), protocol).gain,
                 "exact": exact_closed_form(s, protocol).gain}
        for kind, gain in gains.items():
            radius = data[protocol]["mean_square_radius"][kind]
            assert abs(radius - enumerated_radius(s, gain)) <= 1e-10 * radius
            assert data[protocol]["stable"][kind] is is_mean_square_stable(radius)
    assert main(["solve", "pendulum_bursty", "--no-qp"]) == 0
    text = capsys.readouterr().out
    section = text.split("Gilbert-Elliott channel\n", 1)[1]
    assert section.startswith("p = [0.02] (P(good -> bad)), r = [0.18]")
    assert "0.0000%" not in section
    assert "(equal within 5e-9 relative) (the TCP-like cost holds only the marginals" in section   # exact minimiser
    assert "NOT mean-square stable" in section                        # the pendulum's plug-in loops (1.0124, 1.068)
    assert "(not stable)" not in section


def test_the_gilbert_elliott_section_is_headed_once(capsys):
    """The text printed 'Gilbert-Elliott channel' as a heading and again as the next line's label."""
    assert main(["solve", "pendulum_bursty", "--no-qp"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sum(line.startswith("Gilbert-Elliott channel") for line in lines) == 1



def test_a_chain_beyond_the_mjls_size_is_not_stable_and_not_bad_input():
    """solve on a valid 7-channel Gilbert-Elliott file exited 2 ('expected at most 6 channels') from its
    stability line: the MJLS operator's 2^m modes are out of reach, the file is not bad input."""
    from packetloss_cvx.cli.solve import stability
    from packetloss_cvx.model.channel import GilbertElliott
    system = pl.System(A=[[0.9, 0.1], [0.0, 0.8]], B=np.ones((2, 7)), horizon=3, state_weight=[1.0, 1.0],
                       input_weight=[1.0] * 7, channel=GilbertElliott(p=[0.1] * 7, r=[0.3] * 7), x0=[1.0, 1.0])
    entry: dict = {}
    text = stability(system, np.zeros((7, 2)), entry)
    assert entry["stable"] is False
    assert entry["mean_square_spectral_radius"] is None
    assert "not computed" in text



def test_a_small_real_plug_in_loss_is_not_printed_as_zero(capsys, tmp_path):
    # lambda = 1e-3 at the pendulum's rate 0.9: the UDP-like plug-in law loses 4.4e-8 relative (it scales as
    # lambda^2: 4.4e-10 at 1e-4), and solve printed it as "(+0.0000%)" beside two visibly different costs
    text = (EXAMPLES / "pendulum_bursty.toml").read_text()
    lam, mu = 1e-3, 0.9
    path = tmp_path / "nearly_bernoulli.toml"
    path.write_text(text.replace("p = [0.02]", f"p = [{(1 - mu) * (1 - lam)!r}]")
                    .replace("r = [0.18]", f"r = [{mu * (1 - lam)!r}]"))
    assert main(["solve", str(path), "--protocol", "udp", "--no-qp", "--json"]) == 0
    loss = json.loads(capsys.readouterr().out)["markov"]["udp"]["relative_loss"]
    assert 1e-8 < loss < 1e-7
    assert main(["solve", str(path), "--protocol", "udp", "--no-qp"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("UDP-like exact"))
    assert "0.0000%" not in line
    assert f"({100 * loss:+.3g}%)" in line


def test_a_plug_in_loss_is_equal_within_five_self_check_rtols_and_a_loss_beyond():
    """The section's words for the plug-in law's relative loss: below 5 SELF_CHECK_RTOL (the precision each of the two
    costs is checked to, twice over, with room) "equal within 5e-9 relative"; a loss of 3 times that band is printed
    as a loss, one of 0.3 times is not, on both signs."""
    from packetloss_cvx.cli.markov_section import _percent
    from packetloss_cvx.tolerances import SELF_CHECK_RTOL

    band = 5 * SELF_CHECK_RTOL
    for sign in (1.0, -1.0):
        assert _percent(sign * 0.3 * band) == "equal within 5e-9 relative"
        assert _percent(sign * 3 * band) == f"{100 * sign * 3 * band:+.3g}%"
    assert band == pytest.approx(5e-9)                 # the printed "5e-9" is this band


def test_solve_shows_the_attainable_tcp_cost_beside_the_prior_mean_formula(capsys):
    """The issue's numbers: the paper's J*_tcp at the prior mean (9111.31) labelled as such, and the least cost of
    any law with acknowledgements behind the chain (10668.7, the DP of tests/closedloop/test_chain_dp.py)."""
    assert main(["solve", "pendulum_bursty", "--no-qp", "--json", "--protocol", "tcp"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["tcp"]["basis"] == "paper, prior-mean rates"
    assert round(data["tcp"]["cost"], 2) == 9111.31
    tcp = data["markov"]["tcp"]
    assert tcp["basis"] == "paper, prior-mean rates"
    assert tcp["attainable"]["basis"] == "attainable"
    assert round(tcp["attainable"]["cost"], 1) == 10668.7
    assert tcp["attainable"]["exact"] is True
    assert main(["solve", "pendulum_bursty", "--no-qp", "--protocol", "tcp"]) == 0
    text = capsys.readouterr().out
    assert "[basis: paper, prior-mean rates]" in text
    assert "attainable: J = 10668.66352" in text


def test_attainable_cost_is_not_given_with_lossy_sensor_links():
    from packetloss_cvx.cli.markov_section import attainable_entry
    from packetloss_cvx.model.channel import GilbertElliott

    sensed = load_example("pendulum_sensor")
    entry, text = attainable_entry(sensed.with_channel(GilbertElliott(p=[0.02] * sensed.m, r=[0.18] * sensed.m)))
    assert entry["cost"] is None
    assert entry["exact"] is False
    assert "sensor" in text
