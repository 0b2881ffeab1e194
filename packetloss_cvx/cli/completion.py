"""Shell completion, generated from the grammar by shtab: ``eval "$(packetloss-cvx --completion bash)"``.

Completes subcommands, each subcommand's options (an option that takes a value is followed by its
value, not by another option), choices (``--protocol t<TAB>``), and a system FILE as a packaged
example name (read from the package data: `packetloss_cvx.model.examples.names`) or a file name.
bash and zsh. O(size of the grammar). shtab (0.12 s to import) is loaded only when a script is asked for.
"""

from __future__ import annotations

import argparse

from ..model.examples import names as example_names

__all__ = ["SHELLS", "CompletionAction", "mark_system_file", "script"]

#: the shells a script is generated for
SHELLS = ("bash", "zsh")


def mark_system_file(action: argparse.Action) -> argparse.Action:
    """Tell the completion that ``action`` takes a system FILE: an example name or a file name.

    Examples
    --------
    >>> parser = argparse.ArgumentParser()
    >>> mark_system_file(parser.add_argument("file")).complete["bash"]
    '_packetloss_cvx_system_file'
    """
    words = " ".join(example_names())
    action.complete = {  # type: ignore[attr-defined]   # shtab's per-action hook
        "bash": "_packetloss_cvx_system_file",
        "zsh": f"{{_alternative 'examples:example:({words})' 'files:file:_files'}}",   # {...}: no compadd options added
        "preamble": {"bash": "_packetloss_cvx_system_file() {\n"
                             f'  compgen -W "{words}" -- "$1"\n'
                             '  compgen -f -- "$1"\n'
                             "}\n"},
    }
    return action


def script(parser: argparse.ArgumentParser, shell: str = "bash") -> str:
    """The completion script of ``parser`` for ``shell`` (one of `SHELLS`).

    Examples
    --------
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> text = script(build_parser())
    >>> "complete -o bashdefault -F _shtab_packetloss_cvx packetloss-cvx" in text, "pendulum_bursty" in text
    (True, True)
    """
    import shtab  # lazy: 0.12 s, needed by --completion only

    return shtab.complete(parser, shell=shell)


class CompletionAction(argparse.Action):
    """``--completion SHELL``: print the script and exit 0.

    Examples
    --------
    >>> import contextlib
    >>> import io
    >>> parser = argparse.ArgumentParser(prog="demo")
    >>> _ = parser.add_argument("--completion", choices=SHELLS, action=CompletionAction)
    >>> out = io.StringIO()
    >>> with contextlib.redirect_stdout(out):
    ...     try:
    ...         parser.parse_args(["--completion", "zsh"])
    ...     except SystemExit as stop:
    ...         code = stop.code
    >>> code, out.getvalue().startswith("#compdef demo")
    (0, True)
    """

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        print(script(parser, str(values)))
        parser.exit()
