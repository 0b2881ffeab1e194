"""The house rules, checked by reading the modules' imports (as cvxpylayers and cvxrisk keep one):

* data flows one way through the layers below: a module imports only from its own layer or
  lower ones, and the module graph has no cycle;
* no private name (``_x``) is imported from another module of the package;
* no import inside a function, except lazy imports of the heavy optional libraries that
  ``packetloss_cvx.optional.LAZY_IMPORTS`` lists (the package's one list; the CLI's import budget
  in test_cli_native.py reads it too).

Size is not a rule: a module is cut at its seams, not at a line count. Files over about 600 lines are
listed for review at the end of a verbose test run (``long_files``, printed by tests/conftest.py with ``-v``), never a
failure.
"""

import ast
import functools
import re
import tomllib
from pathlib import Path

import pytest

from packetloss_cvx.optional import EXTRAS, LAZY_IMPORTS, LAZY_MODULES

from ..conftest import LONG_FILE_LINES, long_files

PACKAGE = Path(__file__).resolve().parents[2] / "packetloss_cvx"

#: the folders, bottom up: each imports only from its own folder, the infrastructure (layer 0) and the folders
#: below it, so there is no loop between folders; plots and the command line are the top
LAYERS = [
    {"errors", "tolerances", "budgets", "printable", "optional", "threads", "progress", "safeio", "runfolder",
     "linalg", "display", "results"},
    {"model"},
    {"lq"},
    {"qp"},
    {"closedloop"},
    {"montecarlo"},
    {"sensing"},
    {"allocation"},
    {"studies"},
    {"claims"},
    {"plots", "cli", "__main__", "__init__"},
]
#: lazy imports allowed inside functions: the heavy optional libraries, listed once in the package
LAZY_OK = frozenset(LAZY_IMPORTS)


def _modules() -> dict[str, Path]:
    return {".".join(p.relative_to(PACKAGE).with_suffix("").parts): p for p in PACKAGE.rglob("*.py")}


def _unit(dotted: str) -> str:
    """The layer unit of a module: its top-level module or subpackage (``allocation.udp`` -> ``allocation``)."""
    return dotted.split(".")[0]


def _layer(unit: str) -> int:
    for k, names in enumerate(LAYERS):
        if unit in names:
            return k
    raise AssertionError(f"module {unit!r} is in no layer: add it to LAYERS and to docs/design.md")


def _resolve(module: str, node: ast.ImportFrom) -> str | None:
    """The dotted name (inside the package) that ``from ... import`` refers to, or None if external."""
    if node.level == 0:
        if node.module and node.module.split(".")[0] == "packetloss_cvx":
            return node.module.partition(".")[2] or "__init__"
        return None
    parts = module.split(".")
    is_package = (PACKAGE / Path(*parts) / "__init__.py").exists() or parts[-1] == "__init__"
    base = parts if is_package and parts[-1] != "__init__" else parts[:-1]
    base = base[: len(base) - (node.level - 1)]
    target = ".".join(base + ([node.module] if node.module else []))
    return target or "__init__"


@functools.cache
def _tree(path: Path) -> ast.Module:
    """The module's syntax tree, parsed once for the four tests that read it (they only read it)."""
    return ast.parse(path.read_text())


def _imports(module: str, path: Path):
    return _import_list(module, path)


@functools.cache
def _import_list(module: str, path: Path) -> tuple:
    """Every import of ``module`` as (node, target inside the package or None), found once per module."""
    return tuple(_find_imports(module, _tree(path)))


def _find_imports(module: str, tree: ast.Module):
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            target = _resolve(module, node)
            if target is not None and node.module is None:   # from . import analysis: the module itself
                prefix = "" if target == "__init__" else target + "."
                for alias in node.names:
                    yield node, prefix + alias.name if prefix + alias.name in MODULES else target
                continue
            yield node, target
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "packetloss_cvx":
                    yield node, alias.name.partition(".")[2] or "__init__"
                else:
                    yield node, None


MODULES = _modules()


