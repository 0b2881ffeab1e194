"""Review 6, a hostile new user on the day's fixes: each test is one defect found, failing before its fix."""

import copy
import json
import pickle
from concurrent.futures import ProcessPoolExecutor

import pytest

import packetloss_cvx as pl
from packetloss_cvx import errors
from packetloss_cvx.cli import main
from packetloss_cvx.cli import simulate as simulate_command
from packetloss_cvx.studies import sweep

from .conftest import EXAMPLES


def test_solve_json_names_each_protocol_as_the_readme_says(capsys):
    # README and design.md: "each protocol has `protocol`, `cost`, ..."; solve --json left it out
    assert main(["solve", "two_actuator", "--json", "--no-qp"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["tcp"]["protocol"] == "tcp"
    assert data["udp"]["protocol"] == "udp"
    assert main(["solve", "pendulum_bursty", "--json", "--no-qp", "--protocol", "udp"]) == 0
    assert json.loads(capsys.readouterr().out)["udp"]["protocol"] == "udp"


def test_results_keep_read_only_arrays_through_pickle_and_deepcopy(two_actuator):
    # results are frozen with read-only arrays (results/__init__.py); a result sent back from a
    # multiprocessing worker (pickle) or deep-copied skipped __post_init__ and came back writable
    sol = pl.closed_form(two_actuator, "udp")
    result = sweep(two_actuator, mu_grid=3)
    for obj in (sol, result):
        for twin in (pickle.loads(pickle.dumps(obj)), copy.deepcopy(obj)):
            assert type(twin) is type(obj)
            for name, value in vars(obj).items():
                back = vars(twin)[name]
                if hasattr(value, "flags"):
                    assert not back.flags.writeable, name
                    assert back.tobytes() == value.tobytes(), name
    twin = pickle.loads(pickle.dumps(result))
    assert not any(v.flags.writeable for v in twin.costs.values())
    assert not twin.mu.flags.writeable


@pytest.mark.parametrize(("argv", "field"), [
    # sweep has no --x0: argparse took it as an abbreviation of --x0-scales and swept x0 times 2 and -1
    # (exit 0) where the user asked for x0 = (2, -1), as solve --x0 means
    (["sweep", "two_actuator", "--x0", "2,-1"], "arguments: one of the arguments --mu-grid"),   # no sweep kind given
    (["sweep", "two_actuator", "--x0", "0.5"], "arguments: one of the arguments --mu-grid"),
    (["sweep", "two_actuator", "--mu-grid", "3", "--x0", "0,0"], "--x0"),   # was reported as --x0-scales
    (["solve", "two_actuator", "--mu-s", "x.csv"], "--mu-s"),
    (["simulate", "two_actuator", "--samp", "10"], "--samp"),
])
def test_an_option_is_not_guessed_from_a_prefix(capsys, argv, field):
    assert main(argv + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"packetloss-cvx: error: {field}"), err
    assert field.startswith("arguments") or err[0].endswith("not an option of this command (see its --help)"), err


def test_counted_and_grouped_short_flags_still_parse(capsys):
    assert main(["solve", "two_actuator", "-vv", "--no-qp"]) == 0
    assert "TCP-like" in capsys.readouterr().out


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


def test_a_figure_format_matplotlib_cannot_write_is_refused_before_the_sampling(capsys, monkeypatch):
    # was: the whole Monte Carlo ran (19 s at --samples 200000), then exit 2 under "path", nothing printed
    def never(*args, **kwargs):
        raise AssertionError("sampled before the --plot check")

    monkeypatch.setattr(simulate_command, "simulate", never)
    assert main(["simulate", "two_actuator", "--closed-loop", "--plot", "loop.pgn", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("packetloss-cvx: error: --plot: cannot write a 'pgn' figure"), err


def test_a_burstiness_sweep_of_zero_costs_is_not_nan(capsys, tmp_path):
    # x0 = 0 without noise (valid input): every cost is 0 and plugin / exact - 1 was 0/0: the text read
    # "loses up to nan%" and --json exited 1 ("unexpected ValueError: Out of range float values are not JSON
    # compliant"); solve's chain section already takes a zero minimum's loss as 0 (markov.compare)
    path = tmp_path / "zero.toml"
    path.write_text((EXAMPLES / "two_actuator.toml").read_text().replace("x0 = [1.0, 1.0]", "x0 = [0.0, 0.0]"))
    assert main(["sweep", str(path), "--burstiness", "0,0.5", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "nan" not in text
    assert "TCP-like: the plug-in law is the exact minimiser at every lambda" in text
    assert "UDP-like: the plug-in law is the exact minimiser at every lambda" in text
    assert main(["sweep", str(path), "--burstiness", "0,0.5", "--quiet", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["udp"]["relative_loss"] == [0.0, 0.0]
    assert data["udp"]["exact"] == [0.0, 0.0]


def test_a_cap_of_one_box_is_singular(capsys):
    # 0ed6b71 made the method line say '1 box'; the same line still said 'stopped at the cap of 1 boxes'
    assert main(["allocate", "two_actuator", "--protocol", "udp", "--alpha", "3", "--beta", "1,1",
                 "--max-boxes", "1", "--quiet"]) == 4
    text = capsys.readouterr().out
    assert "stopped at the cap of 1 box;" in text
    assert "1 boxes" not in text


def test_a_sweep_of_one_point_says_point(capsys):
    assert main(["sweep", "two_actuator", "--horizons", "3", "--quiet"]) == 0
    assert capsys.readouterr().out.splitlines()[0] == "two-actuator: horizon sweep, 1 point (1 over horizon)"


def _closed_form_cost(mu):
    return pl.closed_form(pl.load_example("two_actuator").with_mu(mu), "udp", method="recursion").cost


@pytest.mark.parametrize("error", [
    errors.InputError("channel.mu", "expected probabilities in [0, 1], found 1.5"),
    errors.DimensionError("B", "expected (2, m)"), errors.ProbabilityError("mu", "found 1.5"),
    errors.SolverError("infeasible", "Clarabel says so"), errors.SolverError("max_iter"),
    errors.InfeasibleError("alpha below the least cost", 1.92), errors.NumericalError("overflow"),
    errors.CrossCheckError("J differs", {"dense": 1.0, "qp": 2.0}), errors.ResourceError("too big", 1e12, 4e9),
])
def test_every_error_pickles_as_itself(error):
    # a multiprocessing / joblib worker's exception is pickled to the caller: InputError(field, detail)
    # could not be rebuilt from its args (TypeError), SolverError's message doubled, min_cost was lost
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error)
    assert str(back) == str(error)
    assert vars(back) == vars(error)


def test_a_workers_input_error_reaches_the_caller_and_spares_the_other_tasks():
    # was: BrokenProcessPool for all three tasks, the InputError's message lost
    with ProcessPoolExecutor(2) as pool:
        futures = [pool.submit(_closed_form_cost, mu) for mu in ([0.5, 0.5], [1.5, 0.5], [0.9, 0.9])]
        with pytest.raises(errors.ProbabilityError, match=r"mu: expected probabilities in \[0, 1\]"):
            futures[1].result(timeout=120)
        assert futures[0].result(timeout=120) == _closed_form_cost([0.5, 0.5])
        assert futures[2].result(timeout=120) == _closed_form_cost([0.9, 0.9])
