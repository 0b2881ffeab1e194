"""System files: the TOML schema of docs/design.md §4, reading, writing, and the examples
shipped with the package (``packetloss_cvx/model/examples/*.toml``, read with importlib.resources).
"""

from __future__ import annotations

import csv
import errno
import io
import json
import math
import os
import stat
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from ..budgets import BUDGETS, check
from ..errors import InputError
from ..safeio import atomic_write
from .constraints import Constraints, check_constraints, constraints_from_dict
from .examples import names as packaged_names
from .sensor import SENSOR_KEYS
from .system import System

__all__ = ["CsvRows", "dumps_system", "example_names", "load_constraints", "load_example", "load_system", "load_table",
           "read_csv_numbers", "read_csv_rows",
           "read_input",
           "save_system",
           "system_from_dict"]


# TOML section -> {key: System keyword}
_SCHEMA: dict[str, dict[str, str]] = {
    "plant": {"A": "A", "B": "B", "noise_cov": "noise_cov", "dt": "dt", "input_labels": "input_labels",
              "state_labels": "state_labels"},
    "cost": {
        "horizon": "horizon", "state_weight": "state_weight", "state_weights": "state_weights",
        "input_weight": "input_weight", "input_weights": "input_weights",
        "initial_weight": "initial_weight",
    },
    "channel": {"mu": "mu", "mu_schedule": "mu_schedule",   # or a Gilbert-Elliott or general Markov chain
                **{key: f"channel.{key}" for key in ("model", "p", "r", "h_good", "h_bad", "state", "belief",
                                                     "transition", "delivery")}},
    "state": {"x0": "x0", "P0": "sensor.P0"},
    "sensor": {key: f"sensor.{key}" for key in SENSOR_KEYS},     # optional: lossy sensor links (sensor.py)
}
_REQUIRED = {"plant": ("A", "B"), "cost": ("horizon",), "channel": (), "state": ("x0",), "sensor": ()}
_OPTIONAL_SECTIONS = ("sensor",)
#: optional sections a System does not hold, read by their own module (``[power]``: allocation/delivery.py;
#: ``[constraints]``: :func:`load_constraints`, model/constraints.py)
OTHER_SECTIONS = ("power", "constraints")


def system_from_dict(data: Mapping[str, Any]) -> System:
    """Build a [`System`][packetloss_cvx.model.system.System] from the TOML schema's structure (see docs/design.md §4).

    Errors name the TOML path of the offending field (``cost.state_weight``).

    Examples
    --------
    >>> data = {"plant": {"A": [[1.0]], "B": [[1.0]]}, "channel": {"mu": [0.5]}, "state": {"x0": [1.0]},
    ...         "cost": {"horizon": 3, "state_weight": [1.0], "input_weight": [2.0]}}
    >>> s = system_from_dict(data)
    >>> (s.n, s.m, s.horizon, s.mu_schedule[:, 0].tolist())
    (1, 1, 3, [0.5, 0.5, 0.5])
    >>> system_from_dict({**data, "cost": {**data["cost"], "state_weight": [-1.0]}})
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: cost.state_weight: expected a non-negative diagonal (positive semidefinite weight)
    """
    if not isinstance(data, Mapping):
        raise InputError("<file>", "expected a table")
    for key in data:
        if key != "name" and key not in _SCHEMA and key not in OTHER_SECTIONS:
            raise InputError(str(key),
                             f"unknown section; expected one of name, {', '.join([*_SCHEMA, *OTHER_SECTIONS])}")
    kwargs: dict[str, Any] = {"name": data.get("name")}
    where: dict[str, str] = {"name": "name"}
    for section, keys in _SCHEMA.items():
        if section not in data:
            if section in _OPTIONAL_SECTIONS:
                continue
            raise InputError(section, "missing section")
        table = data[section]
        if not isinstance(table, Mapping):
            raise InputError(section, "expected a table")
        for key in table:
            if key not in keys:
                raise InputError(f"{section}.{key}", f"unknown key; expected one of {', '.join(keys)}")
        for key in _REQUIRED[section]:
            if key not in table:
                raise InputError(f"{section}.{key}", "missing field")
        for key, kw in keys.items():
            if key in table:
                kwargs[kw] = table[key]
                where[kw] = f"{section}.{key}"
    sensor = {kw.removeprefix("sensor."): kwargs.pop(kw) for kw in list(kwargs) if kw.startswith("sensor.")}
    if sensor or "sensor" in data:
        if "sensor" not in data:
            raise InputError("state.P0", "the initial state's covariance needs a [sensor] section (without one the "
                                         "state is measured exactly)")
        kwargs["sensor"] = sensor
    markov = {kw.removeprefix("channel."): kwargs.pop(kw) for kw in list(kwargs) if kw.startswith("channel.")}
    if markov:
        kwargs["channel"] = markov
        where.update({"channel": "channel", **{kw: kw for kw in _SCHEMA["channel"].values() if "." in kw}})
    try:
        return System(**kwargs)
    except InputError as err:
        raise err.renamed(_toml_field(err.field, where)) from None