#: the one upward reach: a result draws itself (``.plot()``) through plots/, imported inside the method when it is
#: called, as pandas' ``DataFrame.plot`` reaches its plotting backend; plots/ reads results by their attributes and
#: never imports them, so the graph keeps no cycle
DRAWS_ITSELF = ("results", "plots")


def _in_functions(tree: ast.Module) -> set[int]:
    """ids of the import nodes inside a function of the module."""
    return {id(node) for fn in ast.walk(tree) if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
            for node in ast.walk(fn) if isinstance(node, (ast.Import, ast.ImportFrom))}


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_flow_one_way(module):
    mine = _layer(_unit(module))
    lazy = _in_functions(_tree(MODULES[module]))
    for node, target in _imports(module, MODULES[module]):
        if target is None or _unit(target) == _unit(module):
            continue
        if (_unit(module), _unit(target)) == DRAWS_ITSELF and id(node) in lazy:
            continue
        theirs = _layer(_unit(target))
        assert theirs <= mine, f"{module} (layer {mine}) imports {target} (layer {theirs})"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_private_name_crosses_a_module(module):
    for node, target in _imports(module, MODULES[module]):
        if target is None or not isinstance(node, ast.ImportFrom) or target == module:
            continue
        private = [a.name for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
        assert not private, f"{module} imports private {private} from {target}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_function_level_imports(module):
    tree = _tree(MODULES[module])
    for fn in ast.walk(tree):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            if isinstance(node, ast.Import):
                names = [a.name.split(".")[0] for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level and _resolve(module, node) in LAZY_MODULES:
                continue
            elif isinstance(node, ast.ImportFrom):
                names = [(node.module or "").split(".")[0]] if node.level == 0 else ["packetloss_cvx"]
            else:
                continue
            assert set(names) <= LAZY_OK, f"{module}.{fn.name} imports {names} inside the function"


def test_module_graph_has_no_cycle():
    graph = {m: {t for _, t in _imports(m, p) if t is not None and t in MODULES and t != m} for m, p in MODULES.items()}
    graph = {m: {t for t in ts if not (m.endswith("__init__") and t.startswith(m.rsplit(".", 1)[0]))}
             for m, ts in graph.items()}
    state: dict[str, int] = {}

    def visit(m, path):
        state[m] = 1
        for t in graph[m]:
            assert state.get(t) != 1, f"import cycle: {' -> '.join([*path, m, t])}"
            if t not in state:
                visit(t, [*path, m])
        state[m] = 2

    for m in graph:
        if m not in state:
            visit(m, [])


def test_long_files_are_listed_for_review_not_failed(tmp_path):
    """The size report lists every Python file over LONG_FILE_LINES lines, longest first, and nothing else."""
    (tmp_path / "pkg").mkdir()
    for name, lines in (("pkg/at_limit.py", LONG_FILE_LINES), ("pkg/long.py", LONG_FILE_LINES + 1),
                        ("longer.py", 2 * LONG_FILE_LINES), ("notes.txt", 5 * LONG_FILE_LINES)):
        (tmp_path / name).write_text("x = 1\n" * lines)
    assert long_files(tmp_path, ("pkg", ".")) == [("longer.py", 2 * LONG_FILE_LINES),
                                                   ("pkg/long.py", LONG_FILE_LINES + 1)]


def test_every_lazy_library_is_installed_by_a_dependency_or_an_extra():
    """optional.LAZY_IMPORTS and pyproject.toml agree: each lazily imported library is a required dependency
    or belongs to the extra that optional.EXTRAS names (which is what load's error tells the user to install)."""
    project = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["project"]

    def names(specs):
        """Distribution names a requirement list installs: 'dask[distributed]>=2024.1' -> dask, distributed."""
        found = set()
        for spec in specs:
            name, _, extras = re.split(r"[<>=!~ ;]", spec, maxsplit=1)[0].partition("[")
            found |= {name} | {e.strip() for e in extras.rstrip("]").split(",") if e.strip()}
        return found

    required = names(project["dependencies"])
    for library in LAZY_IMPORTS:
        if library in EXTRAS:
            assert library in names(project["optional-dependencies"][EXTRAS[library]]), library
            assert library not in required, library
        else:
            assert library in required, library
