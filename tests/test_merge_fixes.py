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


def test_a_chain_file_is_audited_at_its_plug_in_rates_without_errors(capsys):
    """The paper's claims are stated for independent losses: a caller's Gilbert–Elliott system is audited
    at its plug-in mu_t (the closed-loop claims errored or were inconclusive on it)."""
    from packetloss_cvx.claims import audit

    results = audit([pl.load_example("pendulum_bursty")], random=0,
                    only=["mpc-vs-dp", "protocol-ranking-closed-loop", "theorem-2"])
    for result in results:
        assert result.errors == 0, (result.id, result.outcomes)
        assert result.outcomes[-1] in "+-.", (result.id, result.outcomes)


def test_the_udp_like_cost_of_a_chain_is_refused_not_the_plug_in_number():
    """closed_form(pendulum_bursty, "udp") returned 15706, the paper's formula on the chain's mu_t, while
    the expected cost of that plan under the chain is 51735: a number without a word. It is refused now,
    with the two ways out; the TCP-like cost (first moments only) stays exact."""
    from packetloss_cvx.errors import InputError
    from packetloss_cvx.markov import exact_closed_form, exact_cost

    s = pl.load_example("pendulum_bursty")
    for call in (lambda: pl.closed_form(s, "udp"), lambda: pl.solve_qp(s, "udp"),
                 lambda: pl.expected_cost(s, [[0.0]] * s.horizon, "udp")):
        with pytest.raises(InputError, match="exact_closed_form") as err:
            call()
        assert err.value.field == "channel"
    plug_in = pl.closed_form(s.with_mu(s.mu_schedule), "udp")
    assert exact_cost(s, plug_in.inputs, "udp") > 3 * plug_in.cost       # 51735 against 15706
    assert exact_closed_form(s, "udp").cost < exact_cost(s, plug_in.inputs, "udp")
    assert pl.closed_form(s, "tcp").cost == pytest.approx(exact_closed_form(s, "tcp").cost, rel=1e-10)


def test_to_xarray_without_the_extra_says_how_to_install_it():
    """After the README's `pip install .` (no xarray), the README's design-study block ended in a bare
    ModuleNotFoundError traceback."""
    import sys
    from unittest import mock

    from packetloss_cvx.errors import InputError
    from packetloss_cvx.studies import sweep

    result = sweep(pl.load_example("two_actuator"), mu_grid=3, progress=False)
    with mock.patch.dict(sys.modules, {"xarray": None}), pytest.raises(InputError, match=r"packetloss-cvx\[xarray\]"):
        result.to_xarray()


def test_plug_in_markov_checks_a_chain_file_behind_its_own_chain():
    """The audit gives the paper's claims a chain file's plug-in mu_t, but plug-in-markov must still see
    the file's own chain (not Gilbert twins of the plug-in rates)."""
    from packetloss_cvx.claims import audit
    from packetloss_cvx.claims.markov import plugin_loss
    from packetloss_cvx.tolerances import CROSS_CHECK_COST_RTOL

    system = pl.load_example("pendulum_bursty")
    (result,) = audit([system], random=0, only=["plug-in-markov"])
    assert result.outcomes[-1] == "-"
    own = CROSS_CHECK_COST_RTOL - plugin_loss(system, None)          # the file's chain: lambda = 0.8
    assert result.worst == pytest.approx(min(own, result.worst), rel=1e-12)
    assert own < -0.05                                                # the plug-in law loses ~7.9 % there
