"""``solve``'s exit code when a constrained program asked for is not solved, and the soft-row weight's range.

A constrained program the solver did not solve (status "failed": a solver error, or an answer whose KKT residual is
not trusted) is a failed computation: exit 1 (docs/design.md §4), the result still printed in full, its text saying
which protocol's program failed. A proven "infeasible" or an "undecided" certificate is an answer with its reason:
exit 0 as before.

A soft weight beyond `SOFT_WEIGHT_MAX_RATIO` times the cost scale (the largest weight) drives the solver out of its
range ("solver_error", or a false "infeasible"): exit 2 before any work, one line naming the flag or the file's key.

Hand values: the TCP-like J* of one step of x' = x + v u from x0 = 1 is min (1 + mu u)^2 + mu R u^2 = R / (mu + R).
With mu = 1/2, Q = 1, R = 2 (the scale is 2), |u| <= 0.1 and E[x_1] = 1 + u/2 <= 0.5 soft with weight rho, the
TCP-like cost (1 + u/2)^2 + u^2 + rho (1/2 + u/2) has slope 0.95 - 0.2 + rho/2 > 0 on [-0.1, 0.1], so u = -0.1
and the row is broken by 0.45, for every rho > 0.
"""

import json

import pytest

import packetloss_cvx.qp.constrained as constrained
from packetloss_cvx.cli import main
from packetloss_cvx.errors import NumericalError, SolverError
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import SOFT_WEIGHT_MAX_RATIO

SCALE = 2.0     # the largest weight of the plant below


def plant(tmp_path, name="scalar.toml", **table):
    s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[SCALE], mu=[0.5], x0=[1.0])
    return str(save_system(s, tmp_path / name, constraints=Constraints(**table) if table else None))


@pytest.mark.parametrize("error", [SolverError("solver_error", "the constrained QP gave no proven answer"),
                                   NumericalError("the KKT residual of the solver's answer is 3e-09")])
def test_a_constrained_program_not_solved_exits_1_with_the_result_printed(tmp_path, capsys, monkeypatch, error):
    path = plant(tmp_path, u_min=[-0.1], u_max=[0.1])

    def fails(*args, **kwargs):
        raise error

    monkeypatch.setattr(constrained, "solve_constrained", fails)
    assert main(["solve", path, "--no-stability", "--json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert [data[p]["constrained"]["status"] for p in ("tcp", "udp")] == ["failed", "failed"]
    assert data["tcp"]["cost"] == pytest.approx(SCALE / (0.5 + SCALE), rel=1e-12)   # R / (mu + R): still stands
    assert main(["solve", path, "--no-stability", "--protocol", "udp"]) == 1
    text = capsys.readouterr().out
    assert "constrained     not solved: " in text
    assert text.rstrip().splitlines()[-1] == "not solved: the constrained program of UDP-like (exit 1)"


def test_a_solved_or_proven_infeasible_program_exits_0(tmp_path, capsys):
    assert main(["solve", plant(tmp_path, u_min=[-0.1], u_max=[0.1]), "--no-stability"]) == 0
    assert "not solved" not in capsys.readouterr().out
    hard = plant(tmp_path, "hard.toml", u_min=[-0.1], u_max=[0.1], x_max=[0.5])     # 1 + u/2 <= 0.5 needs u <= -1
    assert main(["solve", hard, "--no-stability", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [data[p]["constrained"]["status"] for p in ("tcp", "udp")] == ["infeasible", "infeasible"]


@pytest.mark.parametrize("weight", ["1e308", f"{SOFT_WEIGHT_MAX_RATIO * SCALE * 1.05:g}", "inf", "0", "-1"])
def test_a_soft_weight_out_of_range_is_refused_naming_the_flag(tmp_path, capsys, monkeypatch, weight):
    monkeypatch.setattr(constrained, "solve_constrained", None)      # refused before any solve
    path = plant(tmp_path, u_min=[-0.1], u_max=[0.1], x_max=[0.5])
    assert main(["solve", path, "--soft", "--soft-weight", weight]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("packetloss-cvx: error: --soft-weight: expected ")


def test_a_files_soft_weight_out_of_range_is_refused_naming_its_key(tmp_path, capsys):
    path = plant(tmp_path, u_min=[-0.1], u_max=[0.1], x_max=[0.5], soft=True, soft_weight=1e308)
    assert main(["solve", path]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"packetloss-cvx: error: constraints.soft_weight: expected a weight in (0, "
                             f"{SOFT_WEIGHT_MAX_RATIO * SCALE:.3g}]")
    # the same weight on rows that are hard is never used: nothing to refuse
    assert main(["solve", path, "--no-soft", "--no-stability", "--json"]) == 0
    capsys.readouterr()


def test_the_largest_soft_weight_is_solved(tmp_path, capsys):
    path = plant(tmp_path, u_min=[-0.1], u_max=[0.1], x_max=[0.5])
    top = f"{SOFT_WEIGHT_MAX_RATIO * SCALE!r}"
    assert main(["solve", path, "--soft", "--soft-weight", top, "--no-stability", "--json"]) == 0
    entry = json.loads(capsys.readouterr().out)["tcp"]["constrained"]
    assert entry["status"] == "optimal"
    assert entry["inputs"][0][0] == pytest.approx(-0.1, abs=1e-9)
    assert entry["violations"] == [{"constraint": "x_max[0] at k=1", "by": pytest.approx(0.45, abs=1e-9)}]
