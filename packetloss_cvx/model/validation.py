"""The one validator of numeric input (`numeric_array`): every array the package accepts goes
through it, so that every error names its field. Iterative, O(number of entries).

Below it, the checks of a [`System`][packetloss_cvx.model.system.System]'s fields built on it (shapes, PSD weights,
probabilities, the horizon), each raising an error that names the field."""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np

from ..errors import DimensionError, InputError, ProbabilityError
from ..tolerances import PSD_RTOL, SYMMETRY_RTOL

__all__ = [
    "MAX_ENTRIES", "MAX_NESTING", "channel_range", "check_numbers", "diagonal_weight", "digits", "every_channel",
    "exactly_one", "frozen", "horizon_field", "matrix_field", "numeric_array", "probabilities", "psd_weight",
    "psd_weights", "shape_error", "symmetric_psd", "vector_field", "weight_alias", "weight_sequence",
]

#: Arrays in the schema nest at most three levels deep (state_weights: N × n × n).
MAX_NESTING = 3
#: The largest number of entries one stored array may have (8 bytes each: 400 MB), so that a
#: System is refused before an allocation that cannot succeed (horizon = 10**9).
MAX_ENTRIES = 5 * 10**7


def numeric_array(value: Any, field: str) -> np.ndarray:
    """Convert ``value`` to a float array, refusing strings, booleans, NaN, inf, numbers beyond
    the double range, nesting deeper than ``MAX_NESTING`` and more than ``MAX_ENTRIES`` entries.

    The one validator of numeric input: every array the package accepts goes through it,
    so every error names ``field``.

    Examples
    --------
    >>> numeric_array([[1, 2], [3, 4.5]], "A").tolist()
    [[1.0, 2.0], [3.0, 4.5]]
    >>> numeric_array([1.0, float("nan")], "mu")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: mu: expected finite numbers, found NaN or inf
    """
    if isinstance(value, np.ma.MaskedArray) and np.ma.is_masked(value):
        raise InputError(field, "expected plain numbers, found a masked array with masked entries")
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise InputError(field, f"expected numbers, found an array of {value.dtype}")
        if value.ndim > MAX_NESTING or value.size > MAX_ENTRIES:
            raise InputError(field, f"expected at most {MAX_NESTING} dimensions and {MAX_ENTRIES} entries, found "
                                    f"shape {value.shape}")
        arr = value.astype(float)
    else:
        check_numbers(value, field)
        try:
            arr = np.asarray(value, dtype=float)
        except ValueError:
            raise InputError(field, "expected a rectangular array of numbers") from None
    if not np.all(np.isfinite(arr)):
        raise InputError(field, "expected finite numbers, found NaN or inf")
    return arr


def check_numbers(value: Any, field: str) -> None:
    """Walk ``value`` without recursion: numbers only, at most MAX_NESTING levels of lists,
    at most MAX_ENTRIES numbers, each within the double range.

    Examples
    --------
    >>> check_numbers([[1, 2.5], [3, 4]], "B") is None       # numbers only: passes silently
    True
    >>> check_numbers([1, "2"], "B")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: B: expected a number, found the string '2'
    """
    stack: list[tuple[Any, int]] = [(value, 0)]
    count = 0
    while stack:
        item, depth = stack.pop()
        if isinstance(item, bool):
            raise InputError(field, "expected a number, found a boolean")
        if isinstance(item, numbers.Real):
            count += 1
            if count > MAX_ENTRIES:
                raise InputError(field, f"expected at most {MAX_ENTRIES} numbers")
            if isinstance(item, numbers.Integral):
                try:
                    float(item)
                except OverflowError:
                    size = digits(int(item))
                    raise InputError(field, f"expected numbers within the double range (|x| < 1.8e308), found an "
                                            f"integer of about {size} digits") from None
            continue
        if isinstance(item, np.ndarray):            # a row given as an array inside a list
            if item.dtype.kind not in "iuf" or depth + item.ndim > MAX_NESTING:
                raise InputError(field, f"expected numbers, found an array of {item.dtype} and shape {item.shape}")
            count += item.size
            continue
        if isinstance(item, str):
            raise InputError(field, f"expected a number, found the string {item[:40]!r}")
        if isinstance(item, (list, tuple)):
            if depth >= MAX_NESTING:
                raise InputError(field, f"expected at most {MAX_NESTING} levels of nested lists, found more")
            if all(type(sub) is float for sub in item):     # a row of Python floats (TOML's, tolist()'s): numbers
                count += len(item)                           # in range, as the item-by-item walk below finds
                if count > MAX_ENTRIES:
                    raise InputError(field, f"expected at most {MAX_ENTRIES} numbers")
                continue
            stack.extend((sub, depth + 1) for sub in item)
            continue
        raise InputError(field, f"expected a number or a list of numbers, found {type(item).__name__}")


