"""``solve`` on a Gilbert–Elliott file: the section under its heading reads as sentences, and its stability
verdicts follow the proven rule (is_mean_square_stable), with the radius recomputed independently."""

import json

import numpy as np

from packetloss_cvx import load_example
from packetloss_cvx.cli import main
from packetloss_cvx.costs import closed_form
from packetloss_cvx.markov import exact_closed_form
from packetloss_cvx.simulation import is_mean_square_stable


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
