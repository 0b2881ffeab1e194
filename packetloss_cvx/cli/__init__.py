"""Command line: ``packetloss-cvx SUBCOMMAND ...`` (docs/design.md §4).

Exit codes: 0 success; 2 bad input (one stderr line naming the field); 3 a
well-posed problem with no solution (proved); 4 an allocation whose gap was not
certified within its caps (printed as usual); 1 anything else (one stderr line).

The grammar (:mod:`.parser`) imports nothing numerical; the checks that need no solver
(:func:`.common.preflight`: files, overrides, number lists) run next, importing NumPy only;
the module that runs a subcommand (``solve``, ``audit``, ...) is imported only after them,
so ``--help``, ``--version`` and bad input answer without importing cvxpy or SciPy.
``--out FILE`` writes the JSON object to FILE as well (atomically; an existing FILE needs ``--force``);
``-v`` reports the time taken on stderr.

SIGINT and SIGTERM end a run with one line on stderr and exit 130 / 143 (128 + the signal): the handler
raises :class:`Interrupted` (a KeyboardInterrupt) wherever the run is, so every ``with`` block on the way
out removes its temporary files and releases its folder's lock (safeio.py); a second signal during that
clean-up is ignored, and so is one that lands after the program's run is over (``main()`` without ``argv`` has
returned: its files are complete and its code decided). ``main(argv)`` restores the caller's handlers.

When the program runs (``main()`` without ``argv``: the console script, ``python -m packetloss_cvx``), the
subcommand's module is imported with the cyclic garbage collector off, and every object tracked then (modules, their
tables and registries, alive until the program ends, and the few cycles of garbage the imports left: about 1,500
objects for ``reproduce``, kept until the end) is frozen out of it (``gc.freeze``) before the command runs:
the import's collections are skipped and the command's full collections walk only what the command made, not
everything cvxpy, SciPy and Matplotlib keep. Frozen objects are still freed by reference counting; only a cycle
among them stays until the end. When the program ends, the objects
alive at that point are frozen out of the cyclic garbage collector (``gc.freeze``) just before ``main`` returns, so
the interpreter's shutdown does not walk them all again to free memory the operating system takes back anyway:
0.25-0.3 s of CPU at the end of a full ``reproduce`` when measured, before the imports were frozen as well
(docs/performance.md, "The command line's exit"; now only what the command made is left to freeze). Every file is
complete and closed before that (atomic writes end in a rename inside the command), the standard streams are still
flushed by the interpreter, and exit handlers (``atexit``, ``weakref.finalize``) still run; only ``__del__`` of
objects caught in reference cycles at exit is skipped. Called with ``argv`` (in process: tests, notebooks) ``main``
leaves the collector alone.
"""

from __future__ import annotations

import gc
import importlib
import json
import os
import shlex
import signal
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..printable import printable
from ..errors import CrossCheckError, InfeasibleError, InputError, NumericalError, ResourceError, SolverError
from ..safeio import atomic_write
from .parser import build_parser, join_negative_values

__all__ = ["Interrupted", "main"]

#: the signals that end a run cleanly, with their exit codes (128 + the signal's number)
STOP_SIGNALS = {signal.SIGINT: 130, signal.SIGTERM: 143}


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived: raised in the main thread so that clean-up runs on the way out."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


def _stop(signum: int, frame: object) -> None:
    for other in STOP_SIGNALS:       # once: a second signal must not interrupt the clean-up
        signal.signal(other, signal.SIG_IGN)
    raise Interrupted(signum)


def _install_handlers() -> dict[int, Any] | None:
    """Our handlers for SIGINT and SIGTERM, and the previous ones (None outside the main thread)."""
    try:
        return {signum: signal.signal(signum, _stop) for signum in STOP_SIGNALS}
    except ValueError:       # not the main thread: signals are not ours to handle
        return None


def _say(message: str) -> None:
    """One stderr line, whatever the message holds (a key or a path with a newline or an escape sequence in it)."""
    print(printable(message), file=sys.stderr)


