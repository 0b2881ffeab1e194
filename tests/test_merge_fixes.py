"""Defects found when the session's branches met on main."""

import pytest

import packetloss_cvx as pl
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.markov import bursty_twin, coupled_riccati


def test_coupled_riccati_without_stabilising_gains_is_a_numerical_error():
    """two_actuator behind Gilbert channels with lambda = 0.95: the coupled iteration diverged, and
    its overflowing S made np.linalg.solve raise LinAlgError ('unexpected LinAlgError' in simulate)."""
    system = bursty_twin(pl.load_example("two_actuator"), 0.95)
    with pytest.raises(NumericalError, match="not mean-square stabilisable"):
        coupled_riccati(system)


def test_burstiness_errors_name_the_flag_and_accept_a_leading_minus(capsys):
    from packetloss_cvx.cli import main

    assert main(["sweep", "two_actuator", "--burstiness", "-0.2,0.5", "-q"]) == 2   # parsed, then refused
    err = capsys.readouterr().err
    assert err.startswith("packetloss-cvx: error: --burstiness: lambda = -0.2 needs p or r above 1")
    assert "0.9000000000000001" not in err
    assert main(["sweep", "two_actuator", "--burstiness", "-0.05,0.5", "-q", "--json"]) == 0   # p, r stay in [0, 1]
    capsys.readouterr()


def test_closed_loop_claims_do_not_apply_to_a_chain(capsys):
    """The loop behind a Gilbert–Elliott chain is a jump system: mpc-vs-dp and the closed-loop ranking
    mark it not applicable ('.') instead of an error or an inconclusive verdict."""
    from packetloss_cvx.claims import audit

    results = audit([pl.load_example("pendulum_bursty")], random=0,
                    only=["mpc-vs-dp", "protocol-ranking-closed-loop"])
    for result in results:
        assert result.outcomes[-1] == ".", (result.claim_id, result.outcomes)
        assert result.errors == 0