def digits(value: int) -> int:
    """Decimal digits of a huge integer, without str() (Python refuses it past 4300 digits).

    >>> digits(10**5000)
    5001
    """
    return int(abs(value).bit_length() * 0.30103) + 1


def shape_error(field: str, expected: str, found: tuple[int, ...]) -> DimensionError:
    """The DimensionError of a field with the wrong shape.

    >>> str(shape_error("B", "(2, m)", (3, 1)))
    'B: expected shape (2, m) but found (3, 1)'
    """
    return DimensionError(field, f"expected shape {expected} but found {found}")


def matrix_field(value: Any, field: str, rows: int | None, cols: int | None, expected: str) -> np.ndarray:
    """A 2-D float array (`numeric_array`) with ``rows`` and ``cols`` (None: any), else a DimensionError.

    >>> matrix_field([[1, 2]], "B", 1, None, "(1, m)").tolist()
    [[1.0, 2.0]]
    """
    arr = numeric_array(value, field)
    if arr.ndim != 2 or (rows is not None and arr.shape[0] != rows) or (
        cols is not None and arr.shape[1] != cols
    ):
        raise shape_error(field, expected, arr.shape)
    return arr


def vector_field(value: Any, field: str, length: int, expected: str) -> np.ndarray:
    """A float vector of ``length`` entries, else a DimensionError.

    >>> vector_field([1, 2], "x0", 3, "(3,)")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.DimensionError: x0: expected shape (3,) but found (2,)
    """
    arr = numeric_array(value, field)
    if arr.shape != (length,):
        raise shape_error(field, expected, arr.shape)
    return arr


def channel_range(m: int, command_line: bool = False) -> str:
    """How channels are counted, for a message: Python counts from 0 (``channel=0`` is mu1), the command line
    from 1 (``--channel 1`` is mu1); each message says which, and the other beside it. O(1).

    >>> channel_range(2)
    'a channel index from 0 to 1 (0-based in Python: channel 0 is mu1; the command line counts from 1)'
    >>> channel_range(2, command_line=True)
    'a channel from 1 to 2 (1-based on the command line: 1 is mu1; Python counts from 0)'
    """
    if command_line:
        return f"a channel from 1 to {m} (1-based on the command line: 1 is mu1; Python counts from 0)"
    return f"a channel index from 0 to {m - 1} (0-based in Python: channel 0 is mu1; the command line counts from 1)"


def every_channel(value: Any, m: int) -> Any:
    """A bare number as the same value for each of the ``m`` channels (as ``--mu 0.5`` on the command line);
    anything else unchanged (the caller checks its shape). O(m).

    >>> every_channel(0.5, 3).tolist(), every_channel([0.1, 0.2], 3)
    ([0.5, 0.5, 0.5], [0.1, 0.2])
    """
    if value is None or isinstance(value, (list, tuple, str, bytes)) or getattr(value, "ndim", 0):
        return value                     # the common case, a list or an array, costs no conversion
    if np.ndim(value) == 0:
        return np.full(m, numeric_array(value, "mu"))
    return value


