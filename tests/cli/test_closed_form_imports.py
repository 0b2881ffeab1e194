"""The closed-form paths load no solver: ``solve --no-qp``, ``simulate``, ``sweep`` and the audit's
claims that need no QP import no cvxpy (1.5 s of a 1.9 s ``solve --no-qp`` before it was lazy), and no
command that draws no figure imports matplotlib. Each command runs in an interpreter of its own, forked from one
that imported only ``packetloss_cvx.cli`` (what the probe's first line imports) and NumPy (which every command here
imports to load its system), plus, for the commands allowed SciPy and those that must import cvxpy, the SciPy
modules they use (what the probe does not examine there) and the command modules (the package's own code, whose
top-level imports the parent's assertion covers). Each parent's modules are asserted free of what its
children are probed for. The probe reports the heavy top-level packages found in ``sys.modules`` at exit. The
commands that do solve a QP are run too: the probe must see cvxpy there, or it could not fail.
"""

import ast

import pytest

from ..processes import Zygote

#: the top-level packages the probe reports
PROBED = {"cvxpy", "matplotlib", "dask", "xarray", "control", "scipy"}
PROBE = """
import sys
from packetloss_cvx.cli import main
code = main(sys.argv[1:])
heavy = {m.split(".")[0] for m in sys.modules} & {"cvxpy", "matplotlib", "dask", "xarray", "control", "scipy"}
print("PROBE", code, sorted(heavy))
"""


@pytest.fixture(scope="module")
def numpy_parent():
    """The parent of the probes allowed nothing: packetloss_cvx.cli and NumPy imported, none of PROBED."""
    with Zygote(["packetloss_cvx.cli", "numpy"]) as parent:
        assert {"numpy", "packetloss_cvx"} <= parent.modules
        assert not parent.modules & PROBED, sorted(parent.modules & PROBED)
        yield parent


#: the SciPy modules the commands allowed SciPy import (a run of each, listed from sys.modules)
SCIPY_USED = ["scipy.linalg", "scipy.optimize", "scipy.sparse", "scipy.spatial", "scipy.special"]


#: the command modules of the probes forked from scipy_parent (the package's own code, imported once there, not once
#: per probe; 0.19 s): a heavy import at the top of one of them, or of what it imports, is in that parent's modules,
#: which the fixture asserts free of PROBED but SciPy; one inside a function the command runs lands in the probe
COMMANDS_USED = ["packetloss_cvx.cli.solve", "packetloss_cvx.cli.simulate", "packetloss_cvx.cli.sweep",
                 "packetloss_cvx.cli.region", "packetloss_cvx.cli.audit"]


@pytest.fixture(scope="module")
def scipy_parent():
    """The parent of the probes allowed SciPy or required to import cvxpy: SciPy and the command modules too, none
    of the rest of PROBED."""
    with Zygote(["packetloss_cvx.cli", "numpy", *SCIPY_USED, *COMMANDS_USED]) as parent:
        assert "scipy" in parent.modules
        assert not parent.modules & (PROBED - {"scipy"}), sorted(parent.modules & PROBED)
        yield parent


def heavy_modules(zygote, *argv: str) -> set[str]:
    proc = zygote.run(list(argv), code=PROBE)
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("PROBE")]
    assert line, proc.stderr[-2000:]
    code, _, modules = line[-1].removeprefix("PROBE ").partition(" ")
    assert code == "0", proc.stderr[-2000:]
    return set(ast.literal_eval(modules))


#: solve --no-qp runs its closed forms, self-checks and small-plant stability verdicts on numpy.linalg: SciPy's
#: import (about 0.15 s, its array-API layer loading numpy.f2py) would be most of its start-up (the target: within
#: 4x of a bare numpy import); the other commands use SciPy's LU, LAPACK or ARPACK and may import it
@pytest.mark.parametrize(("argv", "allowed"), [
    (["solve", "two_actuator", "--no-qp", "-q"], set()),
    # the Gilbert-Elliott section too; its exact O(N) recursion solves one small system a step through LAPACK's
    # dgesv (linalg.lapack_dgesv: 1.2 us against 4.8 us a step through np.linalg.solve), so SciPy, never cvxpy
    (["solve", "pendulum_bursty", "--no-qp", "-q"], {"scipy"}),
    (["simulate", "two_actuator", "--samples", "50", "--closed-loop", "-q"], {"scipy"}),
    (["sweep", "two_actuator", "--mu-grid", "3", "--json", "-q"], {"scipy"}),
    (["region", "two_actuator", "--law", "all", "--json", "-q"], {"scipy"}),   # the Riccati forms decide every point
    (["audit", "--random", "1", "--claim", "theorem-2", "--claim", "lemma-1", "--claim", "table-1", "-q"], {"scipy"}),
])
def test_closed_form_commands_import_no_cvxpy_and_no_matplotlib(request, argv, allowed):
    parent = request.getfixturevalue("scipy_parent" if "scipy" in allowed else "numpy_parent")
    assert heavy_modules(parent, *argv) <= allowed


@pytest.mark.parametrize("argv", [["solve", "two_actuator", "--protocol", "tcp", "-q"],
                                  ["audit", "--random", "0", "--claim", "theorem-1-costs", "-q"]])
def test_commands_that_solve_a_qp_do_import_cvxpy(scipy_parent, argv):
    assert "cvxpy" in heavy_modules(scipy_parent, *argv)
