"""Command line: ``packetloss-cvx SUBCOMMAND ...`` (docs/design.md §4).

Exit codes: 0 success; 2 bad input (one stderr line naming the field); 3 a
well-posed problem with no solution (proved); 4 an allocation whose gap was not
certified within its caps (printed as usual); 1 anything else (one stderr line).

The grammar (:mod:`.parser`) imports nothing numerical; the module that runs a
subcommand (``solve``, ``audit``, ...) is imported only when that subcommand runs.
"""

from __future__ import annotations

import importlib
import json
import os
import sys
import warnings
from collections.abc import Sequence

from ..errors import CrossCheckError, InfeasibleError, InputError, NumericalError, ResourceError, SolverError
from .parser import build_parser, join_negative_values

__all__ = ["main"]


def _say(message: str) -> None:
    """One stderr line, whatever the message holds (a key or a path with a newline in it)."""
    print(message.replace("\r", "\\r").replace("\n", "\\n"), file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    for stream in (sys.stdout, sys.stderr):   # a terminal that cannot show a name gets an escape, not a crash
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    parser = build_parser()
    try:
        args = parser.parse_args(join_negative_values(list(sys.argv[1:] if argv is None else argv)))
        with warnings.catch_warnings():   # one stderr line, always: numerical warnings are checked, not printed
            warnings.simplefilter("ignore")
            command = importlib.import_module(f"{__name__}.{args.command}")
            data, text, code = command.run(args)
        as_json = getattr(args, "json", False)
        if code == 3 and not as_json:
            _say(f"packetloss-cvx: {text}")
        elif as_json:
            print(json.dumps(data, allow_nan=False))
        else:
            print(text)
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