def weight_alias(alias: str, value: Any, name: str, single: Any, sequence: Any) -> Any:
    """python-control's name ``alias`` (Q, R) for the weight ``name`` (state_weight, input_weight): ``value`` when
    the alias is given, else ``single``; refused when the weight is given twice. O(1).

    >>> weight_alias("Q", [1.0], "state_weight", None, None)
    [1.0]
    >>> weight_alias("Q", [1.0], "state_weight", [2.0], None)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: Q: Q is python-control's name for state_weight: give one of Q, ...
    """
    if value is None:
        return single
    if single is not None or sequence is not None:
        paper = " (the paper's Q, the weight on X_k, is initial_weight)" if alias == "Q" else ""
        raise InputError(alias, f"{alias} is python-control's name for {name}: give one of {alias}, {name}, "
                                f"{name}s, not two{paper}")
    return value


def diagonal_weight(value: Any, field: str, m: int) -> np.ndarray:
    """The diagonal of the input weight Psi: a length-m vector, or an m×m matrix that is diagonal (python-control
    passes ``R`` as a matrix; a number when m = 1). O(m^2).

    A matrix with an off-diagonal entry is refused: the cost weighs the applied input V u (V = diag(v), v_i = 1
    when channel i delivers), and E[(V u)' Psi (V u)] = u' Vbar Psi u, which the paper's closed forms use, holds
    for a diagonal Psi only (a full one adds Psi_ij mu_i mu_j u_i u_j, coupling two channels' deliveries).

    >>> diagonal_weight([[1.0, 0.0], [0.0, 2.0]], "R", 2).tolist()
    [1.0, 2.0]
    >>> diagonal_weight([[1.0, 0.5], [0.5, 2.0]], "R", 2)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: R: expected a diagonal input weight, found R[0, 1] = 0.5: ...
    """
    arr = numeric_array(value, field)
    if arr.ndim == 0 and m == 1:
        return arr.reshape(1)
    if arr.ndim == 2:
        if arr.shape != (m, m):
            raise shape_error(field, f"({m},) or ({m}, {m}) (diagonal)", arr.shape)
        off = arr - np.diag(np.diag(arr))
        if np.any(off != 0):
            i, j = np.argwhere(off != 0)[0]
            raise InputError(field, f"expected a diagonal input weight, found {field}[{i}, {j}] = {arr[i, j]:.6g}: "
                                    "the cost weighs the applied input V u, and the paper's closed forms "
                                    "(Lemma 1, Theorem 1) take E[(V u)' Psi (V u)] = u' Vbar Psi u, true for a "
                                    "diagonal Psi only (an off-diagonal entry couples two channels' deliveries, "
                                    "E[v_i v_j] = mu_i mu_j); give the diagonal, e.g. np.diag(R), if each "
                                    "actuator's own weight is what you mean")
        return np.diag(arr).copy()
    if arr.shape != (m,):
        raise shape_error(field, f"({m},) or ({m}, {m}) (diagonal)", arr.shape)
    return arr


def psd_weight(value: Any, field: str, n: int) -> np.ndarray:
    """A diagonal (length-n vector, non-negative) or full n×n symmetric PSD weight (`symmetric_psd`),
    as a matrix. Time O(n^3).

    >>> psd_weight([1, 2], "state_weight", 2).tolist()
    [[1.0, 0.0], [0.0, 2.0]]
    """
    arr = numeric_array(value, field)
    if arr.ndim == 1:
        if arr.shape != (n,):
            raise shape_error(field, f"({n},) or ({n}, {n})", arr.shape)
        if np.any(arr < 0):
            raise InputError(field, "expected a non-negative diagonal (positive semidefinite weight)")
        return np.diag(arr)
    if arr.shape != (n, n):
        raise shape_error(field, f"({n},) or ({n}, {n})", arr.shape)
    return symmetric_psd(arr, field)


