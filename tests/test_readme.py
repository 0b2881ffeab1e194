"""Every example in the README runs."""

import re
import shlex
from pathlib import Path

import pytest

from packetloss_cvx.cli import main

ROOT = Path(__file__).resolve().parent.parent
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
