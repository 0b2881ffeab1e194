"""Command line: ``packetloss-cvx SUBCOMMAND ...`` (docs/design.md §4).

Exit codes: 0 success; 2 bad input (one stderr line naming the field); 3 a
well-posed problem with no solution (proved); 4 an allocation whose gap was not
certified within its caps (printed as usual); 1 anything else (one stderr line).

The grammar ([`.parser`][packetloss_cvx.cli.parser]) imports nothing numerical; the checks that need no solver
([`.common.preflight`][packetloss_cvx.cli.common.preflight]: files, overrides, number lists) run next, importing NumPy
only; the module that runs a subcommand (``solve``, ``audit``, ...) is imported only after them,
so ``--help``, ``--version`` and bad input answer without importing cvxpy or SciPy.
``--out FILE`` writes the JSON object to FILE as well (atomically; an existing FILE needs ``--force``);
``-v`` reports the time taken on stderr.

SIGINT and SIGTERM end a run with one line on stderr and exit 130 / 143 (128 + the signal): the handler
raises `Interrupted` (a KeyboardInterrupt) wherever the run is, so every ``with`` block on the way
out removes its temporary files and releases its folder's lock (safeio.py); a second signal during that
clean-up only is recorded (the handler sees the interrupt being handled). Nothing is set to "ignore" while the run
lasts: an interrupt that a library swallows is raised again between the run's steps and decides the exit code, and
an error that a signal surfaced as (an extension's import failing) is the interrupt. A signal while ``main`` decides
the code and restores the handlers is recorded and reported; one that lands after the program's run is over
(``main()`` without ``argv`` has returned: its files are complete and its code decided) is ignored. ``main(argv)``
restores the caller's handlers. The console script enters at ``packetloss_cvx.__main__``, whose first lines install
an early handler (one line, 130 / 143) for the imports before ``main``.

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

from ..errors import CrossCheckError, InfeasibleError, InputError, NumericalError, ResourceError, SolverError
from ..printable import printable
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


class _Stopper:
    """The handler of SIGINT and SIGTERM during one ``main`` call. It remembers the first signal and raises
    `Interrupted` where the run is, except where the run must not be interrupted: while an interrupt is
    already on its way out (a ``with`` block's or a ``finally``'s clean-up runs with it as the exception being
    handled), in ``main``'s own frame (which decides the exit code) and once the run is over (``over``). Nothing
    is set to "ignore": a library that swallows the interrupt (a bare ``except:`` around an import) leaves the run
    interruptible, and `check` raises the swallowed signal again at the run's next step."""

    def __init__(self) -> None:
        self.signum: int | None = None      # the first stop signal received
        self.over = False                   # the run's exit code is being decided: record, never raise

    def __call__(self, signum: int, frame: Any) -> None:
        if self.signum is None:
            self.signum = signum
        if self.over or frame is None or frame.f_code in _QUIET_CODES:
            return
        err, seen = sys.exc_info()[1], 0
        while err is not None and seen < 64:      # an interrupt being handled: a clean-up, not interrupted twice
            if isinstance(err, KeyboardInterrupt):
                return
            err, seen = err.__cause__ or err.__context__, seen + 1
        raise Interrupted(signum)

    def check(self) -> None:
        """Raise the interrupt received so far (one a library swallowed). O(1)."""
        if self.signum is not None:
            raise Interrupted(self.signum)


def _install_handlers(stopper: _Stopper) -> dict[int, Any] | None:
    """``stopper`` for SIGINT and SIGTERM, and the previous handlers (None outside the main thread)."""
    try:
        return {signum: signal.signal(signum, stopper) for signum in STOP_SIGNALS}
    except ValueError:       # not the main thread: signals are not ours to handle
        return None