def _toml_field(field: str, where: Mapping[str, str]) -> str:
    if field.split(".")[0] in _OPTIONAL_SECTIONS or field == "state.P0":   # already a TOML path (sensor.py)
        return field
    if "/" in field:  # a paired key
        first, second = field.split("/", 1)
        if "." in first:   # already named by its table (channel.state/belief)
            return field
        section = where.get(first, where.get(second, "")).split(".")[0] or _section_of(first)
        return f"{section}.{first}/{second}"
    base, bracket, rest = field.partition("[")
    return where.get(base, f"{_section_of(base)}.{base}") + bracket + rest


def _section_of(kw: str) -> str:
    for section, keys in _SCHEMA.items():
        if kw in keys.values():
            return section
    return kw


#: A system file is a few kilobytes; anything larger is refused before parsing (the default of the
#: ``file_bytes`` budget, which applies to every input file: budgets.py).
MAX_FILE_BYTES = int(BUDGETS["file_bytes"].default)


@dataclass(frozen=True)
class CsvRows:
    """The rows of numbers of a CSV file (`read_csv_rows`) and the file line each starts on (1-based, as an
    editor numbers lines: comments, blank lines and a header counted), for errors found after reading.

    Examples
    --------
    >>> CsvRows([[0.5], [1.0]], (3, 4)).where(1)
    'line 4'
    """

    rows: list[list[float]]
    lines: tuple[int, ...]

    def where(self, k: int) -> str:
        """How an error names row ``k`` (0-based among the rows of numbers): ``"line L"``, L the file's line."""
        return f"line {self.lines[k]}"


def read_csv_numbers(path: str | Path, field: str, row_budget: str | None = None,
                     width: int | None = None) -> list[list[float]]:
    """The rows of numbers of a CSV input file (``--mu-schedule``, ``--mu-list``): `read_csv_rows`'s rows.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / "mu.csv").write_text("\\ufeffmu1,mu2\\n# a comment\\n0.5,1\\n\\n0,0.25\\n")
    ...     read_csv_numbers(Path(tmp) / "mu.csv", "--mu-list")
    [[0.5, 1.0], [0.0, 0.25]]
    """
    return read_csv_rows(path, field, row_budget, width).rows