def psd_weights(items: list, field: str, n: int) -> np.ndarray:
    """The per-step weights ``items`` (each as `psd_weight` takes it) as an (N, n, n) stack: the same
    floats, and the same first error naming ``field[t]``, as ``psd_weight`` step by step.

    The full matrices are checked as one stack (one batched eigh: LAPACK's routine per matrix, as for a single
    one): an exactly symmetric one whose eigenvalues are all >= 0 passes as it would alone, with the same
    ``(W + W')/2``, and so does a non-negative diagonal, as ``diag(w)``. Every other step (a negative entry, an
    asymmetry to measure, a negative eigenvalue to judge or repair) goes through `psd_weight` in step
    order, which raises or repairs exactly as it does alone, and so does the whole input if a step has a bad
    entry or shape. Time O(N n^3) in a few NumPy calls instead of a few per step.

    >>> psd_weights([[1, 2], [[2, 1], [1, 2]], [[1, 0], [0, 1]]], "state_weights", 2).tolist()
    [[[1.0, 0.0], [0.0, 2.0]], [[2.0, 1.0], [1.0, 2.0]], [[1.0, 0.0], [0.0, 1.0]]]
    >>> psd_weights([[1, 2], [[1, 2], [2, 1]], [[1, 0], [0, 1]]], "state_weights", 2)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: state_weights[1]: expected a positive semidefinite matrix, found ...
    """
    def one_by_one() -> np.ndarray:
        return np.stack([psd_weight(w, f"{field}[{t}]", n) for t, w in enumerate(items)])

    try:
        arrays = _as_one_stack(items, field)
        if arrays is None:
            arrays = [numeric_array(w, f"{field}[{t}]") for t, w in enumerate(items)]
    except InputError:
        return one_by_one()                      # raises the first step's error, whatever it is
    full = [t for t, arr in enumerate(arrays) if arr.shape == (n, n)]
    if any(arr.shape not in ((n,), (n, n)) for arr in arrays):
        return one_by_one()
    diagonal = [t for t, arr in enumerate(arrays) if arr.ndim == 1]
    out = np.zeros((len(arrays), n, n))
    passed = set()
    if full:
        F = np.stack([arrays[t] for t in full])
        sym = 0.5 * (F + F.transpose(0, 2, 1))
        ok = np.all(F == F.transpose(0, 2, 1), axis=(1, 2)) & (np.linalg.eigh(sym)[0].min(axis=1) >= 0)
        out[full] = sym
        passed.update(t for t, good in zip(full, ok, strict=True) if good)
    if diagonal:
        D = np.stack([arrays[t] for t in diagonal])
        out[np.array(diagonal)[:, None], np.arange(n), np.arange(n)] = D          # diag(w) of each
        passed.update(t for t, good in zip(diagonal, ~np.any(D < 0, axis=1), strict=True) if good)
    for t in sorted(set(range(len(arrays))) - passed):
        out[t] = psd_weight(arrays[t], f"{field}[{t}]", n)
    return out


def _as_one_stack(items: list, field: str) -> list[np.ndarray] | None:
    """The steps of a list of nested lists (a TOML file's, ``tolist()``'s) converted by one `numeric_array` of
    the whole list: the same floats as step by step. Its walk is stricter than each step's (one more level of
    nesting, the entries of all steps counted together), so whatever it accepts every step accepts alone, and
    whatever it refuses (a bad entry, ragged or mixed shapes) raises InputError: the caller then goes step by step
    for the step's own error. Plain numeric arrays of one shape (random_systems', NumPy callers') likewise, stacked
    first (each array's dtype checked: NumPy would promote a boolean one). None otherwise (a masked array, whose
    mask is checked step by step, mixed types or shapes). Time O(N n^2)."""
    if all(type(w) is list for w in items):
        return list(numeric_array(items, field))
    if (all(type(w) is np.ndarray and w.dtype.kind in "iuf" for w in items)
            and len({w.shape for w in items}) == 1):
        return list(numeric_array(np.stack(items), field))
    return None


