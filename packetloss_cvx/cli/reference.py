"""The command-line reference page (docs/cli.md), generated from the grammar: every command, option,
default and example, as ``packetloss-cvx COMMAND -h`` shows them, in Markdown.

    python -m packetloss_cvx.cli.reference docs/cli.md

``tests/cli/test_cli_reference.py`` regenerates the page and compares it with the file, so the page cannot
fall behind the parser; a new subcommand (``add_command``) appears with no change here. Standard library
only. O(size of the grammar).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from ..safeio import atomic_write
from .parser import build_parser

__all__ = ["OUT_RULE", "markdown", "write"]

#: what ``--out`` names, stated once for the page (docs/design.md §4 says the same, with the run folders' rules);
#: ``{folders}``: the commands whose ``--out`` is a DIR, read from the grammar
OUT_RULE = ("A command that writes several files takes `--out DIR`, a folder ({folders}): a run folder "
            "with a `manifest.json`, refused when it holds files packetloss-cvx did not write unless `--force`. "
            "A command that returns one result takes `--out FILE`: the JSON object it prints with `--json`. "
            "`simulate`'s other files have options of their own, each one file: `--save FILE.npz`, `--plot FILE`.")

#: the usage lines' width: fixed, so that the page does not depend on the terminal that generated it
WIDTH = 100

_DEFAULT = re.compile(r"\s*\(default: ((?:[^()]|\([^()]*\))*)\)")


def _cell(text: str) -> str:
    """Text for a table cell: pipes and asterisks escaped, no line break."""
    return " ".join(text.split()).replace("|", "\\|").replace("*", "\\*")


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _folder_commands(commands: dict[str, argparse.ArgumentParser]) -> list[str]:
    """The commands whose ``--out`` is a folder (metavar DIR)."""
    return [name for name, command in commands.items()
            if any("--out" in a.option_strings and a.metavar == "DIR" for a in command._actions)]


def _usage(parser: argparse.ArgumentParser) -> str:
    formatter = argparse.HelpFormatter(parser.prog, width=WIDTH)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return formatter.format_help().strip()


def _row(action: argparse.Action) -> str:
    """One option as a table row: the flags (or the positional's name), its value, default and help."""
    if action.option_strings:
        name = ", ".join(f"`{flag}`" for flag in action.option_strings)
    else:
        name = f"`{action.metavar or action.dest}`" + (" ..." if action.nargs in ("*", "+") else "")
    if action.nargs == 0:
        value = ""
    elif action.choices is not None:
        value = ", ".join(f"`{choice}`" for choice in action.choices)
    elif action.option_strings:
        value = f"`{action.metavar or action.dest.upper()}`"       # a code span: a pipe in it is not a cell break
    else:
        value = ""
    text = action.help or ""
    found = _DEFAULT.search(text)
    if found:
        default, text = found.group(1), _DEFAULT.sub("", text, count=1)
    elif action.default not in (None, False, argparse.SUPPRESS) and action.nargs != 0:
        default = str(action.default)
    else:
        default = "required" if action.required or not action.option_strings else ""
    return f"| {name} | {value} | {_cell(default)} | {_cell(text)} |"


def _options(parser: argparse.ArgumentParser) -> list[str]:
    """Each argument group of ``parser`` as a table (its title as the heading); help and version left out."""
    lines: list[str] = []
    for group in parser._action_groups:
        actions = [a for a in group._group_actions
                   if not isinstance(a, (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction))]
        if not actions:
            continue
        lines += [f"**{group.title}**", "", "| option | value | default | description |", "| --- | --- | --- | --- |"]
        lines += [_row(a) for a in actions] + [""]
    return lines


def _examples(parser: argparse.ArgumentParser) -> list[str]:
    """The epilog's examples (``add_command``'s), as one shell block."""
    epilog = parser.epilog or ""
    commands = [line.strip() for line in epilog.splitlines()[1:] if line.strip()] if epilog.startswith("examples:") \
        else []
    return ["Examples:", "", "```sh", *commands, "```", ""] if commands else []


def markdown(parser: argparse.ArgumentParser | None = None) -> str:
    """The reference page of ``parser`` (default: the package's grammar) as Markdown.

    Examples
    --------
    >>> page = markdown()
    >>> page.startswith("# Command-line reference"), "## packetloss-cvx solve" in page, "`--mu-grid`" in page
    (True, True, True)
    """
    parser = parser or build_parser()
    commands = _subcommands(parser)
    folders = ", ".join(f"`{name}`" for name in _folder_commands(commands))
    lines = ["# Command-line reference", "",
             "<!-- generated from the argparse grammar by `python -m packetloss_cvx.cli.reference docs/cli.md`; "
             "do not edit: tests/cli/test_cli_reference.py regenerates it and compares -->", "",
             "Every command below is also `python -m packetloss_cvx COMMAND`; `packetloss-cvx COMMAND -h` prints "
             "the same options. The contracts (exit codes, JSON keys, files) are in "
             "[the design notes](design.md#command-line-packetloss-cvx-and-python-m-packetloss_cvx); "
             "each command's JSON object in [the command-line contracts](cli-contracts.md).", "",
             "```text", _usage(parser), "", (parser.description or "").strip(), "```", "",
             "Commands: " + ", ".join(f"[`{name}`](#packetloss-cvx-{name})" for name in commands) + ".", "",
             "**What `--out` names.** " + OUT_RULE.format(folders=folders), ""]
    lines += _options(parser) + _examples(parser)
    for name, command in commands.items():
        lines += [f"## packetloss-cvx {name}", "", _cell(command.description or ""), "", "```text", _usage(command),
                  "```", ""]
        lines += _options(command) + _examples(command)
    return "\n".join(lines).rstrip() + "\n"


def write(path: str | Path) -> Path:
    """Write [`markdown`][packetloss_cvx.cli.reference.markdown] to ``path``, atomically, replacing it (the page is
        generated). O(size of the grammar)."""
    path = Path(path)
    with atomic_write(path, overwrite=True, text=True, field="path") as handle:
        handle.write(markdown())
    return path


if __name__ == "__main__":
    print(write(sys.argv[1] if len(sys.argv) > 1 else "docs/cli.md"))
