"""Every example in the README runs."""

import re
import shlex
from pathlib import Path

import pytest

from packetloss_cvx.cli import main

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()
PYTHON_BLOCKS = re.findall(r"```python\n(.*?)```", README, flags=re.S)
COMMANDS = [line[2:] for block in re.findall(r"```console\n(.*?)```", README, flags=re.S)
            for line in block.splitlines() if line.startswith("$ ")]


@pytest.mark.parametrize("block", PYTHON_BLOCKS)
def test_python_example(block, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)   # from any folder: nothing may depend on the checkout
    exec(compile(block, "README.md", "exec"), {})


@pytest.mark.parametrize("command", COMMANDS)
def test_cli_example(command, monkeypatch, capsys, tmp_path):
    monkeypatch.chdir(tmp_path)
    argv = shlex.split(command)
    if argv[:3] == ["python", "-m", "packetloss_cvx"]:
        argv = argv[3:]
    else:
        assert argv[0] == "packetloss-cvx"
        argv = argv[1:]
    assert main(argv) == 0
    assert capsys.readouterr().out


def test_readme_has_examples():
    assert len(PYTHON_BLOCKS) >= 2
    assert len(COMMANDS) >= 3


GETTING_STARTED = (ROOT / "docs" / "getting-started.md").read_text()
SETUP = re.findall(r"^    (pip install .*)$", README, flags=re.M)


def test_the_two_setup_commands_are_the_same_in_readme_getting_started_and_ci():
    """The README's set-up is two commands (the main job, the tests); getting-started repeats them, and CI
    runs exactly the second."""
    assert SETUP == ['pip install . && packetloss-cvx reproduce', 'pip install ".[test]" && python -m pytest']
    assert re.findall(r"^    (pip install .*)$", GETTING_STARTED, flags=re.M)[:2] == SETUP
    assert 'pip install ".[test]" && python -m pytest' in (ROOT / ".ci" / "run").read_text()
    for text in (README, GETTING_STARTED):
        assert "root folder" in text and "pyproject.toml" in text       # where the commands run


def test_the_readme_counts_reproduces_figures_and_files():
    from packetloss_cvx.cli.reproduce_report import BEYOND_FIGURES, FIGURES

    words = {2: "two", 3: "three", 6: "six"}
    assert f"the paper's {words[len(FIGURES)]} figures as PNGs and\n{words[len(BEYOND_FIGURES)]} beyond it" in README


def test_getting_started_names_every_packaged_example():
    from importlib.resources import files

    folder = files("packetloss_cvx").joinpath("model", "examples")
    examples = sorted(p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml"))
    assert examples == ["pendulum", "pendulum_bursty", "pendulum_sensor", "two_actuator"]
    for name in examples:
        assert f"`{name}`" in GETTING_STARTED and f"`{name}`" in README


def test_out_is_a_folder_exactly_for_the_commands_that_write_several_files():
    """getting-started says which commands take --out FILE and which --out DIR; the parser agrees."""
    from packetloss_cvx.cli.parser import build_parser

    parser = build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices      # noqa: SLF001 (argparse)
    metavars = {name: next(a.metavar for a in sub._actions if "--out" in a.option_strings)  # noqa: SLF001
                for name, sub in commands.items() if any("--out" in a.option_strings for a in sub._actions)}
    assert {k for k, v in metavars.items() if v == "DIR"} == {"sweep", "reproduce", "region"}
    assert {k for k, v in metavars.items() if v == "FILE"} == {"solve", "allocate", "audit", "simulate", "compare"}
    assert "for `solve`, `allocate`, `audit`, `simulate` and `compare` a FILE" in GETTING_STARTED
    assert "for `sweep`, `region` and `reproduce`, which write several files, a folder" in GETTING_STARTED
