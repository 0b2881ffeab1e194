"""The lossy-sensor description (sensor.Sensor), the System's sensor field and the TOML [sensor] table."""

import pickle

import numpy as np
import pytest

from packetloss_cvx import System
from packetloss_cvx.errors import DimensionError, InputError, ProbabilityError
from packetloss_cvx.model.files import dumps_system, load_example, load_system
from packetloss_cvx.model.sensor import Sensor

GOOD = """
[plant]
A = [[1.2, 0.1], [0.0, 0.9]]
B = [[1.0], [0.5]]
noise_cov = [[0.1, 0.0], [0.0, 0.1]]
[cost]
horizon = 5
state_weight = [1.0, 1.0]
input_weight = [1.0]
[channel]
mu = [0.8]
[state]
x0 = [1.0, 0.0]
P0 = [[0.1, 0.0], [0.0, 0.1]]
[sensor]
C = [[1.0, 0.0], [0.0, 1.0]]
noise_cov = [[0.01, 0.0], [0.0, 0.02]]
gamma = [0.7, 0.9]
groups = [[0], [1]]
"""


def with_line(text: str, section: str, line: str) -> str:
    """``text`` with ``line`` replacing the key it sets in ``[section]`` (or added there)."""
    lines = text.strip().split("\n")
    start = lines.index(f"[{section}]")
    end = next((k for k in range(start + 1, len(lines)) if lines[k].startswith("[")), len(lines))
    key = line.split("=")[0].strip()
    body = [entry for entry in lines[start + 1:end] if entry.split("=")[0].strip() != key]
    return "\n".join(lines[:start + 1] + body + [line] + lines[end:]) + "\n"


def test_sensor_file_reads_and_writes_back(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(GOOD)
    s = load_system(path)
    assert s.sensor.groups == ((0,), (1,))
    assert s.sensor.gamma.tolist() == [0.7, 0.9]
    assert np.array_equal(s.sensor.P0, 0.1 * np.eye(2))
    again = tmp_path / "again.toml"
    again.write_text(dumps_system(s))
    assert load_system(again).sensor == s.sensor
    assert pickle.loads(pickle.dumps(s)).sensor == s.sensor
    assert s.with_mu([0.3]).sensor is s.sensor
    assert s.with_x0([0.0, 1.0]).sensor is s.sensor


def test_default_group_is_one_channel_and_P0_defaults_to_zero():
    s = Sensor(C=[[1.0, 0.0], [0.0, 1.0]], gamma=[0.5])
    assert s.groups == ((0, 1),)
    assert s.g == 1
    assert np.array_equal(s.P0, np.zeros((2, 2)))
    assert np.array_equal(s.noise_cov, np.zeros((2, 2)))
    with pytest.raises(AttributeError):
        s.gamma = np.array([1.0])
    assert not s.gamma.flags.writeable


def test_full_state_file_is_unchanged():
    """A file without [sensor] has no sensor and writes exactly the sections it had."""
    for name in ("pendulum", "two_actuator", "pendulum_bursty"):
        s = load_example(name)
        assert s.sensor is None
        assert "sensor" not in dumps_system(s)
        assert "P0" not in dumps_system(s)


@pytest.mark.parametrize(("section", "line", "error", "field"), [
    ("sensor", "C = [[1.0, 0.0, 1.0]]", DimensionError, "sensor.C"),
    ("sensor", "noise_cov = [[-1.0, 0.0], [0.0, 1.0]]", InputError, "sensor.noise_cov"),
    ("sensor", "noise_cov = [[1.0]]", DimensionError, "sensor.noise_cov"),
    ("sensor", "gamma = [1.2, 0.5]", ProbabilityError, "sensor.gamma"),
    ("sensor", "gamma = [-0.1, 0.5]", ProbabilityError, "sensor.gamma"),
    ("sensor", "gamma = [0.5]", DimensionError, "sensor.gamma"),
    ("sensor", "groups = [[0], [0]]", InputError, "sensor.groups"),
    ("sensor", "groups = [[0]]", InputError, "sensor.groups"),
    ("sensor", "groups = [[0, 1], [2]]", InputError, "sensor.groups"),
    ("sensor", "gama = [1.0]", InputError, "sensor.gama"),
    ("state", "P0 = [[1.0, 2.0], [2.0, 1.0]]", InputError, "state.P0"),
    ("state", "P0 = [[1.0]]", DimensionError, "state.P0"),
])
def test_bad_sensor_input_names_its_field(tmp_path, section, line, error, field):
    path = tmp_path / "bad.toml"
    path.write_text(with_line(GOOD, section, line))
    with pytest.raises(error) as info:
        load_system(path)
    assert info.value.field == field


def test_P0_without_a_sensor_and_an_empty_sensor_are_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.split("[sensor]")[0])
    with pytest.raises(InputError, match="state.P0: .*needs a \\[sensor\\]"):
        load_system(path)
    path.write_text(GOOD.split("[sensor]")[0] + "[sensor]\n")
    with pytest.raises(InputError, match="sensor.C: missing"):
        load_system(path)


def test_gilbert_elliott_sensor_has_its_long_run_rate_as_gamma():
    s = Sensor(C=[[1.0]], channel={"model": "gilbert-elliott", "p": [0.1], "r": [0.3]})
    assert s.gamma.tolist() == pytest.approx([0.75])           # r / (p + r) by hand
    with pytest.raises(InputError, match="sensor.gamma: expected exactly one"):
        Sensor(C=[[1.0]], gamma=[0.5], channel={"model": "gilbert-elliott", "p": [0.1], "r": [0.3]})
    with pytest.raises(InputError) as info:
        Sensor(C=[[1.0]], channel={"model": "gilbert-elliott", "p": [1.5], "r": [0.3]})
    assert info.value.field == "sensor.p"


def test_system_sensor_of_the_wrong_width_is_refused():
    with pytest.raises(DimensionError, match="sensor.C"):
        System(A=np.eye(2), B=np.ones((2, 1)), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0], mu=[0.5],
               x0=[0.0, 0.0], sensor=Sensor(C=[[1.0]], gamma=[0.5]))


def test_cli_bad_sensor_is_one_line_and_exit_2(tmp_path, capsys):
    from packetloss_cvx.cli import main

    path = tmp_path / "bad.toml"
    path.write_text(with_line(GOOD, "sensor", "gamma = [1.2, 0.5]"))
    code = main(["solve", str(path), "--no-qp"])        # in process: the exit code and stderr are the command's
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip().count("\n") == 0
    assert "sensor.gamma" in err
