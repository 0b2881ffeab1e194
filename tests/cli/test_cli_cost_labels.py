"""Every cost the command line shows says its basis: "paper" (the paper's expressions; J*_tcp a first-moment value
no law attains), "attainable" (the least expected cost a causal law of the protocol reaches), "loop" (a law run in
closed loop), or "realised" (the exact expected realised cost of one named plan). J*_tcp is never shown bare.

The scan reads the text of solve, allocate, sweep, simulate and region on the packaged examples clause by clause
(a line split at "; "): a clause that names a cost (J*, J_Delta, J, cost, minimum) beside a number carries one of the
basis words ("open loop", a plan applied without feedback, is not the loop basis); "method" rows describe the
algorithm, not a value, and are not read. In the JSON, every number under a cost key (cost, formula, exact, minimum)
has a key naming its basis in its object or an enclosing one.
"""

import json
import re

import pytest

from packetloss_cvx.cli import main

COST = re.compile(r"J\*|J_Delta|J_udp|J_tcp|\bJ\b|\bcosts?\b|\bminimum\b")
LABEL = re.compile(r"\bpaper\b|\battainable\b|\bloop\b|\bbasis\b|\brealised\b")
COST_KEY = re.compile(r"cost|formula|^exact$|minimum")

COMMANDS = [
    "solve two_actuator", "solve pendulum_bursty", "solve pendulum_sensor", "solve two_actuator --actuator all",
    "allocate two_actuator --alpha 8 --beta 1,1 --protocol tcp",
    "allocate two_actuator --alpha 8 --beta 1,1 --protocol udp",
    "allocate two_actuator --alpha 8 --beta 1,1 --protocol best --ack-price 0.5",
    "allocate two_actuator --alpha 8 --beta 1,1 --protocol tcp --target attainable --gap 1e-2",
    "allocate two_actuator --beta 1,1 --target stable --gap 1e-2",
    "allocate two_actuator --beta 1,1 --target dp-cost --alpha 20 --gap 1e-2",
    "allocate two_actuator --protocol tcp --alpha 8 --power exponential --power-scale 1,1",
    "allocate two_actuator --protocol tcp --budget 2 --power exponential --power-scale 1,1",
    "allocate pendulum_bursty --protocol udp --alpha 30000 --beta 1",
    "sweep two_actuator --mu-grid 3", "sweep pendulum --mu-grid 4 --shared --stability",
    "sweep two_actuator --horizons 2,5", "sweep two_actuator --x0-scales 1,2",
    "sweep pendulum_bursty --burstiness 0.5,0.9 --mean-rate 0.5,0.9",
    "simulate two_actuator --samples 200", "simulate two_actuator --samples 200 --closed-loop --steps 20",
    "simulate two_actuator --samples 100 --closed-loop --steps 10 --actuator all",
    "simulate pendulum_bursty --samples 100", "simulate pendulum_sensor --samples 100",
    "simulate pendulum_sensor --samples 50 --closed-loop --steps 10",
    # the constrained programs and loop ([constraints] keys from the command line)
    "solve two_actuator --u-max 0.5 --u-min=-0.5 --x-max 2", "solve two_actuator --x-max 0.5 --soft --soft-weight 1e-3",
    "solve pendulum_bursty --u-max 5 --u-min=-5",
    "simulate two_actuator --samples 100 --u-max 0.5 --u-min=-0.5 --mpc-samples 4 --steps 5",
]


def unlabelled_clauses(text: str) -> list[str]:
    """The clauses of ``text`` that show a cost beside a number without a basis word.

    >>> unlabelled_clauses("  J*_tcp: min 1.9, max 140; J*_udp (paper basis): min 1.9\\n  method  1 box of cost")
    ['J*_tcp: min 1.9, max 140']
    """
    found = []
    for line in text.splitlines():
        if line.strip().startswith("method"):
            continue
        for clause in line.split("; "):
            if COST.search(clause) and re.search(r"\d", clause) and not LABEL.search(clause.replace("open loop", "")):
                found.append(clause.strip())
    return found


def unlabelled_keys(data, path: str = "", labelled: bool = False) -> list[str]:
    """The paths of numbers under cost keys with no basis key in their object or an enclosing one.

    >>> unlabelled_keys({"tcp": {"cost": 1.0}, "udp": {"cost": 2.0, "basis": "paper"}})
    ['/tcp/cost']
    """
    out = []
    if isinstance(data, dict):
        labelled = labelled or any("basis" in key for key in data)
        for key, value in data.items():
            numeric = isinstance(value, int | float | list) and not isinstance(value, bool)
            if COST_KEY.search(key) and "basis" not in key and numeric and not labelled:
                out.append(f"{path}/{key}")
            out += unlabelled_keys(value, f"{path}/{key}", labelled)
    elif isinstance(data, list):
        for k, value in enumerate(data):
            out += unlabelled_keys(value, f"{path}[{k}]", labelled)
    return out