def symmetric_psd(arr: np.ndarray, field: str) -> np.ndarray:
    """Symmetric to SYMMETRY_RTOL and PSD to PSD_RTOL, both relative to ||arr||; eigenvalues that are
    negative only by rounding are set to zero, so the returned weight is exactly PSD. Time O(n^3).

    >>> symmetric_psd(np.array([[1.0, 2.0], [2.0, 1.0]]), "noise_cov")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: noise_cov: expected a positive semidefinite matrix, found the eigenvalue -1 ...
    """
    # ||arr|| (an SVD) only where a tolerance needs it: an exactly symmetric matrix (the usual input) has no
    # asymmetry to measure, and no eigenvalue >= 0 is below -PSD_RTOL ||arr|| (the usual PSD weight)
    scale = None
    if not np.array_equal(arr, arr.T):
        scale = float(np.linalg.norm(arr, ord=2))
        if np.linalg.norm(arr - arr.T, ord=2) > SYMMETRY_RTOL * scale:
            raise InputError(field, "expected a symmetric matrix")
    sym = 0.5 * (arr + arr.T)
    vals, vecs = np.linalg.eigh(sym)
    if vals.min() < 0 and vals.min() < -PSD_RTOL * (float(np.linalg.norm(arr, ord=2)) if scale is None else scale):
        raise InputError(field, f"expected a positive semidefinite matrix, found the eigenvalue {vals.min():.3g} "
                                f"beside {vals.max():.3g}")
    if vals.min() < 0:
        sym = (vecs * np.maximum(vals, 0.0)) @ vecs.T
        sym = 0.5 * (sym + sym.T)
    return sym


def _short(value: Any) -> str:
    """A bounded repr (Python refuses str() of integers over 4300 digits)."""
    if isinstance(value, numbers.Integral) and abs(int(value)) >= 10**30:
        return f"(an integer of about {digits(int(value))} digits)"
    return repr(value)[:40]


def horizon_field(value: Any, field: str, n: int, m: int) -> int:
    """N >= 1, and small enough that the per-step weights (N n^2 and N m entries) fit MAX_ENTRIES.

    >>> horizon_field(10, "horizon", 4, 2)
    10
    >>> horizon_field(0, "horizon", 4, 2)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: horizon: expected an integer >= 1, found 0
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(field, f"expected an integer >= 1, found {_short(value)}")
    N = int(value)
    if N < 1:
        raise InputError(field, f"expected an integer >= 1, found {_short(N)}")
    limit = MAX_ENTRIES // max(n * n, m)
    if N > limit:
        shown = N if N < 10**30 else f"an integer of about {digits(N)} digits"
        raise InputError(field, f"expected at most {limit} for n = {n}, m = {m} (horizon * max(n^2, m) <= "
                                f"{MAX_ENTRIES}, what fits in memory), found {shown}")
    return N


def probabilities(arr: np.ndarray, field: str) -> np.ndarray:
    """``arr`` if every entry lies in [0, 1], else a ProbabilityError naming the first one outside.

    >>> probabilities(np.array([0.5, 1.2]), "mu")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.ProbabilityError: mu: expected probabilities in [0, 1], found 1.2
    """
    if np.any(arr < 0.0) or np.any(arr > 1.0):
        bad = arr[(arr < 0.0) | (arr > 1.0)].flat[0]
        raise ProbabilityError(field, f"expected probabilities in [0, 1], found {bad}")
    return arr


def exactly_one(first: Any, second: Any, names: tuple[str, str]) -> None:
    """An InputError naming the pair unless exactly one of ``first`` and ``second`` is given (not None).

    >>> exactly_one(None, None, ("mu", "mu_schedule"))
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: mu/mu_schedule: expected exactly one of the two, found neither
    """
    if (first is None) == (second is None):
        both = "both" if first is not None else "neither"
        raise InputError(f"{names[0]}/{names[1]}", f"expected exactly one of the two, found {both}")


def frozen(arr: np.ndarray) -> np.ndarray:
    """A read-only float copy of ``arr``.

    >>> frozen(np.ones(2)).flags.writeable
    False
    """
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


def weight_sequence(value: Any, field: str, N: int) -> list:
    """``value`` as a list of N per-step weights (a list, tuple or array), else an error naming ``field``.

    >>> len(weight_sequence(np.ones((3, 2)), "state_weights", 3))
    3
    """
    if isinstance(value, np.ndarray):
        value = list(value)
    if not isinstance(value, (list, tuple)):
        raise InputError(field, f"expected a list of {N} weights, found {type(value).__name__}")
    if len(value) != N:
        raise DimensionError(field, f"expected {N} entries (one per step t = 1..N), found {len(value)}")
    return list(value)
