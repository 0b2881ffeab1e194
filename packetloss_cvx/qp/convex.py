"""Running cvxpy problems with Clarabel under one policy.

* solver warnings are captured, never printed (the command line prints one line);
* cvxpy's own solver failures become [`SolverError`][packetloss_cvx.errors.SolverError], and so does a panic in
  Clarabel's Rust code (pyo3's ``PanicException``, a BaseException that ``except Exception`` misses: e.g. "Eigval
  error" in its PSD cone on a badly scaled SDP), always through `clarabel_failure`;
* only the statuses in `tolerances.ACCEPTED_STATUSES` count as an answer
  (``optimal_inaccurate`` does not);
* infeasibility counts only when the solver proved it (``infeasible``, not ``infeasible_inaccurate``).

A problem re-solved many times for new Parameter values is compiled once into a
`ClarabelProgram`: each solve maps the values onto the compiled cone program (one sparse
product) and runs Clarabel cold on exactly the data ``problem.solve`` would give it.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable, Mapping, Sequence

import clarabel
import cvxpy as cp
import numpy as np
import scipy.sparse as sp
from cvxpy.cvxcore.python.canonInterface import get_parameter_vector
from cvxpy.reductions.solvers.conic_solvers.clarabel_conif import CLARABEL, dims_to_solver_cones

from ..errors import SolverError, is_panic
from ..tolerances import ACCEPTED_STATUSES, CLARABEL_DEFAULT, CLARABEL_TIGHT

__all__ = ["PROVEN_INFEASIBLE", "ClarabelPoint", "ClarabelProgram", "clarabel_failure", "first_answer",
           "require_optimal", "solve_problem"]

#: The status that proves infeasibility (Clarabel's certificate); "infeasible_inaccurate" does not.
PROVEN_INFEASIBLE = cp.INFEASIBLE

#: cvxpy's canonicalisation backend of :class:`ClarabelProgram`'s compile: "COO" where this cvxpy has it (the same
#: parameter maps as the default "CPP", entry for entry, in about 0.6 of the time; tests/qp/test_convex.py), else
#: cvxpy's default (None).
CANON_BACKEND = getattr(cp.settings, "COO_CANON_BACKEND", None)


def clarabel_failure(err: BaseException, what: str) -> SolverError:
    """The [`SolverError`][packetloss_cvx.errors.SolverError] (status "solver_error") for a Clarabel call that
    raised ``err``: a failure of the solver, never a verdict on the problem. A Rust panic says so ("Clarabel
    panicked: ..."); the caller re-raises anything else that is no Exception (KeyboardInterrupt, SystemExit). O(1).

    Examples
    --------
    >>> PanicException = type("PanicException", (BaseException,), {})
    >>> str(clarabel_failure(PanicException("Eigval error: Eigen(1)"), "an SDP"))
    "solver status 'solver_error': an SDP: Clarabel panicked (Eigval error: Eigen(1))"
    """
    if is_panic(err):
        return SolverError("solver_error", f"{what}: Clarabel panicked ({err})")
    return SolverError("solver_error", f"{what}: {err}")


def _solver_failure(err: BaseException) -> bool:
    """Whether ``err`` is a solver's failure to be reported as SolverError: any Exception, or a Rust panic (not
    KeyboardInterrupt or SystemExit). O(1)."""
    return isinstance(err, Exception) or is_panic(err)


def solve_problem(problem: cp.Problem, what: str,
                  attempts: Sequence[Mapping] = (CLARABEL_TIGHT, CLARABEL_DEFAULT)) -> str:
    """Solve with Clarabel, trying each settings dict in ``attempts`` until one gives an
    accepted status or a proven infeasibility; returns the final status.

    Each attempt runs on a new Clarabel solver (cvxpy's ``warm_start=False``; a settings dict may say otherwise).
    cvxpy's default keeps the solver of the problem's last solve and updates its data in place: the answer then
    carries the equilibration of the first data it saw, and an updated solver panicked in its PSD cone ("Eigval
    error") where a new one on the same data failed cleanly (the stabilising LMI of the pendulum at
    ``--margin 1e-9``, after 107 solves along the design search; after a panic every later update of that solver
    panicked too).

    Raises
    ------
    SolverError
        When cvxpy or Clarabel fails outright, a Rust panic of Clarabel's included (status ``"solver_error"``).

    Examples
    --------
    >>> x = cp.Variable()
    >>> problem = cp.Problem(cp.Minimize(cp.square(x - 1)))
    >>> solve_problem(problem, "a scalar QP")
    'optimal'
    >>> bool(abs(x.value - 1.0) < 1e-6)
    True
    """
    def attempt(settings: Mapping) -> str:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                problem.solve(solver=cp.CLARABEL, **{"warm_start": False, **settings})
            except (cp.error.SolverError, ValueError, ArithmeticError) as err:   # e.g. a value cvxpy refuses
                raise clarabel_failure(err, what) from None
            except BaseException as err:
                if not is_panic(err):
                    raise
                raise clarabel_failure(err, what) from None
        return str(problem.status)

    return first_answer(attempt, attempts)


def first_answer(attempt: Callable[[Mapping], str], attempts: Sequence[Mapping]) -> str:
    """The status policy's loop: run ``attempt(settings)`` for each settings dict in turn and stop
    at the first accepted status or proven infeasibility; returns the last status ("not_solved"
    when there are no attempts). O(len(attempts)) solves.

    Examples
    --------
    >>> first_answer(lambda s: s["says"], [{"says": "optimal_inaccurate"}, {"says": "optimal"}])
    'optimal'
    >>> first_answer(lambda s: s["says"], [{"says": "infeasible"}, {"says": "optimal"}])
    'infeasible'
    >>> first_answer(lambda s: s["says"], [{"says": "infeasible_inaccurate"}])
    'infeasible_inaccurate'
    """
    status = "not_solved"
    for settings in attempts:
        status = attempt(settings)
        if status in ACCEPTED_STATUSES or status == PROVEN_INFEASIBLE:
            return status
    return status


def require_optimal(status: str, what: str) -> None:
    """Raise [`SolverError`][packetloss_cvx.errors.SolverError] unless ``status`` is an accepted answer.

    Examples
    --------
    >>> require_optimal("optimal", "the QP") is None
    True
    >>> require_optimal("infeasible", "the QP")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.SolverError: solver status 'infeasible': the QP
    """
    if status not in ACCEPTED_STATUSES:
        raise SolverError(status, what)


class ClarabelProgram:
    """A DPP cvxpy problem, compiled once for Clarabel and re-solved cold for new Parameter values.

    cvxpy's own compilation (``problem.get_problem_data(cp.CLARABEL)``) gives the cone program
    ``min x'Px/2 + c'x + d  s.t.  A x + s = b, s in K`` whose data are affine in the Parameters: one sparse
    matrix maps the parameter vector to the nonzeros of ``[A b]``, another to ``(c, d)``, a third (a
    quadratic objective, e.g. the shared condensed QP of `.shared`) to P
    (cvxpy's ``reduce_problem_data_tensor``). A solve forms that vector, applies the two maps and
    hands Clarabel the matrices ``problem.solve`` would hand it (the same products, the same sparsity,
    the same cones: ``tests/qp/test_convex.py`` compares the two bit for bit), in a new solver per
    attempt: cold, so an answer depends on its own data only (a warm Clarabel keeps the
    equilibration of the first data it saw). What ``problem.solve`` adds per call, re-applying the
    Parameters through its reduction chain, setting up its solver interface and unpacking every
    variable, is skipped (about two fifths of a small solve).

    An attempt whose settings switch Clarabel's equilibration off (``equilibrate_enable`` False) runs on a
    solver kept per thread and given the new data (``update``: its KKT pattern and ordering kept, the
    set-up saved): without an equilibration to carry over, Clarabel then
    computes the floats a new solver computes (``tests/qp/test_convex.py``). With the equilibration on, an
    updated solver would keep the scaling of the first data it saw, so those attempts build a new solver.

    Construction O(compilation) (cvxpy's), each solve O(nnz) for the data plus Clarabel's
    interior-point iterations. Between solves the object holds only those per-thread solvers, whose
    answers do not depend on what they solved before (thread-safe).

    Examples
    --------
    The least x1 + x2 in the unit disc around a is at a - (1, 1)/sqrt(2):

    >>> x, a = cp.Variable(2), cp.Parameter(2)
    >>> program = ClarabelProgram(cp.Problem(cp.Minimize(cp.sum(x)), [cp.norm(x - a) <= 1]))
    >>> status, point = program.solve({a: [1.0, 2.0]}, "an SOCP")
    >>> status, bool(np.allclose(point(x), np.array([1.0, 2.0]) - np.sqrt(0.5), atol=1e-7))
    ('optimal', True)
    >>> program.solve({a: [1.0, np.nan]}, "an SOCP")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.SolverError: solver status 'solver_error': an SOCP: Parameter param... is not finite
    """

    def __init__(self, problem: cp.Problem, duals: bool = False) -> None:
        if not problem.is_dpp():
            raise ValueError("ClarabelProgram needs a DPP problem (cvxpy's disciplined parametrized programming)")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data, chain, inverse = problem.get_problem_data(cp.CLARABEL, canon_backend=CANON_BACKEND, solver_opts={})
        self._problem, self._chain, self._inverse = problem, chain, inverse
        self._selections: dict | None = None       # `duals` and `primals`: cvxpy's inversion as selections
        program = data[cp.settings.PARAM_PROB]
        program.reduced_A.cache()
        if program.P is not None:                 # a quadratic objective: P mapped like [A b], per solve
            program.reduced_P.cache()
        self._program = program
        self._parameters = {p.id: p for p in problem.parameters()}
        if set(self._parameters) != set(program.param_id_to_size):
            raise ValueError("cvxpy replaced a Parameter during compilation: ClarabelProgram cannot map its values")
        self._values, self._index = program.reduced_A.reduced_mat, program.reduced_A.problem_data_index
        if self._index is None:
            raise ValueError("ClarabelProgram needs constraints (cvxpy compiled no constraint data)")
        self._cones = dims_to_solver_cones(data[CLARABEL.DIMS])
        nvar = program.x.size
        self._P = sp.triu(sp.csc_array((nvar, nvar))).tocsc()
        if program.P is not None:      # a P that no Parameter moves (the usual case) is mapped once
            fixed = program.reduced_P.reduced_mat[:, :-1].count_nonzero() == 0
            unit = np.zeros(program.total_param_size + 1)
            unit[-1] = 1.0                               # the parameter vector's constant entry (cvxpy's layout)
            self._P = self._quadratic(unit) if fixed else None
            if not fixed:                            # the parameter entries P depends on: P is formed when they move
                self._P_columns = np.unique(sp.csc_array(program.reduced_P.reduced_mat).nonzero()[1])
                self._P_last: tuple[bytes, sp.csc_array] | None = None
        self._kept = threading.local()          # per thread: settings -> a Clarabel solver to update
        if duals:                               # the multipliers' map now, so that a refusal shows at construction
            self._selections = self._probe()

    def data(self, values: Mapping[cp.Parameter, np.typing.ArrayLike]) -> tuple:
        """Clarabel's ``(P, q, A, b)`` for the Parameter values (every Parameter of the problem).
        O(nnz)."""
        P, q, _, A, b = self._data(values)
        return P, q, A, b

    def _data(self, values: Mapping[cp.Parameter, np.typing.ArrayLike]) -> tuple:
        """``(P, q, d, A, b)``: `data` and the objective's constant d (cvxpy's offset). O(nnz)."""
        given = {}
        for parameter, value in values.items():
            array = np.asarray(value, dtype=float).reshape(parameter.shape)
            if not np.all(np.isfinite(array)):
                raise ValueError(f"Parameter {parameter.name()} is not finite")
            given[parameter.id] = array
        if set(given) != set(self._parameters):
            missing = sorted(self._parameters[i].name() for i in set(self._parameters) - set(given))
            raise ValueError(f"values for every Parameter are needed; missing {missing}")
        program = self._program
        vector = get_parameter_vector(program.total_param_size, program.param_id_to_col, program.param_id_to_size,
                                      given.__getitem__)
        q = np.asarray(program.q @ vector).ravel()
        q, d = q[:-1], q[-1]                    # the objective's constant: cvxpy adds it to Clarabel's value
        flat = self._values @ vector
        indices, indptr, (rows, cols) = self._index
        end = indptr[cols - 1]                  # the last column of [A b] holds b
        A = sp.csc_array((-flat[:end], indices[:end], indptr[:cols]), shape=(rows, cols - 1))
        b = np.zeros(rows)
        b[indices[end:]] = flat[end:]
        if self._P is not None:
            return self._P, q, d, A, b
        key, last = vector[self._P_columns].tobytes(), self._P_last
        if last is None or last[0] != key:
            last = self._P_last = (key, self._quadratic(vector))
        return last[1], q, d, A, b

    def _quadratic(self, vector: np.ndarray) -> sp.csc_array:
        """P for a parameter vector, formed as cvxpy's ConicSolver.apply and its Clarabel interface form it
        (the upper triangle). O(nnz)."""
        P, _ = self._program.reduced_P.get_matrix_from_tensor(vector, with_offset=False)
        return sp.triu(P).tocsc()

    def solve(self, values: Mapping[cp.Parameter, np.typing.ArrayLike], what: str,
              attempts: Sequence[Mapping] = (CLARABEL_TIGHT, CLARABEL_DEFAULT)
              ) -> tuple[str, ClarabelPoint]:
        """Clarabel on the data for ``values`` under `solve_problem`'s policy (each settings
        dict in turn, each run cold, until an accepted status or proven infeasibility). Returns the
        final status (cvxpy's name for it) and Clarabel's point (`ClarabelPoint`: ``variable ->
        value``, and the objective's value there as cvxpy reports it).

        Raises
        ------
        SolverError
            A value that is not finite or of the wrong shape, or Clarabel failing outright.
        """
        try:
            P, q, d, A, b = self._data(values)
        except ValueError as err:
            raise SolverError("solver_error", f"{what}: {err}") from None
        solution = None

        def attempt(settings: Mapping) -> str:
            nonlocal solution
            options = clarabel.DefaultSettings()
            options.verbose = False
            for key, value in settings.items():
                setattr(options, key, value)
            try:
                if settings.get("equilibrate_enable", True) is False:
                    solution = self._updated(settings, options, P, q, A, b).solve()
                else:
                    solution = clarabel.DefaultSolver(P, q, A, b, self._cones, options).solve()
            except BaseException as err:    # Clarabel's own failures (untyped Python errors, or a Rust panic)
                if not _solver_failure(err):
                    raise
                self._kept.solvers = {}                  # none kept after a failure
                raise clarabel_failure(err, what) from None
            return CLARABEL.STATUS_MAP.get(str(solution.status), cp.SOLVER_ERROR)

        status = first_answer(attempt, attempts)
        if solution is None:
            return status, ClarabelPoint(np.full(self._program.x.size, np.nan), self._program.var_id_to_col, np.nan)
        return status, ClarabelPoint(np.asarray(solution.x, dtype=float), self._program.var_id_to_col,
                                     solution.obj_val + d, np.asarray(solution.z, dtype=float))

    def duals(self, point: ClarabelPoint) -> dict[int, np.ndarray]:
        """The multipliers of the problem's constraints at Clarabel's ``point`` (its z: the multipliers of an
        optimum, the certificate of a proven infeasibility), ``constraint id -> value``, as cvxpy's chain would
        unpack them (``constraint.dual_value``).

        Each multiplier is a signed selection of entries of z; which entries and signs is read once from cvxpy's own
        inversion of the chain (``chain.invert`` on a probe point x = 1, 2, ..., z = 1, 2, ...) and confirmed on a
        second, random probe, so a reduction that mixed entries would be refused (ValueError), never mapped wrongly.
        O(rows) per call, O(cvxpy's inversion) once.
        """
        return self._selected(point.z, "dual")

    def primals(self, point: ClarabelPoint) -> dict[int, np.ndarray]:
        """The values of the problem's variables at ``point``, ``variable id -> value``, as cvxpy's chain would unpack
        them (``variable.value``; a variable that cvxpy re-posed, e.g. one declared ``nonneg``, included), read like
        `duals`. O(variables' size)."""
        return self._selected(point.x, "primal")

    def _selected(self, vector: np.ndarray, kind: str) -> dict[int, np.ndarray]:
        if self._selections is None:
            self._selections = self._probe()
        out = {key: (sign * vector[index]).reshape(shape)
               for (which, key), (index, sign, shape) in self._selections.items() if which == kind}
        if kind == "primal":            # cvxpy projects a variable's value onto its attributes (nonneg: max(x, 0))
            for key, variable in self._projected.items():
                out[key] = variable.project(out[key])
        return out

    def _probe(self) -> dict[tuple[str, int], tuple[np.ndarray, np.ndarray, tuple]]:
        """``(kind, id) -> (entries, signs, shape)``: each constraint's multiplier as entries of z and each variable's
        value as entries of x, from cvxpy's inversion of probe solutions."""
        rows, columns = int(self._index[2][0]), self._program.x.size
        ids = [("dual", c.id) for c in self._problem.constraints]
        ids += [("primal", v.id) for v in self._problem.variables()]

        def inverted(x: np.ndarray, z: np.ndarray) -> dict[tuple[str, int], np.ndarray]:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                solution = self._chain.invert(_ProbeSolution(x, z), self._inverse)
            found = {("dual", key): value for key, value in solution.dual_vars.items()}
            found.update({("primal", key): value for key, value in solution.primal_vars.items()})
            missing = [key for key in ids if key not in found]
            if missing:
                raise ValueError(f"cvxpy's inversion gave no value for {len(missing)} constraint(s) or variable(s)")
            return {key: np.asarray(found[key], dtype=float) for key in ids}

        sizes = {"dual": rows, "primal": columns}
        selections = {}
        for key, value in inverted(np.arange(1.0, columns + 1.0), np.arange(1.0, rows + 1.0)).items():
            flat = value.ravel()
            index = np.rint(np.abs(flat)).astype(int) - 1
            if np.any(index < 0) or np.any(index >= sizes[key[0]]) or not np.array_equal(np.abs(flat), index + 1.0):
                raise ValueError(f"a {key[0]} value is not a selection of Clarabel's point")
            selections[key] = (index, np.sign(flat), value.shape)
        #: variables whose value cvxpy projects onto their attributes (Leaf.project), as its inversion does
        self._projected = {v.id: v for v in self._problem.variables()
                           if any(v.attributes.get(name) for name in ("nonneg", "nonpos", "pos", "neg", "bounds",
                                                                      "integer", "boolean"))}
        rng = np.random.default_rng(0)
        x, z = rng.normal(size=columns), rng.normal(size=rows)
        for key, value in inverted(x, z).items():
            index, sign, shape = selections[key]
            expected = (sign * (z if key[0] == "dual" else x)[index]).reshape(shape)
            if key[0] == "primal" and key[1] in self._projected:
                expected = self._projected[key[1]].project(expected)
            if not np.array_equal(value, expected):
                raise ValueError(f"a {key[0]} value is not a selection of Clarabel's point")
        return selections

    def _updated(self, settings: Mapping, options: clarabel.DefaultSettings, P: sp.csc_array, q: np.ndarray,
                 A: sp.csc_array, b: np.ndarray) -> clarabel.DefaultSolver:
        """This thread's solver for ``settings`` (equilibration off) holding the data (P, q, A, b): the kept one
        updated, or a new one where none is kept or Clarabel refuses the update (its presolve removed rows).
        O(nnz)."""
        solvers = getattr(self._kept, "solvers", None)
        if solvers is None:
            solvers = self._kept.solvers = {}
            self._kept.matrices = {}             # settings -> the (P, A) the kept solver holds
        key = tuple(sorted(settings.items()))
        solver, held = solvers.get(key), self._kept.matrices.get(key)
        if solver is not None and solver.is_data_update_allowed():
            try:
                changed = {"q": q, "b": b}        # a matrix the solver holds already is not given again
                if held is None or not _same(P, held[0]):
                    changed["P"] = P
                if held is None or not _same(A, held[1]):
                    changed["A"] = A
                solver.update(**changed)
                self._kept.matrices[key] = (P, A)
                return solver
            except Exception:   # noqa: BLE001 - an update Clarabel refuses: a new solver instead
                pass
        solver = solvers[key] = clarabel.DefaultSolver(P, q, A, b, self._cones, options)
        self._kept.matrices[key] = (P, A)
        return solver


def _same(a: sp.csc_array, b: sp.csc_array) -> bool:
    """Whether two CSC matrices hold the same entries in the same layout. O(nnz)."""
    return a is b or (a.shape == b.shape and np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
                      and np.array_equal(a.data, b.data))


class ClarabelPoint:
    """Clarabel's point of a `ClarabelProgram` solve: ``point(variable)`` is the variable's value
    (cvxpy's column layout), ``point.value`` the objective there as ``problem.value`` gives it (Clarabel's
    objective plus the compiled constant). Read them only under an accepted status. O(1) to build.

    Examples
    --------
    The least (x - a)^2 + 1 is 1, at x = a:

    >>> x, a = cp.Variable(), cp.Parameter()
    >>> status, point = ClarabelProgram(cp.Problem(cp.Minimize(cp.square(x - a) + 1))).solve({a: 2.0}, "a QP")
    >>> status, round(float(point(x)), 6), round(point.value, 6)
    ('optimal', 2.0, 1.0)
    """

    def __init__(self, x: np.ndarray, columns: Mapping[int, int], value: float, z: np.ndarray | None = None) -> None:
        self._x, self._columns, self.value = x, columns, float(value)
        #: Clarabel's primal point (`ClarabelProgram.primals` maps it onto the variables)
        self.x = x
        #: Clarabel's dual point (`ClarabelProgram.duals` maps it onto the constraints)
        self.z = np.full(0, np.nan) if z is None else z

    def __call__(self, variable: cp.Variable) -> np.ndarray:
        start = self._columns[variable.id]
        return self._x[start:start + variable.size].reshape(variable.shape, order="F")


class _ProbeSolution:
    """The fields of a Clarabel solution that cvxpy's Clarabel interface reads when it inverts (status "Solved")."""

    def __init__(self, x: np.ndarray, z: np.ndarray) -> None:
        self.x, self.z, self.s = x, z, np.zeros_like(z)
        self.status, self.obj_val, self.solve_time, self.iterations = "Solved", 0.0, 0.0, 0
