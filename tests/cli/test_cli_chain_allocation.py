"""``allocate FILE`` behind a Markov chain: the verdict and the attainable cost at mu* in the JSON, and the warning
line's advice saying what applies behind a chain (``--target stable|dp-cost`` do not: each is refused, exit 2, one
line; the advised ``region FILE --grid 21`` runs and gives the chain's critical mean rate, and the advised
``--target attainable`` meets alpha).

Independent references, written here: the scalar rule ``a^2 (1 - r) < 1`` behind a Gilbert channel (r = mu (1 -
lambda) at burstiness lambda held), and the attainable cost by the brute-force DP over delivery histories of
tests/closedloop/test_chain_dp.py.
"""

import json
import sys
from pathlib import Path

import pytest

from packetloss_cvx import System
from packetloss_cvx.cli import main
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import save_system
from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL, PATH_AGREEMENT_RTOL

LAM = 0.1          # the file's burstiness, held along the family


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def chain_file(tmp_path):
    """x' = 1.5 x + v u behind a Gilbert channel, mean rate 0.9, burstiness 0.1."""
    s = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.1 * (1 - LAM)], r=[0.9 * (1 - LAM)]))
    return str(save_system(s, tmp_path / "scalar_chain.toml"))


def test_a_chain_allocation_no_law_holds_warns_with_what_applies_behind_a_chain(capsys, chain_file):
    sys.path.insert(0, str(Path(__file__).parents[1] / "closedloop"))
    from test_chain_dp import brute_force_dp

    code, out, err = run(capsys, "allocate", chain_file, "--protocol", "tcp", "--alpha", "6", "--beta", "1", "--json")
    assert (code, err) == (0, "")
    data = json.loads(out)
    mu = data["mu"][0]
    assert 2.25 * (1 - mu * (1 - LAM)) >= 1                     # by hand: no law holds the loop at this mu*
    assert data["stabilisable"] is False
    at = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                channel=GilbertElliott(p=[(1 - mu) * (1 - LAM)], r=[mu * (1 - LAM)]))
    reference = brute_force_dp(at)
    assert data["attainable_cost"] == pytest.approx(reference, rel=PATH_AGREEMENT_RTOL)

    code, out, err = run(capsys, "allocate", chain_file, "--protocol", "tcp", "--alpha", "6", "--beta", "1")
    assert code == 0
    [line] = [text for text in out.splitlines() if text.startswith("warning:")]
    assert "no linear law holds the loop" in line
    assert "--target stable or --target dp-cost" not in line                # the Bernoulli advice is not offered
    assert "behind a chain --target stable|dp-cost do not apply" in line
    assert f"packetloss-cvx region {chain_file} --grid 21" in line
    assert reference > 6.0                                                # the attainable cost misses alpha
    assert "--target attainable designs on the chain's attainable cost" in line

    for target in ("stable", "dp-cost"):                                  # the advice is right: neither applies
        extra = ["--alpha", "6"] if target == "dp-cost" else []
        code, out, err = run(capsys, "allocate", chain_file, "--protocol", "tcp", "--beta", "1", "--target", target,
                             *extra)
        assert (code, out) == (2, ""), target
        assert err.count("\n") == 1, err
    code, out, err = run(capsys, "allocate", chain_file, "--protocol", "tcp", "--alpha", "6", "--beta", "1", "--target",
                         "attainable", "--json")                         # and what is advised runs
    assert (code, err) == (0, "")
    mu = json.loads(out)["mu"][0]
    assert brute_force_dp(at.with_channel(GilbertElliott(p=[(1 - mu) * (1 - LAM)], r=[mu * (1 - LAM)]))) <= 6.0 * (
        1 + ALLOCATION_COST_RTOL)
    code, out, err = run(capsys, "region", chain_file, "--grid", "21", "--json")
    assert (code, err) == (0, "")
    critical = json.loads(out)["dp"]["critical_mu"][0]
    assert critical == pytest.approx((1 - 1 / 2.25) / (1 - LAM), abs=1e-5)       # a^2 (1 - mu (1 - lambda)) = 1


def test_a_bernoulli_allocation_keeps_the_loop_targets_advice(capsys, tmp_path):
    """x' = 2 x + v u, one step: J*_tcp = 4 - 2 mu <= alpha = 3 at mu* = 0.5, where no law holds the loop
    (4 (1 - mu) >= 1): the advice is the loop targets, which apply to Bernoulli channels."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = str(save_system(s, tmp_path / "scalar.toml"))
    code, out, _ = run(capsys, "allocate", path, "--protocol", "tcp", "--alpha", "3", "--beta", "1")
    assert code == 0
    [line] = [text for text in out.splitlines() if text.startswith("warning:")]
    assert line.endswith("(design on the loop: --target stable or --target dp-cost)")