def _say(message: str) -> None:
    """One stderr line, whatever the message holds (a key or a path with a newline or an escape sequence in it);
    nothing when standard error is closed (``print(file=None)`` would write to standard output)."""
    if sys.stderr is not None:
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
    program = argv is None
    for stream in (sys.stdout, sys.stderr):   # a terminal that cannot show a name gets an escape, not a crash
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    stopper = _Stopper()
    previous = _install_handlers(stopper)
    # From here to the end this frame is never interrupted (the handler records a signal that lands in it, and
    # every signal once ``over`` is set): only _run is, and what the signal did is decided below.
    interrupt: BaseException | None = None
    code = 1
    try:
        code = _run(argv, stopper)
    except KeyboardInterrupt as err:      # our Interrupted (or a library's own KeyboardInterrupt)
        interrupt = err
    finally:
        stopper.over = True
        if previous is not None:
            for signum, handler in previous.items():
                # the program ends here (its files complete, its code decided): a signal from now on has nothing to
                # stop, and the interpreter's own handlers would end it by the signal or with a traceback; in
                # process (main(argv)) the caller's handlers come back
                signal.signal(signum, signal.SIG_IGN if program else handler)
    if interrupt is not None or stopper.signum is not None:
        signum = getattr(interrupt, "signum", None) or stopper.signum or signal.SIGINT
        _say(f"packetloss-cvx: interrupted by {signal.Signals(signum).name}")
        code = STOP_SIGNALS.get(signum, 128 + signum)
        if program:             # the program is ending: a library's exit hook (distributed's close_clusters on a
            _quiet_stderr()     # cluster still starting) must not add a traceback after the one line
            if getattr(interrupt, "half_imported", False):   # the signal surfaced as a library's own error (an
                # extension's import failing): skip the interpreter's shutdown, which can abort on the
                # half-initialised module (exit -6, not 130)
                if sys.stdout is not None:
                    sys.stdout.flush()
                os._exit(code)
    if program:        # the program ends: its shutdown need not collect what is alive now (module docstring)
        gc.freeze()
    return code


def _quiet_stderr() -> None:
    """Standard error onto /dev/null, after what was said is flushed."""
    if sys.stderr is not None:
        sys.stderr.flush()
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stderr.fileno())


def _run(argv: Sequence[str] | None, stopper: _Stopper) -> int:
    """The command, and its exit code with one stderr line for a failure. An error raised after a signal arrived
    (or while handling one) is the interrupt: it is raised as `Interrupted`."""
    try:
        return _command(argv, stopper)
    except BrokenPipeError:  # the reader went away (e.g. `| head`): stop quietly
        if stopper.signum is not None:
            raise Interrupted(stopper.signum) from None
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Exception as err:  # noqa: BLE001 - last line of defence: one line, no traceback
        behind = _interrupt_behind(err)
        if behind is not None or stopper.signum is not None:
            # the signal surfaced as another error (a library's import failing with "initialization failed", or
            # NumPy's "C-extensions failed" with the interrupt cleared): that is the interrupt, not a fault; the
            # half-initialised module makes the interpreter's shutdown unsafe
            stop = Interrupted(getattr(behind, "signum", None) or stopper.signum or signal.SIGINT)
            stop.half_imported = True
            raise stop from None
        code, line = _failure(err)
        _say(line)
        return code


def _failure(err: Exception) -> tuple[int, str]:
    """The exit code and the one line of an error that ended a command.

    >>> _failure(InputError("--mu", "expected probabilities in [0, 1], found 2"))
    (2, 'packetloss-cvx: error: --mu: expected probabilities in [0, 1], found 2')
    """
    if isinstance(err, InputError):
        return 2, f"packetloss-cvx: error: {err}"
    if isinstance(err, InfeasibleError):
        return 3, f"packetloss-cvx: infeasible: {err}"
    if isinstance(err, (SolverError, NumericalError, CrossCheckError, ResourceError)):
        return 1, f"packetloss-cvx: {type(err).__name__}: {err}"
    return 1, f"packetloss-cvx: unexpected {type(err).__name__}: {err}"


def _command(argv: Sequence[str] | None, stopper: _Stopper) -> int:
    """Parse, check, import and run the command, write ``--out`` and print; returns the exit code. Between the
    steps ``stopper.check()`` raises a signal that a library swallowed, so a run never goes on past it."""
    stopper.check()
    if sys.stdout is None:      # started with standard output closed (`>&-`): print() would lose the result silently
        raise InputError("stdout", "standard output is closed, so the result would be lost; send it to a file or to "
                                   "/dev/null (> out.txt)")
    parser = build_parser()
    words = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(join_negative_values(words))
    args.command_line = shlex.join(["packetloss-cvx", *words])     # for a run folder's manifest
    start = time.perf_counter()
    with warnings.catch_warnings():   # one stderr line, always: numerical warnings are checked, not printed
        warnings.simplefilter("ignore")
        importlib.import_module(f"{__name__}.common").preflight(args)   # NumPy: not needed for --help
        stopper.check()
        command = _import_command(args.command, program=argv is None)
        stopper.check()
        data, text, code = command.run(args)
    stopper.check()
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
    """The KeyboardInterrupt (our signal handler's `Interrupted`) that ``err`` was raised while handling,
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


#: the frames the handler never raises in: main's own (it decides the exit code) and the handler's (a second signal
#: landing inside the first one's handling)
_QUIET_CODES = frozenset({main.__code__, _Stopper.__call__.__code__})