def read_csv_rows(path: str | Path, field: str, row_budget: str | None = None, width: int | None = None) -> CsvRows:
    """The rows of numbers of a CSV input file and their file lines, one reader with one set of rules: read as
    every input file is (`read_input`); UTF-8 with or without Excel's byte-order mark; blank lines and lines
    starting with ``#`` skipped; a first row whose cells are all non-numeric (a header such as ``mu1,mu2``)
    skipped, while a first row with a typo among numbers is an error; every value finite; every row ``width``
    numbers long (default: as long as the first row of numbers). ``row_budget``: a budget (budgets.py) the rows
    are counted against as they are parsed. Every error about a row names its file line (``"line 6: ..."``), as
    `CsvRows.where` does for a caller's checks after reading. O(size).

    Raises
    ------
    InputError
        Field ``field``: not a CSV text file, a cell that is not a number (with its line), a value that is not
        finite, or no row of numbers.
    BudgetError
        A file beyond the ``file_bytes`` budget, or more rows than ``row_budget``.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / "mu.csv").write_text("mu1,mu2\\n# a comment\\n0.5,1\\n\\n0,x\\n")
    ...     read_csv_rows(Path(tmp) / "mu.csv", "--mu-list")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: --mu-list: line 5: expected numbers, found '0,x'
    """
    data = read_input(path, field)
    rows: list[tuple[int, list[str]]] = []
    try:
        text = data.decode("utf-8-sig")                  # -sig: Excel's byte-order mark
        reader = csv.reader(io.StringIO(text, newline=""))
        start = 1
        for row in reader:
            line, start = start, reader.line_num + 1     # a quoted cell may span lines: a row starts where it starts
            if not row or not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
                continue
            rows.append((line, row))
            if row_budget is not None and len(rows) > 1:   # counted as parsed: 16 MiB of "0,0" are 4e6 lists
                check(row_budget, len(rows) - 1, field, f"more than {len(rows) - 2} rows")
    except (UnicodeDecodeError, csv.Error) as err:
        raise InputError(field, f"{str(path)!r} is not a CSV text file: {err}") from None
    numbers, lines = [], []
    for k, (line, row) in enumerate(rows):
        try:
            values = [float(cell) for cell in row]
        except ValueError:
            if k == 0 and not any(_is_number(cell) for cell in row):
                continue          # a header; a first row with a typo among numbers is an error, not a header
            raise InputError(field, f"line {line}: expected numbers, found {','.join(row)[:60]!r}") from None
        if not all(map(math.isfinite, values)):
            raise InputError(field, f"line {line}: expected finite numbers, found {','.join(row)[:60]!r}")
        width = len(values) if width is None else width
        if len(values) != width:
            raise InputError(field, f"line {line}: expected {width} numbers, found {len(values)}")
        numbers.append(values)
        lines.append(line)
    if not numbers:
        raise InputError(field, f"{str(path)!r} has no rows of numbers (comma-separated, one row per line)")
    return CsvRows(numbers, tuple(lines))


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def read_input(path: str | Path, field: str) -> bytes:
    """The bytes of an input file (a system file, a CSV of channels), refused before they are read when the
    file is not a regular file (a FIFO or a device would block or never end: it is opened without blocking
    and checked with ``fstat``) or larger than the ``file_bytes`` budget (a bounded read: ``st_size`` is
    0 for devices). O(size), at most the budget.

    Raises
    ------
    InputError
        A missing, unreadable or irregular file, or a name the system refuses (too long), named ``field``.
    BudgetError
        A file larger than the budget.

    Examples
    --------
    >>> read_input("/dev/zero", "--mu-list")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --mu-list: /dev/zero is not a regular file (a device, a pipe or a socket)
    """
    text = str(path)
    if "\x00" in text:
        raise InputError(field, "expected a file path, found a path with a NUL character")
    try:
        fd = os.open(text, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as err:
        raise InputError(field, f"cannot read {_shown(text)}: {_reason(err)}") from None
    info = os.fstat(fd)
    problem = ("is a directory, not a file" if stat.S_ISDIR(info.st_mode) else
               "is not a regular file (a device, a pipe or a socket)" if not stat.S_ISREG(info.st_mode) else "")
    if problem:
        os.close(fd)
        raise InputError(field, f"{_shown(text)} {problem}")
    with os.fdopen(fd, "rb") as handle:
        check("file_bytes", info.st_size, field, f"{_shown(text)} ({info.st_size} bytes)")
        blocks, size = [], 0
        while block := handle.read(1 << 20):       # in blocks: a file that grows as it is read stays bounded
            blocks.append(block)
            size += len(block)
            check("file_bytes", size, field, f"{_shown(text)} (more than {size - len(block)} bytes)")
    return b"".join(blocks)


def _shown(path: str) -> str:
    """A path as an error line shows it: at most 200 characters (a 100,000-character name is not echoed)."""
    return path if len(path) <= 200 else f"{path[:100]}...({len(path)} characters)"


def _reason(err: OSError) -> str:
    if err.errno == errno.ENAMETOOLONG:
        return "file name too long"
    return err.strerror or str(err)


def example_names() -> list[str]:
    """Names of the example systems shipped with the package (``load_example`` takes them).

    Examples
    --------
    >>> {"pendulum", "two_actuator"} <= set(example_names())
    True
    """
    return packaged_names()


def load_example(name: str) -> System:
    """The example system ``name`` shipped with the package: ``"pendulum"`` (paper §V-A,
    eq:pendulum-ss) or ``"two_actuator"`` (§V-B, eq:mixed-ss). A hyphen may stand for the underscore.

    Examples
    --------
    >>> load_example("pendulum").n
    4
    """
    key = str(name).replace("-", "_")
    if key not in example_names():
        raise InputError("example", f"unknown example {name!r}; expected one of {', '.join(example_names())}")
    resource = resources.files(__package__) / "examples" / f"{key}.toml"
    return _parse(resource.read_bytes(), f"example {key}")


def load_system(path: str | Path) -> System:
    """Read a system file in the TOML schema of docs/design.md §4, or a packaged example.

    ``path`` is a file path; a bare example name (``"pendulum"``, ``"two_actuator"``) that is
    not an existing file loads the example shipped with the package
    ([`load_example`][packetloss_cvx.model.files.load_example]).

    Raises
    ------
    InputError
        Missing or unreadable file (field ``file``), invalid TOML, or any field
        that fails validation (named by its TOML path).

    Examples
    --------
    >>> s = load_system("two_actuator")          # not a file here: the packaged example (paper §V-B)
    >>> s.B.tolist(), s.mu_schedule[0].tolist()
    ([[1.0, 0.0], [0.0, 1.0]], [0.9, 0.5])
    """
    text = str(path)
    if "\x00" in text:
        raise InputError("file", "expected a file path, found a path with a NUL character")
    file = Path(text)
    try:
        exists = file.exists()
    except OSError as err:         # a name longer than the system allows: not a file, and not an example
        raise InputError("file", f"cannot read {_shown(text)}: {_reason(err)}") from None
    if not exists and file.suffix == "" and file.name == text and text.replace("-", "_") in example_names():
        return load_example(text)
    if not exists:
        hint = f" (or an example name: {', '.join(example_names())})" if file.suffix == "" else ""
        raise InputError("file", f"no such file: {_shown(text)}{hint}")
    data = read_input(file, "file")
    return _parse(data, str(file))


def load_table(path: str | Path) -> dict[str, Any]:
    """The TOML tables of a system file (or a packaged example) as read, unchecked: for the sections a
    System does not hold (``OTHER_SECTIONS``). Read under `read_input`'s rules. O(size).

    Examples
    --------
    >>> sorted(load_table("two_actuator"))
    ['channel', 'cost', 'name', 'plant', 'state']
    """
    text = str(path)
    file = Path(text)
    if "\x00" not in text and not file.exists() and file.suffix == "" and text.replace("-", "_") in example_names():
        key = text.replace("-", "_")
        return _toml((resources.files(__package__) / "examples" / f"{key}.toml").read_bytes(), f"example {key}")
    return _toml(read_input(file, "file"), text)


def load_constraints(path: str | Path, system: System | None = None) -> Constraints | None:
    """The ``[constraints]`` table of a system file (docs/design.md §4) checked against its system (``system``, or
    the file's own), or None when the file has none. Errors name ``constraints.<key>``. O(size).

    Examples
    --------
    >>> import tempfile
    >>> s = load_example("two_actuator")
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = save_system(s, Path(tmp) / "plant.toml", constraints=Constraints(u_min=[-1, -1], u_max=[1, 1]))
    ...     c = load_constraints(path)
    >>> c.u_max.tolist(), load_constraints("two_actuator") is None
    ([1.0, 1.0], True)
    """
    table = load_table(path).get("constraints")
    if table is None:
        return None
    system = load_system(path) if system is None else system
    return constraints_from_dict(table, system.n, system.m)


def _parse(data: bytes, where: str) -> System:
    return system_from_dict(_toml(data, where))


def _toml(data: bytes, where: str) -> dict[str, Any]:
    try:
        text = data.decode("utf-8-sig")   # a byte-order mark is tolerated
    except UnicodeDecodeError as err:
        raise InputError("file", f"{where} is not UTF-8 text: {err}") from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise InputError("file", f"{where} is not valid TOML: {err}") from None
    except ValueError as err:   # an integer of more than 4300 digits (Python's int-from-text limit)
        raise InputError("file", f"{where} holds a number tomllib cannot read ({str(err).split(':')[0]}); "
                                 "a system file's numbers are within the double range") from None
    except RecursionError:
        raise InputError("file", f"{where} nests arrays too deeply (a system file needs at most 3 levels)") from None
    return table


def dumps_system(system: System, constraints: Constraints | None = None) -> str:
    """The system as TOML text in the schema of docs/design.md §4 (``load_system`` reads it back).

    Examples
    --------
    >>> import numpy as np
    >>> s = load_example("pendulum")
    >>> again = system_from_dict(tomllib.loads(dumps_system(s)))      # the text reads back to the same system
    >>> all(np.array_equal(getattr(again, k), getattr(s, k)) for k in ("A", "B", "x0", "mu_schedule"))
    True
    """
    data = system.to_dict()
    if constraints is not None:      # the [constraints] table (model/constraints.py), checked against the system
        data["constraints"] = check_constraints(constraints, system.n, system.m).to_dict()
    lines = [f"name = {_toml_value(data.pop('name'))}", ""] if "name" in data else []
    for section, table in data.items():
        lines.append(f"[{section}]")
        lines += [f"{key} = {_toml_value(value)}" for key, value in table.items()]
        lines.append("")
    return "\n".join(lines)


def save_system(system: System, path: str | Path, *, overwrite: bool = False,
                constraints: Constraints | None = None) -> Path:
    """Write ``system`` to ``path`` as TOML, atomically (`atomic_write`);
    returns the path. An existing file is refused ([`OutputExistsError`][packetloss_cvx.errors.OutputExistsError], a
    ValueError) unless ``overwrite=True`` (a user's file is never replaced silently).

    Examples
    --------
    >>> import tempfile
    >>> s = load_example("two_actuator")
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = save_system(s, Path(tmp) / "plant.toml")
    ...     again = load_system(path)
    >>> path.name, dumps_system(again) == dumps_system(s)
    ('plant.toml', True)
    """
    if not isinstance(system, System):
        raise InputError("system", f"expected a System, found {type(system).__name__}")
    with atomic_write(path, overwrite=overwrite, text=True, field="path") as handle:   # the path as given ('dir/')
        handle.write(dumps_system(system, constraints))
    return Path(path)


def _toml_value(value: Any) -> str:
    # Kept rather than tomli-w (tomli-w 1.2.0): tomli-w writes every array one element
    # per line, so the two-actuator file's 2 x 2 A takes 10 lines and the pendulum's 4 x 4 A 26, where a
    # system file shows a matrix on one line; a System holds only finite floats, ints, bools, strings and
    # (nested) lists of them, which these nine lines write in TOML exactly (floats by their shortest repr).
    if isinstance(value, str):   # a JSON string is a TOML basic string once DEL is escaped and characters
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")   # beyond U+FFFF stay raw
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):          # shortest round-trip repr; finite in a System, +-inf in [constraints]
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    return "[" + ", ".join(_toml_value(item) for item in value) + "]"
