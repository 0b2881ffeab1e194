"""Shell completion, generated from the grammar: ``eval "$(packetloss-cvx --completion bash)"``.

Completes subcommands, each subcommand's options, choices (``--protocol t<TAB>``), packaged
example names and file names. Standard library only. O(size of the grammar).
"""

from __future__ import annotations

import argparse

__all__ = ["CompletionAction", "bash_script"]

EXAMPLES = "pendulum two_actuator"


def subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """Subcommand name -> its parser."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def bash_script(parser: argparse.ArgumentParser) -> str:
    """A bash completion function for ``parser`` (zsh: after ``autoload bashcompinit; bashcompinit``).

    Examples
    --------
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> bash_script(build_parser()).endswith("complete -o filenames -F _packetloss_cvx packetloss-cvx")
    True
    """
    commands = subparsers(parser)
    top = " ".join([*commands, *(s for a in parser._actions for s in a.option_strings)])
    cases, choices = [], []
    for name, sub in commands.items():
        options = " ".join(s for a in sub._actions for s in a.option_strings)
        cases.append(f'    {name}) opts="{options}";;')
        for action in sub._actions:
            if action.choices and action.option_strings:
                words = " ".join(map(str, action.choices))
                choices += [f'    {name}:{flag}) COMPREPLY=($(compgen -W "{words}" -- "$cur")); return;;'
                            for flag in action.option_strings]
    return "\n".join([
        "_packetloss_cvx() {",
        '  local cur="${COMP_WORDS[COMP_CWORD]}" prev="${COMP_WORDS[COMP_CWORD-1]}" cmd="${COMP_WORDS[1]}" opts=""',
        "  if [ \"$COMP_CWORD\" -eq 1 ]; then",
        f'    COMPREPLY=($(compgen -W "{top}" -- "$cur")); return',
        "  fi",
        '  case "$cmd:$prev" in', *choices, "  esac",
        '  case "$cmd" in', *cases, "  esac",
        '  if [[ "$cur" == -* ]]; then',
        '    COMPREPLY=($(compgen -W "$opts" -- "$cur"))',
        "  else",
        f'    COMPREPLY=($(compgen -W "{EXAMPLES}" -- "$cur") $(compgen -f -- "$cur"))',
        "  fi",
        "}",
        "complete -o filenames -F _packetloss_cvx packetloss-cvx",
    ])


class CompletionAction(argparse.Action):
    """``--completion bash``: print the script and exit 0.

    Examples
    --------
    >>> import contextlib
    >>> import io
    >>> parser = argparse.ArgumentParser(prog="demo")
    >>> _ = parser.add_argument("--completion", choices=("bash",), action=CompletionAction)
    >>> out = io.StringIO()
    >>> with contextlib.redirect_stdout(out):
    ...     try:
    ...         parser.parse_args(["--completion", "bash"])
    ...     except SystemExit as stop:
    ...         code = stop.code
    >>> code, out.getvalue().startswith("_packetloss_cvx() {")
    (0, True)
    """

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        print(bash_script(parser))
        parser.exit()
