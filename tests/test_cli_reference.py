"""The command line as documented: what ``--out`` names (docs/design.md §4, "What --out names")."""

import json

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.cli.parser import build_parser

from .test_cli_native import subcommands

#: the commands that write several files: --out is a folder
FOLDER_COMMANDS = {"sweep", "reproduce"}


def out_option(command):
    (action,) = [a for a in command._actions if "--out" in a.option_strings]
    return action


@pytest.mark.parametrize("name", sorted(subcommands(build_parser())))
def test_every_command_says_whether_out_is_a_folder_or_a_file(name):
    action = out_option(subcommands(build_parser())[name])
    assert action.metavar == ("DIR" if name in FOLDER_COMMANDS else "FILE")
    assert ("folder" in action.help) == (name in FOLDER_COMMANDS)


@pytest.mark.parametrize("argv", [["solve", "two_actuator", "--no-qp"], ["audit", "--random", "0", "--claim", "table-1"],
                                  ["simulate", "pendulum", "--samples", "50"],
                                  ["allocate", "two_actuator", "--protocol", "tcp", "--alpha", "8", "--beta", "1,1"]])
def test_out_file_is_the_printed_json_object_and_nothing_else(argv, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "-q", "--json", "--out", "result.json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]
    assert json.loads((tmp_path / "result.json").read_text()) == printed


def test_out_dir_is_a_folder_of_files_with_a_manifest(tmp_path, capsys):
    assert main(["sweep", "pendulum", "--x0-scales", "0:1:3", "-q", "--out", str(tmp_path / "run")]) == 0
    names = sorted(p.name for p in (tmp_path / "run").iterdir())
    assert names == ["manifest.json", "sweep.csv", "sweep.npz", "sweep.png"]
    assert sorted(f["name"] for f in json.loads((tmp_path / "run" / "manifest.json").read_text())["files"]) == [
        n for n in names if n != "manifest.json"]
