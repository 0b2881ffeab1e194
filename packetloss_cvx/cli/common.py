"""Helpers the subcommands share: number lists, the file's overrides, the checks run before a
command's (numerical) module is imported, the result a command returns.

Imports only the model and io layers (NumPy): [`preflight`][packetloss_cvx.cli.common.preflight] runs before ``main``
imports the subcommand's module, so that bad input is refused without importing cvxpy or SciPy
(docs/design.md §4).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..budgets import (
    burstiness_work,
    chain_states,
    check,
    check_constrained,
    count_text,
    duration_text,
    estimated_seconds,
    gib_text,
    mpc_bytes,
    mpc_loop_solves,
    simulate_work,
    solve_bytes,
    solve_work,
)
from ..errors import InputError, ProbabilityError
from ..model.constraints import Constraints, constraints_from_dict
from ..model.files import load_constraints, load_system, read_csv_rows, read_input
from ..model.system import System
from ..safeio import FIGURE_DPI, check_dpi, check_output_file
from ..tolerances import ALLOCATION_COST_RTOL, SOFT_WEIGHT_MAX_RATIO
from . import format as fmt
from .parser import FIGURE_FORMATS

__all__ = ["CHAIN_BASIS", "CONSTRAINT_FLAGS", "COST_BASIS", "MPC_SAMPLES", "WARNING_ADVICE", "CommandResult",
           "allocation_numbers", "attained_rows", "check_budgets", "check_dead_flags", "check_figure_format",
           "check_writable", "constraints_of", "figure_dpi", "figure_file", "floats", "integers", "mpc_samples_of",
           "number", "number_range", "preflight", "prices_and_bounds", "progress_of", "search_options", "system_of",
           "systems_of", "warning_advice", "with_overrides"]

#: counts that must be >= 0, with the words of their error message
NONNEGATIVE = {"random": "a count", "seed": "an integer"}
#: options that name a file the command writes after its work: checked before the work starts
OUTPUT_FILES = {"json_out": "--out", "save": "--save", "plot": "--plot"}
#: every option that names a path, read or written: a name the system cannot hold is refused under its flag
PATHS = {"file": "file", "files": "file", "mu_schedule": "--mu-schedule", "mu_list": "--mu-list", "out": "--out",
         "power_table": "--power-table", **OUTPUT_FILES}
#: the constrained loop's runs when FILE has a [constraints] table and --mpc-samples is not given
MPC_SAMPLES = 100
#: per command that draws, the options without which it writes no figure (the figure options are dead then)
FIGURE_NEEDS = {"simulate": (("plot", "--plot FILE"),), "sweep": (("out", "--out DIR"),),
                "region": (("out", "--out DIR"), ("grid", "--grid K"))}
#: the options that only shape a figure
FIGURE_OPTIONS = {"format": "--format", "dpi": "--dpi", "yscale": "--yscale"}
#: the longest path and path component the command line accepts (POSIX PATH_MAX and NAME_MAX on Linux)
MAX_PATH, MAX_NAME = 4096, 255


class CommandResult(NamedTuple):
    """What a subcommand returns: the JSON object, the text, and the exit code (0 unless said).

    Examples
    --------
    >>> CommandResult({"status": "optimal"}, "optimal").code, CommandResult({}, "infeasible", 3).code
    (0, 3)
    """

    data: dict[str, Any]
    text: str
    code: int = 0


def floats(text: str, field: str) -> list[float]:
    """``"1,-2.5"`` -> ``[1.0, -2.5]``; anything else is an [`InputError`][packetloss_cvx.errors.InputError] naming
        ``field``.

    Examples
    --------
    >>> floats("1,-2.5", "--x0")
    [1.0, -2.5]
    """
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        raise InputError(field, f"expected comma-separated numbers, found {text!r}") from None
    return values


def integers(text: str, field: str) -> list[int]:
    """``"5,10,20"`` -> ``[5, 10, 20]``: whole numbers only (``inf``, ``nan`` and ``2.5`` are refused with the
    field's name, not an OverflowError). O(len(text)).

    Examples
    --------
    >>> integers("5,1e2", "--horizons")
    [5, 100]
    >>> integers("10,inf", "--horizons")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --horizons: expected integers, found '10,inf'
    """
    values = floats(text, field)
    if not all(np.isfinite(v) and v == int(v) for v in values):
        raise InputError(field, f"expected integers, found {text[:40]!r}")
    return [int(v) for v in values]


def number_range(text: str, field: str) -> np.ndarray:
    """``"S1,S2,.."`` or ``"LO:HI:K"`` (K values from LO to HI): the values of ``--x0-scales`` and ``--burstiness``.
    K must be a whole number within the ``sweep_points`` budget, checked before ``linspace`` allocates. O(K).

    Examples
    --------
    >>> number_range("0:1:3", "--x0-scales").tolist(), number_range("0.5,2", "--x0-scales").tolist()
    ([0.0, 0.5, 1.0], [0.5, 2.0])
    >>> number_range("0:1:inf", "--burstiness")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --burstiness: expected an integer count K >= 1, found 'inf'
    """
    if ":" not in text:
        return np.array(floats(text, field))
    parts = text.split(":")
    if len(parts) != 3:
        raise InputError(field, f"expected LO:HI:K, found {text[:40]!r}")
    lo, hi = number(parts[0], field), number(parts[1], field)
    count = number(parts[2], field)
    if not np.isfinite(count) or count != int(count) or count < 1:
        raise InputError(field, f"expected an integer count K >= 1, found {parts[2][:40]!r}")
    check("sweep_points", count, field, f"{int(count)} values")      # before linspace allocates them
    return np.linspace(lo, hi, int(count))


def number(text: str, field: str) -> float:
    """Exactly one number.

    Examples
    --------
    >>> number("8", "--alpha")
    8.0
    """
    values = floats(text, field)
    if len(values) != 1:
        raise InputError(field, f"expected one number, found {text[:40]!r}")
    return values[0]


def read_schedule(path: str) -> np.ndarray:
    """A CSV file of N rows of m delivery probabilities, read by the one CSV reader
    (`read_csv_rows`: a header row, ``#`` comments and a byte-order mark skipped;
    a regular file within the ``file_bytes`` budget, a FIFO or /dev/zero refused before it is read); a value
    outside [0, 1] is a `ProbabilityError` naming its file line, as the reader's own errors do. O(N m).

    Examples
    --------
    >>> read_schedule("/dev/zero")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --mu-schedule: /dev/zero is not a regular file (a device, a pipe or a socket)
    """
    csv = read_csv_rows(path, "--mu-schedule")
    schedule = np.array(csv.rows, dtype=float)     # rows of one width
    bad = np.flatnonzero(np.any((schedule < 0.0) | (schedule > 1.0), axis=1))
    if bad.size:
        value = next(v for v in schedule[bad[0]] if not 0.0 <= v <= 1.0)
        raise ProbabilityError("--mu-schedule", f"{csv.where(bad[0])}: expected probabilities in [0, 1], found "
                                                f"{value:g}")
    return schedule


def with_overrides(system: System, args: argparse.Namespace) -> System:
    """The file's system with ``--mu`` (one number means every channel), ``--mu-schedule`` and
    ``--x0`` applied, errors renamed to the flag. O(N m + n).

    Examples
    --------
    >>> from packetloss_cvx.model.files import load_example
    >>> with_overrides(load_example("two_actuator"), argparse.Namespace(mu="0.5")).mu.tolist()
    [0.5, 0.5]
    """
    if getattr(args, "mu", None) is not None:
        values = floats(args.mu, "--mu")
        try:
            system = system.with_mu(values * system.m if len(values) == 1 else values)
        except InputError as err:
            raise err.renamed("--mu") from None
    if getattr(args, "mu_schedule", None) is not None:
        try:
            system = system.with_mu(read_schedule(args.mu_schedule))
        except InputError as err:
            raise err.renamed("--mu-schedule") from None
    if getattr(args, "x0", None) is not None:
        try:
            system = system.with_x0(floats(args.x0, "--x0"))
        except InputError as err:
            raise err.renamed("--x0") from None
    return system


#: The ``[constraints]`` keys the command line overrides, with their flags (``args`` holds them under the key).
CONSTRAINT_FLAGS = {"u_min": "--u-min", "u_max": "--u-max", "du_max": "--du-max", "x_min": "--x-min",
                    "x_max": "--x-max", "terminal_min": "--terminal-min", "terminal_max": "--terminal-max",
                    "soft": "--soft", "soft_weight": "--soft-weight"}


def constraints_of(args: argparse.Namespace, system: System) -> Constraints | None:
    """The file's ``[constraints]`` table with the command line's overrides (`CONSTRAINT_FLAGS`: each flag given
    replaces its key; one number stands for every input or state), checked against ``system``; None where neither
    the file nor a flag constrains anything. An error names the flag where the key came from one, else
    ``constraints.<key>``. O(n + m) beyond the file's table.

    Examples
    --------
    >>> args = argparse.Namespace(file="two_actuator", u_min="-1", u_max="1,2", soft=None)
    >>> from packetloss_cvx.model.files import load_example
    >>> c = constraints_of(args, load_example("two_actuator"))
    >>> c.u_min.tolist(), c.u_max.tolist()
    ([-1.0, -1.0], [1.0, 2.0])
    >>> constraints_of(argparse.Namespace(file="two_actuator", u_min="0.5"), load_example("two_actuator"))
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: --u-min: a lost packet applies zero input, ...; found u_min[0] = 0.5 > 0
    """
    constraints = load_constraints(args.file, system)
    given = {key: getattr(args, key) for key in CONSTRAINT_FLAGS if getattr(args, key, None) is not None}
    if not given:
        if constraints is not None:
            check_soft_weight(constraints, system, "constraints.soft_weight")
        return constraints
    table = {} if constraints is None else constraints.to_dict()
    for key, value in given.items():
        flag = CONSTRAINT_FLAGS[key]
        if key == "soft":
            table[key] = bool(value)
        elif key == "soft_weight":
            table[key] = number(value, flag)
        else:
            values = floats(value, flag)
            size = system.m if key[0] in "ud" else system.n
            table[key] = values * size if len(values) == 1 else values
    try:
        constraints = constraints_from_dict(table, system.n, system.m, prefix="")
    except InputError as err:
        key = err.field.split(".")[0].split("[")[0]
        raise err.renamed(CONSTRAINT_FLAGS[key] if key in given else f"constraints.{err.field}") from None
    check_soft_weight(constraints, system, "--soft-weight" if "soft_weight" in given else "constraints.soft_weight")
    return constraints


def check_soft_weight(constraints: Constraints, system: System, field: str) -> None:
    """Refuse a soft-row weight beyond the solver's range: rho above `SOFT_WEIGHT_MAX_RATIO` (1e8) times the cost
    scale (the largest weight, as ``ConstrainedQP.scale``) swamps the cost and the QP comes back "solver_error" or a
    false "infeasible"; a weight that large holds the rows as hard as the solver can anyway. O(n^3).

    Examples
    --------
    >>> from packetloss_cvx.model.files import load_example
    >>> check_soft_weight(Constraints(x_max=[1.0, 1.0], soft=True, soft_weight=1e308), load_example("two_actuator"),
    ...                   "--soft-weight")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: --soft-weight: expected a weight in (0, 1e+08] ...; found 1e+308
    """
    if not constraints.soft:
        return
    scale = max(float(system.input_weights.max()), float(np.linalg.eigvalsh(system.state_weights).max()))
    top = SOFT_WEIGHT_MAX_RATIO * scale
    if not constraints.soft_weight <= top:
        raise InputError(field, f"expected a weight in (0, {top:.3g}] (at most {SOFT_WEIGHT_MAX_RATIO:g} times the "
                                f"largest cost weight, {scale:.3g}: beyond it the solver cannot weigh the slack "
                                "against the cost, and the rows are already as hard as it can hold them; --no-soft "
                                f"makes them hard); found {constraints.soft_weight:.6g}")


def system_of(args: argparse.Namespace) -> System:
    """``args.file`` loaded with its overrides, once per command (kept on ``args``).

    Examples
    --------
    >>> args = argparse.Namespace(file="two_actuator", mu="0.5")
    >>> system_of(args).mu.tolist(), system_of(args) is system_of(args) is args.loaded_system
    ([0.5, 0.5], True)
    """
    if getattr(args, "loaded_system", None) is None:
        args.loaded_system = with_overrides(load_system(args.file), args)
    return args.loaded_system


def systems_of(args: argparse.Namespace) -> list[System]:
    """Every ``args.files`` loaded, once per command (kept on ``args``).

    Examples
    --------
    >>> args = argparse.Namespace(files=["pendulum", "two_actuator"])
    >>> [s.name for s in systems_of(args)], systems_of(args) is args.loaded_systems
    (['pendulum', 'two-actuator'], True)
    """
    if getattr(args, "loaded_systems", None) is None:
        args.loaded_systems = [load_system(path) for path in args.files]
    return args.loaded_systems


def allocation_numbers(args: argparse.Namespace, m: int) -> tuple[float, list[float], list[float]]:
    """``--alpha``, ``--beta`` (m prices) and ``--bounds`` (lo,hi) parsed and counted.

    Examples
    --------
    >>> allocation_numbers(argparse.Namespace(alpha="8", beta="1,0.05", bounds="0,1"), 2)
    (8.0, [1.0, 0.05], [0.0, 1.0])
    """
    return (number(args.alpha, "--alpha"), *prices_and_bounds(args, m))


def prices_and_bounds(args: argparse.Namespace, m: int) -> tuple[list[float], list[float]]:
    """``--beta`` (m prices) and ``--bounds`` (lo,hi) parsed and counted.

    Examples
    --------
    >>> prices_and_bounds(argparse.Namespace(beta="1,0.05", bounds="0,1"), 2)
    ([1.0, 0.05], [0.0, 1.0])
    """
    beta = floats(args.beta, "--beta")
    if len(beta) != m:
        raise InputError("--beta", f"expected {m} comma-separated numbers, found {len(beta)}")
    bounds = floats(args.bounds, "--bounds")
    if len(bounds) != 2:
        raise InputError("--bounds", f"expected lo,hi, found {args.bounds[:40]!r}")
    return beta, bounds


def search_options(args: argparse.Namespace) -> dict[str, Any]:
    """``--gap``, ``--max-boxes`` and ``--time-limit`` of the allocation searches, only those given (unset flags
    keep the API's defaults: one source of truth).

    Examples
    --------
    >>> search_options(argparse.Namespace(gap="1e-3", max_boxes=None, time_limit="5"))
    {'gap': 0.001, 'time_limit': 5.0}
    """
    options: dict[str, Any] = {}
    if args.gap is not None:
        options["gap"] = number(args.gap, "--gap")
    if args.max_boxes is not None:
        options["max_boxes"] = args.max_boxes
    if args.time_limit is not None:
        options["time_limit"] = number(args.time_limit, "--time-limit")
    return options


def preflight(args: argparse.Namespace) -> None:
    """Every check that needs no numerical module: counts, files, overrides, number lists.

    ``main`` runs it before importing the command's module, so bad input costs a NumPy import,
    not a cvxpy one. The command's own checks still run (they are the same functions).

    Examples
    --------
    >>> preflight(argparse.Namespace(file="two_actuator", mu="1.5"))
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.ProbabilityError: --mu: expected probabilities in [0, 1], found 1.5
    """
    for name, what in NONNEGATIVE.items():
        value = getattr(args, name, None)
        if isinstance(value, int) and value < 0:
            raise InputError(f"--{name}", f"expected {what} >= 0, found {value}")
    for name, flag in PATHS.items():
        value = getattr(args, name, None)
        for path in value if isinstance(value, list) else [value]:
            if isinstance(path, str):
                check_path_length(path, flag)
    seen: dict[str, str] = {}
    for name, flag in OUTPUT_FILES.items():   # a typo in an output path costs nothing, not the whole run
        if isinstance(getattr(args, name, None), str):
            target = os.path.realpath(getattr(args, name))
            if target in seen:                # two outputs of one run into one file: one would replace the other
                raise InputError(flag, f"names the same file as {seen[target]}: {getattr(args, name)!r}")
            seen[target] = flag
            check_writable(getattr(args, name), flag, getattr(args, "force", False))
    if isinstance(getattr(args, "save", None), str) and not args.save.endswith(".npz"):
        raise InputError("--save", f"expected a FILE.npz, found {args.save!r}")
    figure_dpi(args)
    check_dead_flags(args)
    if isinstance(getattr(args, "plot", None), str):
        figure_file(args, args.plot)
    if getattr(args, "plot", None) and getattr(args, "closed_loop", None) is False:
        raise InputError("--plot", "the figure shows the closed loop: add --closed-loop")
    if getattr(args, "file", None) is not None:
        system = system_of(args)
        if getattr(args, "alpha", None) is not None and getattr(args, "beta", None) is not None:
            allocation_numbers(args, system.m)
    if getattr(args, "files", None):
        systems_of(args)
    check_budgets(args)


def check_budgets(args: argparse.Namespace) -> None:
    """The counts a command line gives checked against their budgets (budgets.py) under the option's name,
    before the command's module is imported: ``--random``, ``--workers``, ``--max-boxes``, simulate's
    ``--samples`` x ``--steps`` (and the constrained loop's ``--mpc-samples`` x ``--steps`` solves), sweep's
    ``--horizons``, ``--x0-scales`` and ``--burstiness`` values (and the burstiness work) and the ``--mu-list``
    file. (A sweep's other points and its work are checked by the sweep itself, before any point is evaluated, and
    named by the option that asked for them.) O(1), or O(values) for a list.

    Examples
    --------
    >>> check_budgets(argparse.Namespace(command="audit", random=10**12))
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.BudgetError: --random: 1000000000000 random systems is over the budget of 1e+04 random \
systems of an audit (about 5 min); to run it on purpose set PACKETLOSS_CVX_BUDGET_AUDIT_CASES=1e+12
    """
    command = getattr(args, "command", None)
    if command == "audit" and isinstance(getattr(args, "random", None), int):
        check("audit_cases", args.random, "--random", f"{count_text(args.random)} random systems")
    if command in ("sweep", "simulate") and isinstance(getattr(args, "workers", None), int):
        check("dask_workers", args.workers, "--workers", f"{count_text(args.workers)} worker processes")
    if command == "allocate" and isinstance(getattr(args, "max_boxes", None), int):
        check("allocation_boxes", args.max_boxes, "--max-boxes", f"{count_text(args.max_boxes)} boxes")
    if command == "sweep":        # what the sweep module would refuse, refused before it is imported
        if getattr(args, "horizons", None) is not None:
            integers(args.horizons, "--horizons")
        if getattr(args, "x0_scales", None) is not None:
            number_range(args.x0_scales, "--x0-scales")
        if getattr(args, "mu_list", None) is not None:
            read_input(args.mu_list, "--mu-list")
        if getattr(args, "burstiness", None) is not None:
            values = number_range(args.burstiness, "--burstiness")
            rates = number_range(args.mean_rate, "--mean-rate") if getattr(args, "mean_rate", None) else None
            points = values.size if rates is None else values.size * rates.size
            field = "--burstiness" if rates is None else "--mean-rate"
            what = f"{values.size} values" if rates is None else f"{rates.size} x {values.size} points"
            check("sweep_points", points, field, what)
            system = system_of(args)
            check("sweep_work", burstiness_work(points, system.horizon, system.m, n=system.n), field,
                  f"{what} at N = {system.horizon}, m = {system.m}")
    if command == "solve":
        check_solve(system_of(args), args, constraints_of(args, system_of(args)))
    if command == "simulate" and min(args.samples, args.steps) >= 1:
        system = system_of(args)
        laws = ("tcp", "udp", "dp") if args.law == "all" else (args.law,)
        plans, loops = sum(law != "dp" for law in laws), len(laws) if args.closed_loop else 0
        check("simulate_work", simulate_work(args.samples, args.steps, system.horizon, system.n, system.m, plans,
                                             loops),
              "--samples", f"{count_text(args.samples)} samples"
                           f"{f' of {count_text(args.steps)} steps' if args.closed_loop else ''} "
                           f"(--samples x (N x {plans} plans + --steps x {loops} loops) x n (n + m), "
                           f"n = {system.n}, m = {system.m}, N = {system.horizon})")
        mpc_samples = mpc_samples_of(args)
        constraints = constraints_of(args, system) if mpc_samples >= 1 else None
        if constraints is not None:
            check_constrained(N := system.horizon, system.n, system.m, constraints.program_rows(N),
                              len(constraints.chance), "cost.horizon",
                              instead="use a shorter horizon, or --mpc-samples 0 to skip the constrained loop",
                              states=chain_states(system.channel))
            # per --actuator strategy (none: zero alone): expected-cost per protocol, certainty-equivalent once
            # (per protocol under hold and buffer: what it plans from differs), the clipped law per protocol
            names = _strategy_names(getattr(args, "actuator", None))
            programs = sum(2 if args.law != "all" else 3 if name == "zero" else 4 for name in names)
            clipped = len(names) * (2 if args.law == "all" else 1)
            linear, chance = constraints.program_rows(N), len(constraints.chance)
            # behind a chain the expected-cost programs (one per clipped law) pose their chance rows exact under it
            states = chain_states(system.channel) if chance else 0
            units, priced = mpc_loop_solves(mpc_samples, args.steps, programs, clipped, clipped if states else 0, N,
                                            system.n, system.m, linear, chance, states)
            check("mpc_solves", units, "--mpc-samples", f"{count_text(mpc_samples)} runs of {count_text(args.steps)} "
                  f"steps x {programs} programs (the constrained loop; {priced})")
            rows = constraints.loop_rows()
            jobs = max(3 if args.law != "all" else 5 if name == "zero" else 6 for name in names)   # one loop at a time
            needed = mpc_bytes(mpc_samples, args.steps, system.n, system.m, jobs, rows)
            check("memory_bytes", needed, "--mpc-samples", f"{count_text(mpc_samples)} runs of "
                                                           f"{count_text(args.steps)} steps of the constrained loop "
                                                           f"(about {gib_text(needed)})",
                  instead="use fewer runs (--mpc-samples) or steps (--steps)")


def _strategy_names(text: str | None) -> list[str]:
    """The distinct strategies ``--actuator`` names, as written (checked later by ``actuator_strategies``), for the
    constrained loop's budget: zero alone without it, "all" three. O(len(text)).

    >>> _strategy_names(None), _strategy_names("all"), _strategy_names("hold, buffer:2,hold")
    (['zero'], ['zero', 'hold', 'buffer'], ['hold', 'buffer:2'])
    """
    if text is None:
        return ["zero"]
    if text.strip() == "all":
        return ["zero", "hold", "buffer"]
    return list(dict.fromkeys(part.strip() for part in text.split(",")))


def mpc_samples_of(args: argparse.Namespace) -> int:
    """``--mpc-samples``, `MPC_SAMPLES` where not given. O(1).

    >>> mpc_samples_of(argparse.Namespace(mpc_samples=None)), mpc_samples_of(argparse.Namespace(mpc_samples=0))
    (100, 0)
    """
    value = getattr(args, "mpc_samples", None)
    return MPC_SAMPLES if value is None else value


def check_dead_flags(args: argparse.Namespace) -> None:
    """An option that would change nothing is refused (exit 2, one line naming it and what it needs), as a
    conflicting one is: ``--format``, ``--dpi`` and ``--yscale`` without the option that writes the figure
    (`FIGURE_NEEDS`), ``simulate --mpc-samples K >= 1`` on a FILE with no ``[constraints]`` table and no
    constraint flag (``--mpc-samples 0`` skips the constrained loop, which such a FILE does anyway), and ``audit
    --report`` with ``--json`` (the JSON is printed instead of the text the report is). O(1) beyond loading FILE.

    Examples
    --------
    >>> check_dead_flags(argparse.Namespace(command="sweep", out=None, format="svg", dpi=None))
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --format: needs --out DIR (it sets the figures written there)
    >>> check_dead_flags(argparse.Namespace(command="simulate", file="two_actuator", plot=None, mpc_samples=400))
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --mpc-samples: needs a [constraints] table in FILE or a constraint flag \
(--u-min, --u-max, --du-max, ...): without one there is no constrained loop to sample
    """
    command = getattr(args, "command", None)
    if command == "audit" and getattr(args, "report", False) and getattr(args, "json", False):
        raise InputError("--report", "not with --json, which prints the claims' JSON object instead of text: the "
                                     "Markdown report is text (--out FILE writes the JSON beside it)")
    for name, need in FIGURE_NEEDS.get(command, ()):
        if getattr(args, name, None) is None:
            for option, flag in FIGURE_OPTIONS.items():
                if getattr(args, option, None) is not None:
                    what = "figure" if command == "simulate" else "figures written there"
                    raise InputError(flag, f"needs {need} (it sets the {what})" if name != "grid" else
                                     f"needs {need} (it sets the map region.png; without --grid none is drawn)")
    if command == "simulate" and getattr(args, "mpc_samples", None) and getattr(args, "file", None) is not None:
        if constraints_of(args, system_of(args)) is None:
            raise InputError("--mpc-samples", "needs a [constraints] table in FILE or a constraint flag "
                                              "(--u-min, --u-max, --du-max, ...): without one there is no "
                                              "constrained loop to sample")


def check_solve(system: System, args: argparse.Namespace, constraints: Constraints | None = None) -> None:
    """``solve``'s horizon priced before the work: its time (``solve_work``, with or without the QP cross-check) and
    its memory (``memory_bytes``), each refused under the file's ``cost.horizon`` with the way out (``--no-qp``: the
    cross-check is 60 times the closed forms). O(1).

    Examples
    --------
    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[0.9]], B=[[1.0]], horizon=10 ** 6, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> check_solve(s, argparse.Namespace(protocol="both", no_qp=True, formulation="auto"))     # 0.93 s: silent
    >>> check_solve(s, argparse.Namespace(protocol="both", no_qp=False, formulation="auto"))
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.BudgetError: cost.horizon: N = 1000000 (n = 1, m = 1) with the QP cross-check (about 1 \
min; --no-qp skips it: 0.93 s) is over the budget of 6e+07 work units of one solve (solve_work) (about 1 min); to run \
it on purpose set PACKETLOSS_CVX_BUDGET_SOLVE_WORK=6.22e+07
    """
    N, n, m = system.horizon, system.n, system.m
    protocols = 2 if getattr(args, "protocol", "both") == "both" else 1
    qp = None if getattr(args, "no_qp", False) else getattr(args, "formulation", "auto")
    qp = "sparse" if qp == "auto" else qp
    size = f"N = {N} (n = {n}, m = {m})"
    if qp is None:
        what = f"{size} without the QP cross-check"
    else:
        alone = estimated_seconds("solve_work", solve_work(N, n, m, protocols, qp=None))
        what = f"{size} with the QP cross-check (about {{}}; --no-qp skips it: {duration_text(alone)})"
    work = solve_work(N, n, m, protocols, qp)
    check("solve_work", work, "cost.horizon", what.format(duration_text(estimated_seconds("solve_work", work))))
    need = solve_bytes(N, n, m, qp)
    check("memory_bytes", need, "cost.horizon", f"{size}{'' if qp is None else ' with the QP cross-check'} "
                                               f"(about {gib_text(need)})",
          instead="use a shorter horizon" if qp is None else "--no-qp skips the cross-check")
    if constraints is not None and qp is not None:     # the [constraints] table's program, once per protocol
        check_constrained(N, n, m, constraints.program_rows(N), len(constraints.chance), "cost.horizon", protocols,
                          instead="use a shorter horizon, or --no-qp to skip the constrained program",
                          states=chain_states(system.channel))       # behind a chain its chance rows are exact


def check_figure_format(path: str, field: str) -> None:
    """A figure FILE in one of the formats every command writes (`FIGURE_FORMATS`: png, pdf, svg; no extension:
    ``--format``, default png), else exit 2 naming ``field``. Matplotlib writes more (jpg, tiff, eps: the last
    with a transparency warning on stderr), but the figures are styled, tested and documented in these three. O(1).

    Examples
    --------
    >>> check_figure_format("loop.eps", "--plot")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --plot: cannot write an 'eps' figure: expected a FILE ending in .png, .pdf \
or .svg, found 'loop.eps'
    """
    suffix = Path(path).suffix[1:].lower()
    if suffix and suffix not in FIGURE_FORMATS:
        article = "an" if suffix[0] in "aeiou" else "a"
        raise InputError(field, f"cannot write {article} {suffix!r} figure: expected a FILE ending in .png, .pdf or "
                                f".svg, found {path[:80]!r}")


def figure_file(args: argparse.Namespace, stem: str) -> str:
    """The name of a figure a command writes: ``stem`` with the extension of ``--format`` (default png). For a
    FILE the user named (``stem`` with an extension, e.g. ``--plot loop.pdf``), that extension, and a different
    ``--format`` beside it is refused rather than one silently winning. O(1).

    Examples
    --------
    >>> figure_file(argparse.Namespace(format="svg"), "region"), figure_file(argparse.Namespace(), "region")
    ('region.svg', 'region.png')
    >>> figure_file(argparse.Namespace(format=None), "loop.pdf")
    'loop.pdf'
    >>> figure_file(argparse.Namespace(format="svg"), "loop.pdf")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --format: svg, but the figure's file 'loop.pdf' says pdf: drop one
    """
    chosen = getattr(args, "format", None)
    check_figure_format(stem, "--plot")
    suffix = Path(stem).suffix[1:].lower()
    if not suffix:
        return f"{stem}.{chosen or 'png'}"
    if chosen and chosen != suffix:
        raise InputError("--format", f"{chosen}, but the figure's file {stem!r} says {suffix}: drop one")
    return stem


def figure_dpi(args: argparse.Namespace) -> int:
    """``--dpi`` checked (safeio.check_dpi), default `FIGURE_DPI`: a whole number on the command line, since a PNG
    records its resolution in whole dots per metre (``--dpi 100.5`` would be stored as 100.51; the API's
    ``save_figure(dpi=)`` takes what Matplotlib takes). O(1).

    >>> figure_dpi(argparse.Namespace(dpi=None)), figure_dpi(argparse.Namespace(dpi=300.0))
    (120, 300)
    >>> figure_dpi(argparse.Namespace(dpi=100.5))
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --dpi: expected a whole number of dots per inch in [10, 2400], found 100.5
    """
    dpi = getattr(args, "dpi", None)
    if dpi is None:
        return FIGURE_DPI
    value = check_dpi(dpi, "--dpi")
    if not float(value).is_integer():
        raise InputError("--dpi", f"expected a whole number of dots per inch in [10, 2400], found {dpi!r}")
    return int(value)


def check_path_length(path: str, field: str) -> None:
    """A path no longer than `MAX_PATH` whose components are at most `MAX_NAME` characters (what
    Linux file systems hold), else an InputError naming ``field`` (exit 2, not an OSError). O(len(path)).

    Examples
    --------
    >>> check_path_length("out/" + "a" * 5000 + ".json", "--out")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --out: file name too long (a component of 5005 characters; at most 255)
    """
    longest = max((len(part.encode("utf-8", "surrogateescape")) for part in path.split("/")), default=0)
    if longest > MAX_NAME:
        raise InputError(field, f"file name too long (a component of {longest} characters; at most {MAX_NAME})")
    if len(path.encode("utf-8", "surrogateescape")) > MAX_PATH:
        raise InputError(field, f"path too long ({len(path)} characters; at most {MAX_PATH})")


def check_writable(path: str, field: str, force: bool = False) -> None:
    """A FILE the command will write: not a directory, FIFO or device, in a directory that exists and may be
    written, and not an existing file unless ``--force`` (safeio.check_output_file). Nothing is created. O(1).

    Examples
    --------
    >>> check_writable("/no-such-directory/out.json", "--out")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --out: cannot write '/no-such-directory/out.json': no such directory
    """
    check_output_file(path, field, force)


def progress_of(args: argparse.Namespace) -> bool | None:
    """The ``progress=`` to pass to the API: off with ``--quiet``, else automatic (a terminal shows bars).

    Examples
    --------
    >>> progress_of(argparse.Namespace(quiet=True)), progress_of(argparse.Namespace(quiet=False))
    (False, None)
    """
    return False if getattr(args, "quiet", False) else None


#: the basis of each protocol's J* as the commands print it (docs/design.md, "Cost bases"): the paper's
#: expressions, J*_tcp a first-moment value that no law attains, J*_udp the exact expected cost of its plan and so the
#: attainable cost too; J_Delta ("diff") their difference
COST_BASIS = {"tcp": "paper", "udp": "paper = attainable", "diff": "paper"}
#: behind a Markov chain: the TCP-like cost holds only the predicted mu_t (the paper's expression), the UDP-like
#: exact minimum is the exact expected cost of the optimal plan under the chain (the attainable cost)
CHAIN_BASIS = {"tcp": "paper", "udp": "attainable"}

#: what the warning line advises (Bernoulli channels; behind a chain `warning_advice`)
WARNING_ADVICE = " (design on the loop: --target stable or --target dp-cost)"


def warning_advice(result: Any, channel: Any, file: str) -> str:
    """What the warning line advises after an allocation for ``file``: `WARNING_ADVICE` on Bernoulli channels; behind
    a Markov chain (``channel``), where ``--target stable|dp-cost`` do not apply (they design Bernoulli channels),
    what does: for a loop no law holds, the chain's critical mean rate and stabilisable map (``region FILE``,
    two-state chains; nothing for k-state chains) to raise ``--bounds`` above; for an attainable cost above alpha,
    ``--target attainable`` (the chain DP along the family). O(1).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> r = SimpleNamespace(alpha=8.0, attainable_cost=9.0, stabilisable=False)
    >>> warning_advice(r, None, "f.toml") == WARNING_ADVICE
    True
    >>> text = warning_advice(r, GilbertElliott(p=[0.1], r=[0.4]), "f.toml")
    >>> text.startswith(" (behind a chain --target stable|dp-cost do not apply: "), "region f.toml" in text
    (True, True)
    >>> "--target attainable" in text                 # 9 > alpha = 8: the attainable cost misses it too
    True
    """
    if channel is None:
        return WARNING_ADVICE
    parts = []
    if result.stabilisable is False:
        parts.append(f"the chain's critical mean rate and map, packetloss-cvx region {file} --grid 21, then --bounds "
                     "LO,1 above it" if channel.two_state else
                     "no stabilisable-set engine covers k-state chains: raise --bounds LO,1 and read the verdict at "
                     "each mu*")
    alpha = getattr(result, "alpha", None)
    if (alpha is not None and result.attainable_cost is not None
            and result.attainable_cost > alpha * (1.0 + ALLOCATION_COST_RTOL)):
        parts.append("--target attainable designs on the chain's attainable cost")
    return " (behind a chain --target stable|dp-cost do not apply: " + "; ".join(parts) + ")"


def attained_rows(result: Any) -> list[tuple[str, str]]:
    """The rows of what a loop attains at mu*: the attainable cost (named by its basis) and the verdict of the best
    linear law, each with its note.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> r = SimpleNamespace(attainable_cost=38.0843, attainable_note="finite-horizon DP with acknowledgements",
    ...                     stabilisable=None, stability_note="undecided: near the boundary")
    >>> attained_rows(r)[0][1], attained_rows(r)[1][1]
    ('38.0843 (finite-horizon DP with acknowledgements)', 'no verdict (undecided: near the boundary)')
    """
    cost = ("not computed" if result.attainable_cost is None else fmt.num(result.attainable_cost, 10))
    verdict = {True: "yes", False: "NO", None: "no verdict"}[result.stabilisable]
    return [("attainable cost", f"{cost} ({result.attainable_note})"),
            ("stabilisable", f"{verdict} ({result.stability_note})")]