def costs_without_their_own_basis(data, path: str = "", inherited: bool = False) -> list[str]:
    """The paths of numbers under cost keys whose basis is not named for them: ``<key>_basis`` beside them, or
    ``basis`` where the key is ``cost`` or the object's only cost, or ``basis`` in an enclosing object that holds no
    cost of its own (an enclosing object's basis may be its own cost's, not theirs). Relative differences
    (``cost_rel_diff``) and radii have no basis.

    >>> costs_without_their_own_basis({"basis": "paper", "cost": 1.0, "plan_cost": 2.0, "q": {"cost": 3.0}})
    ['/plan_cost', '/q/cost']
    >>> costs_without_their_own_basis({"basis": "loop", "rows": {"a": {"cost": 1.0}}, "x": {"cost": 2.0,
    ...                                "x_cost": 3.0, "x_cost_basis": "realised", "basis": "paper"}})
    []
    """
    out = []
    if isinstance(data, dict):
        costs = [key for key, value in data.items() if COST_KEY.search(key) and "basis" not in key
                 and "diff" not in key and isinstance(value, int | float | list) and not isinstance(value, bool)]
        for key in costs:
            if f"{key}_basis" not in data and not ("basis" in data and (key == "cost" or len(costs) == 1)) \
                    and not inherited:
                out.append(f"{path}/{key}")
        passes = inherited or ("basis" in data and not costs)
        for key, value in data.items():
            if "radius" not in key:
                out += costs_without_their_own_basis(value, f"{path}/{key}", passes)
    elif isinstance(data, list):
        for k, value in enumerate(data):
            out += costs_without_their_own_basis(value, f"{path}[{k}]", inherited)
    return out


def run(capsys, command: str, *extra: str) -> str:
    code = main([*command.split(), "--quiet", *extra] if not command.startswith("region") else
                [*command.split(), *extra])
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.out


@pytest.mark.parametrize("command", COMMANDS)
def test_every_cost_in_the_text_says_its_basis(capsys, command):
    text = run(capsys, command)
    assert COST.search(text)                     # the command shows costs: the scan has something to read
    assert unlabelled_clauses(text) == []


@pytest.mark.parametrize("command", COMMANDS)
def test_every_cost_in_the_json_says_its_basis(capsys, command):
    data = json.loads(run(capsys, command, "--json"))
    assert unlabelled_keys(data) == []



@pytest.mark.parametrize("command", [c for c in COMMANDS if c.startswith("solve")])
def test_every_cost_of_solve_names_its_own_basis_in_its_own_object(capsys, command):
    data = json.loads(run(capsys, command, "--json"))
    assert costs_without_their_own_basis(data) == []


def test_solve_behind_a_chain_gives_each_cost_its_basis(capsys):
    """pendulum_bursty with an input box: the plug-in laws' costs are the paper's on the chain's prior-mean rates,
    the plans' expected costs under the chain realised, the UDP-like exact minimum attainable; the QPs' costs are
    the numbers beside them, on their basis."""
    data = json.loads(run(capsys, "solve pendulum_bursty --u-max 5 --u-min=-5", "--json"))
    prior = "paper, prior-mean rates"
    for protocol in ("tcp", "udp"):
        assert (data[protocol]["basis"], data[protocol]["qp"]["basis"]) == (prior, prior)
        constrained = data[protocol]["constrained"]
        assert (constrained["basis"], constrained["plan_expected_cost_basis"]) == (prior, "realised")
    tcp, udp = data["markov"]["tcp"], data["markov"]["udp"]
    assert (tcp["plugin_cost_basis"], tcp["plan_expected_cost_basis"]) == (prior, "realised")
    assert (tcp["exact"]["basis"], tcp["qp"]["basis"]) == (prior, prior)
    # UDP-like: the plug-in law's cost is its plan's expected cost under the chain, the same number realised
    assert udp["plugin_cost"] == udp["plan_expected_cost"]
    assert (udp["plugin_cost_basis"], udp["plan_expected_cost_basis"]) == ("realised", "realised")
    assert (udp["exact"]["basis"], udp["qp"]["basis"]) == ("attainable", "attainable")


