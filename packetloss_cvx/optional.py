"""The heavy optional libraries: the one list of what a function may import lazily, and `load`.

Every module imports its dependencies at the top, except these: libraries that are an optional extra
(absent after a plain ``pip install packetloss-cvx``) or slow to import and needed on few paths. A
function that needs one imports it when called, so that importing the package, ``--help``, usage errors
and refusing bad input stay fast, and the closed-form paths never pay for a solver they do not use.

Three readers share this list, which is why it lives in the package (the bottom layer, beside
``errors``) and not in a test: ``tests/house/test_architecture.py`` allows exactly these names inside
functions, ``tests/cli/test_cli_native.py`` checks that ``--help``, usage errors and bad input import none
of them, and `load` imports one for the package, turning a missing extra into an
[`InputError`][packetloss_cvx.errors.InputError] that says how to install it (never a bare traceback).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from types import MappingProxyType, ModuleType

from .errors import InputError

__all__ = ["EXTRAS", "LAZY_IMPORTS", "LAZY_MODULES", "load"]

#: library (top-level import name) -> why it is imported inside the functions that need it
LAZY_IMPORTS: Mapping[str, str] = MappingProxyType({
    "cvxpy": "the QP twins and the TCP-like allocation only: closed-form paths never import it (1.5 s)",
    "matplotlib": "figures only (plots.py, --plot): slow to import",
    "tqdm": "progress bars only, when stderr is a terminal",
    "shtab": "shell completion only (--completion): 0.12 s to import",
    "dask": "the 'distributed' extra: sweeps as Dask tasks",
    "distributed": "the 'distributed' extra: sweeps on a Dask cluster",
    "xarray": "the 'xarray' extra: sweep results as Datasets and NetCDF files",
    "control": "the 'control' extra: python-control interop (StateSpace in and out)",
    "pandas": "the 'xarray' extra (it installs pandas): results as tidy DataFrames (to_pandas)",
    "scipy": "ARPACK, GMRES, LU and the complex Schur form only where used (large n, the pointwise and QP "
             "paths, the error bound of a plan rolled out on a plant that rotates): importing any of "
             "SciPy costs about 0.15 s (its array-API layer clones NumPy's namespace, loading numpy.f2py and "
             "numpy.testing), so the closed-form paths (numpy.linalg) never import it",
})

#: the package's own modules that load one of those libraries at import time (dotted under the package) ->
#: why a caller imports it inside the function that needs it: so that its caller's other paths never load
#: cvxpy or matplotlib (tests/cli/test_closed_form_imports.py runs those paths and checks sys.modules)
LAZY_MODULES: Mapping[str, str] = MappingProxyType({
    "qp.expected_cost": "the QP twin (cvxpy): solve without --no-qp, the audit's QP claims",
    "qp.markov": "the Markov-chain QP twin (cvxpy)",
    "qp.constrained": "the constrained expected-cost QP (cvxpy): solve only for a file with a [constraints] table",
    "closedloop.region_lmi": "the stabilisable set's LMI form (cvxpy): only where asked or where the Riccati forms "
                             "cannot decide",
    "allocation.brute_force": "the brute-force allocation reference, through the allocation package (cvxpy)",
    "allocation.api": "the channel allocation (cvxpy), through the allocation package: only the audit's claims "
                      "on the designs' attainable costs",
    "allocation.attainable": "what a loop attains at a design, through the allocation package (cvxpy): only the "
                             "audit's claims on the designs' attainable costs",
    "allocation.power": "power-limited links (cvxpy): only the power-water-filling claim of the audit",
    "allocation.delivery": "the delivery-versus-power models, through the allocation package (cvxpy): only the "
                           "power-water-filling claim of the audit",
    "plots": "figures (matplotlib), through the plots package: only commands asked to draw",
    "plots.figures": "figures (matplotlib): only commands asked to draw",
    "sensing.lmi": "Sinopoli's filter LMI (cvxpy): the critical arrival rate's cross-check, only where asked",
    "montecarlo.mpc": "the constrained receding-horizon loop (cvxpy): simulate only for a file with a [constraints] "
                      "table",
    "cli.mpc_section": "the constrained loop's section of simulate (cvxpy): only for a file with a [constraints] table",
})

#: library -> the pyproject extra that installs it (the others are required dependencies)
EXTRAS: Mapping[str, str] = MappingProxyType({
    "dask": "distributed", "distributed": "distributed", "xarray": "xarray", "control": "control", "pandas": "xarray",
})


def load(name: str, field: str) -> ModuleType:
    """Import the heavy optional library ``name`` for the caller's ``field``. O(1) once imported.

    Raises
    ------
    InputError
        Field ``field`` when the library is not installed, naming the extra that installs it; field
        ``name`` when ``name`` is not in `LAZY_IMPORTS` (import it at the top of the module).

    Examples
    --------
    >>> load("tqdm", "progress").__name__
    'tqdm'
    >>> try:
    ...     load("numpy", "x")
    ... except InputError as err:
    ...     print(err.field)
    name
    """
    if name not in LAZY_IMPORTS:
        raise InputError("name", f"{name!r} is not a lazily imported library (optional.LAZY_IMPORTS): "
                                 "import it at the top of the module")
    try:
        return importlib.import_module(name)
    except ImportError:
        extra = EXTRAS.get(name)
        how = f"pip install 'packetloss-cvx[{extra}]'" if extra else f"pip install {name}"
        raise InputError(field, f"needs {name}, not installed: {how}") from None
