"""Every public function has a docstring with an example that runs as a doctest.

A public function is one named in its module's ``__all__`` and defined there (re-exports are counted
where they are defined); a public class needs an example on itself or on one of its methods. The
examples run under ``pytest --doctest-modules`` (pyproject's addopts); this file checks that they
exist, for the modules in ``COVERED`` (all of theirs have one now: keep it so), and reports the rest
of the package: ``python tests/docs/test_doctest_coverage.py`` prints, per module, the public functions
without an example and the totals.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import sys
import types

import pytest

import packetloss_cvx

#: modules (under packetloss_cvx) whose every public function and class has a ``>>>`` example
COVERED = (
    "allocation.api", "allocation.boxes", "allocation.brute_force", "allocation.grammar", "allocation.tcp",
    "allocation.udp", "claims.channel_allocation", "claims.closed_loop", "claims.context", "claims.cost_difference",
    "claims.evaluate", "claims.markov", "claims.mpc_vs_dp", "claims.ordering", "claims.registry", "claims.report",
    "claims.tables", "claims.theorem1", "cli.allocate", "cli.audit", "cli.common", "cli.completion", "cli.format",
    "cli.markov_section", "cli.parser", "cli.reproduce", "cli.simulate", "cli.solve", "cli.sweep",
    "closedloop.certificates", "closedloop.critical", "closedloop.interop", "closedloop.mjls", "closedloop.moments",
    "closedloop.region", "closedloop.region_lmi", "closedloop.riccati", "closedloop.stability", "display", "linalg",
    "lq.analysis", "lq.costs", "lq.difference", "lq.markov_cost", "lq.prediction", "lq.recursion", "lq.roundoff",
    "model.chain", "model.channel", "model.files", "model.protocols", "model.random_systems", "model.system",
    "model.twins", "model.validation", "montecarlo.channels", "montecarlo.markov", "montecarlo.markov_channels",
    "montecarlo.markov_loop", "montecarlo.runs", "montecarlo.sampling", "montecarlo.simulate", "optional",
    "plots.figures", "progress", "qp.convex", "qp.expected_cost", "qp.markov", "qp.markov_solution", "qp.shared",
    "results.base", "runfolder", "safeio", "studies.allocation", "studies.burstiness", "studies.design",
    "studies.output", "studies.paper_figures", "studies.region_map", "studies.sweeps", "threads",
)


def has_example(obj: object) -> bool:
    return ">>>" in (inspect.getdoc(obj) or "")


def public_objects(module: types.ModuleType) -> list[tuple[str, object]]:
    """The functions and classes named in ``module.__all__`` and defined in ``module``."""
    out = []
    for name in getattr(module, "__all__", ()):
        obj = getattr(module, name, None)
        if (inspect.isfunction(obj) or inspect.isclass(obj)) and obj.__module__ == module.__name__:
            out.append((name, obj))
    return out


def missing_examples(module: types.ModuleType) -> list[str]:
    """Public functions without an example, and public classes with none on the class or any of its methods."""
    missing = []
    for name, obj in public_objects(module):
        if inspect.isfunction(obj):
            if not has_example(obj):
                missing.append(name)
        elif not has_example(obj) and not any(has_example(getattr(v, "__func__", v)) for v in vars(obj).values()):
            missing.append(name)
    return missing


def package_modules() -> list[types.ModuleType]:
    modules = []
    for info in pkgutil.walk_packages(packetloss_cvx.__path__, "packetloss_cvx."):
        if not info.name.endswith("__main__"):
            modules.append(importlib.import_module(info.name))
    return modules


@pytest.mark.parametrize("name", COVERED)
def test_every_public_function_of_a_covered_module_has_an_example(name):
    module = importlib.import_module(f"packetloss_cvx.{name}")
    assert public_objects(module), f"{name}: no public function or class found (is __all__ set?)"
    assert missing_examples(module) == [], f"{name}: public functions without a >>> example"


def test_the_scan_finds_a_missing_example():
    """Not vacuous: a function and a class without examples are reported; a class with one on a method is not."""
    module = types.ModuleType("fake")

    def documented():
        """>>> 1 + 1
        2"""

    def bare():
        """No example."""

    class Shown:
        """No example here."""

        @classmethod
        def build(cls):
            """>>> Shown.build()"""

    class Hidden:
        """No example."""

        def method(self):
            """Nowhere either."""

    for obj in (documented, bare, Shown, Hidden):
        obj.__module__ = "fake"
        setattr(module, obj.__name__, obj)
    module.__all__ = ["documented", "bare", "Shown", "Hidden"]
    assert missing_examples(module) == ["bare", "Hidden"]


def report() -> tuple[int, int, list[str]]:
    """(with, without, lines): the package-wide count of public functions with and without an example."""
    with_example, without, lines = 0, 0, []
    for module in package_modules():
        functions = [(n, f) for n, f in public_objects(module) if inspect.isfunction(f)]
        if not functions:
            continue
        missing = [n for n, f in functions if not has_example(f)]
        with_example += len(functions) - len(missing)
        without += len(missing)
        if missing:
            lines.append(f"{module.__name__}: {len(missing)} of {len(functions)} without: {' '.join(missing)}")
    return with_example, without, lines


if __name__ == "__main__":
    done, todo, rows = report()
    print("\n".join(rows))
    print(f"public functions: {done} with an example, {todo} without ({done + todo} in all)")
    sys.exit(0)