def test_the_tcp_like_constrained_plans_expected_cost_is_realised_not_paper(capsys):
    data = json.loads(run(capsys, "solve two_actuator --u-max 0.5 --u-min=-0.5 --x-max 2", "--json"))
    assert (data["tcp"]["constrained"]["basis"], data["tcp"]["constrained"]["plan_expected_cost_basis"]) == (
        "paper", "realised")
    assert data["udp"]["constrained"]["basis"] == "realised"


def test_region_shows_no_cost(capsys):
    """region prints critical delivery probabilities and radii only: no cost to label."""
    text = run(capsys, "region two_actuator")
    data = json.loads(run(capsys, "region two_actuator", "--json"))
    assert "critical mu" in text
    assert not COST.search(text)
    assert not [key for key in re.findall(r'"(\w+)":', json.dumps(data)) if COST_KEY.search(key)]


SENSOR_FILE = """name = "sens"
[plant]
A = [[1.03, 0.005], [0.35, 1.01]]
B = [[1.0, 0.0], [0.0, 1.0]]
noise_cov = [[0.01, 0.0], [0.0, 0.01]]
[cost]
horizon = 10
state_weight = [1.0, 1.0]
input_weight = [1.0, 1.0]
[channel]
mu = [0.9, 0.5]
[state]
x0 = [1.0, 1.0]
P0 = [[0.01, 0.0], [0.0, 0.01]]
[sensor]
C = [[1.0, 0.0]]
noise_cov = [[0.001]]
gamma = [0.7]
"""


def test_the_sensor_split_says_what_each_part_is(capsys, tmp_path):
    """The loop cost's "control" part is tr(P Sigma_W) of the DP whatever the law (the same number for the TCP-like,
    the UDP-like and the DP law here): it is the full-state DP optimum, and for a law other than the DP law on the
    TCP-like estimate the other part holds the law's excess over the DP law beside the estimation error."""
    path = tmp_path / "sens.toml"
    path.write_text(SENSOR_FILE)
    data = json.loads(run(capsys, f"solve {path}", "--json"))
    entries = [data["tcp"]["estimated_state"], data["udp"]["estimated_state"], data["estimation"]["dp"]]
    assert all(entry["control_part"] is not None for entry in entries)
    assert len({entry["control_part"] for entry in entries}) == 1          # law-independent: the DP's, not the law's
    text = run(capsys, f"solve {path}")
    split = [line for line in text.splitlines() if "loop's average stage cost" in line]
    assert len(split) == 3
    assert all("full-state DP optimum" in line and "control" not in line for line in split)
    assert sum("(estimation and the law's excess over the DP law)" in line for line in split) == 2
    assert "DP optimum" in split[2]
    assert "+ estimation " in split[2]
    assert "excess" not in split[2]


def test_simulate_names_the_open_loop_costs_basis(capsys):
    """The open-loop lines' sampled and exact numbers are the plan's expected realised cost: basis realised."""
    text = run(capsys, "simulate two_actuator --samples 200")
    lines = [line for line in text.splitlines() if "open loop:" in line]
    assert len(lines) == 2
    assert all(line.split("; ")[0].endswith("[basis: realised]") for line in lines)


def test_compare_names_the_loop_basis_of_its_cost_columns(capsys):
    lines = run(capsys, "compare two_actuator --actuator zero,hold").splitlines()
    assert "[basis: loop]" in lines[0]
    assert "avg cost [loop]" in lines[1]
    assert "x0 cost [loop]" in lines[1]


def test_simulate_names_the_loop_and_realised_bases_beside_each_cost(capsys):
    """simulate's closed-loop lines name the loop basis as its constrained (MPC) lines do, each open-loop object
    names the realised basis of its sample and exact value, and every estimated-state entry names the loop basis,
    in text and JSON."""
    text = run(capsys, "simulate pendulum_sensor --samples 50 --closed-loop --steps 10")
    closed = [line for line in text.splitlines() if "closed loop over" in line]
    estimated = [line for line in text.splitlines() if "filter: mean stage cost" in line]
    assert len(closed) == 3
    assert len(estimated) == 6
    assert all("[basis: loop]" in line.split("; ")[0] for line in closed + estimated)
    data = json.loads(run(capsys, "simulate pendulum_sensor --samples 50 --closed-loop --steps 10", "--json"))
    assert [data[p]["open_loop"]["basis"] for p in ("tcp", "udp")] == ["realised", "realised"]
    for law in ("tcp", "udp", "dp"):
        entry = data["estimated_state"][law]
        assert entry["basis"] == "loop"
        assert (entry["kalman"]["basis"], entry["stationary"]["basis"]) == ("loop", "loop")