def write_json(path: str, data: dict[str, Any], force: bool = False) -> None:
    """``--out FILE``: the JSON object written to FILE atomically (an unwritable path is bad input; an existing
    FILE is refused without ``--force``)."""
    with atomic_write(Path(path), overwrite=force, text=True, field="--out") as handle:
        handle.write(json.dumps(data, allow_nan=False, indent=2) + "\n")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code.

    >>> main(["solve", "no-such-file.toml"])
    2
    """
    for stream in (sys.stdout, sys.stderr):   # a terminal that cannot show a name gets an escape, not a crash
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    previous = _install_handlers()
    try:
        return _run(argv)
    except KeyboardInterrupt as err:      # Ctrl-C before our handler (or a library's own KeyboardInterrupt)
        signum = err.signum if isinstance(err, Interrupted) else signal.SIGINT
        _say(f"packetloss-cvx: interrupted by {signal.Signals(signum).name}")
        code = STOP_SIGNALS.get(signum, 128 + signum)
        if argv is None:        # the program is ending: a library's exit hook (distributed's close_clusters on a
            sys.stderr.flush()  # cluster still starting) must not add a traceback after the one line
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stderr.fileno())
            if getattr(err, "half_imported", False):   # the signal landed in an extension's import: skip the
                # interpreter's shutdown, which can abort on the half-initialised module (exit -6, not 130)
                sys.stdout.flush()
                os._exit(code)
        return code
    finally:
        if previous is not None:
            for signum, handler in previous.items():
                # the program ends here (its files complete, its code decided): a signal from now on has nothing to
                # stop, and the interpreter's own handlers would end it by the signal or with a traceback; in
                # process (main(argv)) the caller's handlers come back
                signal.signal(signum, signal.SIG_IGN if argv is None else handler)
        if argv is None:        # the program ends: its shutdown need not collect what is alive now (module docstring)
            gc.freeze()


def _run(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        words = list(sys.argv[1:] if argv is None else argv)
        args = parser.parse_args(join_negative_values(words))
        args.command_line = shlex.join(["packetloss-cvx", *words])     # for a run folder's manifest
        start = time.perf_counter()
        with warnings.catch_warnings():   # one stderr line, always: numerical warnings are checked, not printed
            warnings.simplefilter("ignore")
            importlib.import_module(f"{__name__}.common").preflight(args)   # NumPy: not needed for --help
            command = _import_command(args.command, program=argv is None)
            data, text, code = command.run(args)
        if getattr(args, "json_out", None):
            write_json(args.json_out, data, getattr(args, "force", False))
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
        stop = _interrupt_behind(err)
        if stop is not None:   # a signal that landed inside a library's import (an extension's initialisation
            stop.half_imported = True   # failing as ImportError "initialization failed") is the interrupt, not a
            raise stop from None        # fault; the half-initialised module makes the shutdown unsafe
        _say(f"packetloss-cvx: unexpected {type(err).__name__}: {err}")
        return 1


def _import_command(name: str, program: bool) -> Any:
    """The module that runs subcommand ``name``. For the program (``program``: ``main()`` without ``argv``) the
    cyclic garbage collector is off during the import and what the import made is then frozen out of it (module
    docstring): modules and their tables live as long as the program, so neither the import's collections nor the
    command's full collections need to walk them. In process the collector is left alone."""
    if not program:
        return importlib.import_module(f"{__name__}.{name}")
    enabled = gc.isenabled()
    gc.disable()
    try:
        return importlib.import_module(f"{__name__}.{name}")
    finally:
        gc.freeze()
        if enabled:
            gc.enable()


def _interrupt_behind(err: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (our signal handler's :class:`Interrupted`) that ``err`` was raised while handling,
    if any: a signal inside an import surfaces as the import's own error. O(length of the chain).

    >>> try:
    ...     try:
    ...         raise Interrupted(signal.SIGINT)
    ...     except KeyboardInterrupt:
    ...         raise ImportError("initialization failed")
    ... except ImportError as err:
    ...     type(_interrupt_behind(err)).__name__
    'Interrupted'
    """
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None
