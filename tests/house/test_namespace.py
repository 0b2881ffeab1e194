"""The package's public namespace: ``__all__``, ``dir()`` and the lazily imported names agree."""

import subprocess
import sys

import packetloss_cvx as pl
from packetloss_cvx import errors

HELPERS = {"Any", "TYPE_CHECKING", "annotations", "importlib", "typing", "LAZY"}


def test_dir_shows_the_public_names_and_no_helper():
    names = dir(pl)
    assert not HELPERS & set(names), HELPERS & set(names)
    assert not [n for n in names if n.startswith("_") and n != "__version__"]
    assert set(names) == {*pl.__all__, "__version__"}
    assert names == sorted(names)


def test_every_name_in_all_resolves_and_is_defined_where_documented():
    for name in pl.__all__:
        value = getattr(pl, name)
        # the object itself, not a re-export shim: defined in a module of this package
        assert value.__module__.startswith("packetloss_cvx."), (name, value.__module__)
    for name in ("InputError", "NumericalError", "CrossCheckError", "SolverError"):
        assert getattr(pl, name) is getattr(errors, name)
    assert len(set(pl.__all__)) == len(pl.__all__)


def test_star_import_gives_exactly_all():
    space: dict = {}
    exec("from packetloss_cvx import *", space)
    assert set(space) - {"__builtins__"} == set(pl.__all__)


def test_unknown_name_is_an_attribute_error():
    try:
        pl.not_a_name  # noqa: B018
    except AttributeError as err:
        assert "not_a_name" in str(err)
    else:
        raise AssertionError("an unknown name must raise AttributeError")


def test_dir_in_a_fresh_interpreter_before_any_name_is_used():
    # nothing loaded yet: dir() still lists the lazily imported names, and listing them imports nothing heavy
    code = ("import sys, packetloss_cvx as pl; names = dir(pl); "
            "print(len(names), 'System' in names, 'cvxpy' in sys.modules, 'scipy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == [str(len(pl.__all__) + 1), "True", "False", "False"]
