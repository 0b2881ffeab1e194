"""The command line as documented: the reference page docs/cli.md is the grammar's (regenerated and
compared; every command, option, default and example on it), and what ``--out`` names (docs/design.md §4)."""

import argparse
import json
import re
from pathlib import Path

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.cli.reference import markdown

from .test_cli_native import subcommands

PAGE = Path(__file__).resolve().parents[2] / "docs" / "cli.md"

#: the commands that write several files: --out is a folder
FOLDER_COMMANDS = {"sweep", "reproduce", "region"}


def out_option(command):
    (action,) = [a for a in command._actions if "--out" in a.option_strings]
    return action


@pytest.mark.parametrize("name", sorted(subcommands(build_parser())))
def test_every_command_says_whether_out_is_a_folder_or_a_file(name):
    action = out_option(subcommands(build_parser())[name])
    assert action.metavar == ("DIR" if name in FOLDER_COMMANDS else "FILE")
    assert ("folder" in action.help) == (name in FOLDER_COMMANDS)


@pytest.mark.parametrize("argv", [["solve", "two_actuator", "--no-qp"],
                                  ["audit", "--random", "0", "--claim", "table-1"],
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


def test_the_reference_page_is_the_grammars():
    assert PAGE.read_text(encoding="utf-8") == markdown(), (
        "docs/cli.md is behind the parser: python -m packetloss_cvx.cli.reference docs/cli.md")


def section(page, name):
    return page.split(f"## packetloss-cvx {name}\n", 1)[1].split("\n## ", 1)[0]


@pytest.mark.parametrize("name", sorted(subcommands(build_parser())))
def test_the_page_shows_every_option_default_and_example_of(name):
    command = subcommands(build_parser())[name]
    text = section(PAGE.read_text(encoding="utf-8"), name)
    assert command.description.replace("*", "\\*") in text      # Markdown: a star escaped
    rows = {line.split(" | ")[0].removeprefix("| "): line.split(" | ") for line in text.splitlines()
            if line.startswith("| `")}
    for action in command._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        key = ", ".join(f"`{f}`" for f in action.option_strings) or f"`{action.metavar}`"
        key += " ..." if action.nargs in ("*", "+") else ""
        assert key in rows, f"{name}: {key} is not on the page"
        for choice in action.choices or ():
            assert f"`{choice}`" in rows[key][1]
        if action.default not in (None, False) and action.nargs != 0:
            assert rows[key][2] == str(action.default), (key, rows[key])
    examples = re.findall(r"^  packetloss-cvx (.+)$", command.epilog or "", flags=re.M)
    assert examples, f"{name} has no example in its --help"
    assert all(f"\npacketloss-cvx {line}\n" in text for line in examples)


def test_a_new_command_appears_on_the_page_with_its_options():
    from packetloss_cvx.cli.parser import add_command

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    new = add_command(sub, "later", "a command added later", examples=["later pendulum --grid 5"])
    new.add_argument("--grid", type=int, default=11, help="points per axis")
    text = section(markdown(parser), "later")
    assert "| `--grid` | `GRID` | 11 | points per axis |" in text
    assert "\npacketloss-cvx later pendulum --grid 5\n" in text
