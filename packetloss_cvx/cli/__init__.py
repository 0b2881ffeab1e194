"""Command line: ``packetloss-cvx SUBCOMMAND ...`` (docs/design.md §4).

Exit codes: 0 success; 2 bad input (one stderr line naming the field); 3 a
well-posed problem with no solution (proved); 4 an allocation whose gap was not
certified within its caps (printed as usual); 1 anything else (one stderr line).

The grammar (:mod:`.parser`) imports nothing numerical; the checks that need no solver
(:func:`.common.preflight`: files, overrides, number lists) run next, importing NumPy only;
the module that runs a subcommand (``solve``, ``audit``, ...) is imported only after them,
so ``--help``, ``--version`` and bad input answer without importing cvxpy or SciPy.
``--out FILE`` writes the JSON object to FILE as well; ``-v`` reports the time taken on stderr.
"""

from __future__ import annotations

import importlib
import json
import os
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..printable import printable
from ..errors import CrossCheckError, InfeasibleError, InputError, NumericalError, ResourceError, SolverError
from .parser import build_parser, join_negative_values

__all__ = ["main"]


def _say(message: str) -> None:
    """One stderr line, whatever the message holds (a key or a path with a newline or an escape sequence in it)."""
    print(printable(message), file=sys.stderr)


def write_json(path: str, data: dict[str, Any]) -> None:
    """``--out FILE``: the JSON object written to FILE (an unwritable path is bad input)."""
    try:
        Path(path).write_text(json.dumps(data, allow_nan=False, indent=2) + "\n", encoding="utf-8")
    except OSError as err:
        raise InputError("--out", f"cannot write {path!r}: {err.strerror or err}") from None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code.

    >>> main(["solve", "no-such-file.toml"])
    2
    """
    for stream in (sys.stdout, sys.stderr):   # a terminal that cannot show a name gets an escape, not a crash
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    parser = build_parser()
    try:
        args = parser.parse_args(join_negative_values(list(sys.argv[1:] if argv is None else argv)))
        start = time.perf_counter()
        with warnings.catch_warnings():   # one stderr line, always: numerical warnings are checked, not printed
            warnings.simplefilter("ignore")
            importlib.import_module(f"{__name__}.common").preflight(args)   # NumPy: not needed for --help
            command = importlib.import_module(f"{__name__}.{args.command}")
            data, text, code = command.run(args)
        if getattr(args, "json_out", None):
            write_json(args.json_out, data)
        if getattr(args, "verbose", 0):
            _say(f"packetloss-cvx: {args.command} took {time.perf_counter() - start:.3g} s")
        as_json = getattr(args, "json", False)
        if code == 3 and not as_json:
            _say(f"packetloss-cvx: {text}")
        elif as_json:
            print(json.dumps(data, allow_nan=False))
        else:
            print(printable(text, keep="\n"))   # a name the command missed still cannot drive the terminal
        return code
    except InputError as err:
        _say(f"packetloss-cvx: error: {err}")
        return 2
    except InfeasibleError as err:
        _say(f"packetloss-cvx: infeasible: {err}")
        return 3
    except (SolverError, NumericalError, CrossCheckError, ResourceError) as err:
        _say(f"packetloss-cvx: {type(err).__name__}: {err}")
        return 1
    except BrokenPipeError:  # the reader went away (e.g. `| head`): stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Exception as err:  # noqa: BLE001 - last line of defence: one line, no traceback
        _say(f"packetloss-cvx: unexpected {type(err).__name__}: {err}")
        return 1
