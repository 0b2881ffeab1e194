"""The validated, immutable model: plant, weights, horizon, channel, initial state.

TOML files are read and written by :mod:`packetloss_cvx.io`.

Conventions (paper eq:plant, big):

* ``state_weights[t]`` is Omega_{t+1}, the weight on X_{k+t+1}, t = 0..N-1;
* ``input_weights[t]`` is the diagonal of Psi_t, the weight on U_{k+t};
* ``mu_schedule[t, i]`` is the delivery probability of actuator i at step t;
* ``initial_weight`` is Q, the weight on X_k; ``noise_cov`` is Sigma_W.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np
import numpy.typing as npt

from .channel import GilbertElliott, channel_schedule
from .display import system_html, system_repr, to_json
from .errors import DimensionError, InputError, ProbabilityError
from .statespace import plant_matrices
from .tolerances import PSD_RTOL, SYMMETRY_RTOL
from .validation import MAX_ENTRIES, digits, numeric_array

__all__ = ["System", "check_system", "numeric_array"]

def _shape_error(field: str, expected: str, found: tuple[int, ...]) -> DimensionError:
    return DimensionError(field, f"expected shape {expected} but found {found}")


def _matrix(value: Any, field: str, rows: int | None, cols: int | None, expected: str) -> np.ndarray:
    arr = numeric_array(value, field)
    if arr.ndim != 2 or (rows is not None and arr.shape[0] != rows) or (
        cols is not None and arr.shape[1] != cols
    ):
        raise _shape_error(field, expected, arr.shape)
    return arr


def _vector(value: Any, field: str, length: int, expected: str) -> np.ndarray:
    arr = numeric_array(value, field)
    if arr.shape != (length,):
        raise _shape_error(field, expected, arr.shape)
    return arr


def _psd_weight(value: Any, field: str, n: int) -> np.ndarray:
    """A diagonal (length-n vector) or full n×n symmetric PSD weight, as a matrix."""
    arr = numeric_array(value, field)
    if arr.ndim == 1:
        if arr.shape != (n,):
            raise _shape_error(field, f"({n},) or ({n}, {n})", arr.shape)
        if np.any(arr < 0):
            raise InputError(field, "expected a non-negative diagonal (positive semidefinite weight)")
        return np.diag(arr)
    if arr.shape != (n, n):
        raise _shape_error(field, f"({n},) or ({n}, {n})", arr.shape)
    return _symmetric_psd(arr, field)


def _symmetric_psd(arr: np.ndarray, field: str) -> np.ndarray:
    """Symmetric to SYMMETRY_RTOL and PSD to PSD_RTOL, both relative to ||arr||; eigenvalues that are
    negative only by rounding are set to zero, so the returned weight is exactly PSD."""
    scale = float(np.linalg.norm(arr, ord=2))
    if np.linalg.norm(arr - arr.T, ord=2) > SYMMETRY_RTOL * scale:
        raise InputError(field, "expected a symmetric matrix")
    sym = 0.5 * (arr + arr.T)
    vals, vecs = np.linalg.eigh(sym)
    if vals.min() < -PSD_RTOL * scale:
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


def _horizon(value: Any, field: str, n: int, m: int) -> int:
    """N >= 1, and small enough that the per-step weights (N n^2 and N m entries) fit MAX_ENTRIES."""
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


def _probabilities(arr: np.ndarray, field: str) -> np.ndarray:
    if np.any(arr < 0.0) or np.any(arr > 1.0):
        bad = arr[(arr < 0.0) | (arr > 1.0)].flat[0]
        raise ProbabilityError(field, f"expected probabilities in [0, 1], found {bad}")
    return arr


def _one_of(first: Any, second: Any, names: tuple[str, str]) -> None:
    if (first is None) == (second is None):
        both = "both" if first is not None else "neither"
        raise InputError(f"{names[0]}/{names[1]}", f"expected exactly one of the two, found {both}")


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


class System:
    """A plant behind m Bernoulli packet-loss channels, with an N-step MPC cost.

    Parameters
    ----------
    A, B : array_like
        Plant matrices, n×n and n×m (eq:plant).
    horizon : int
        Prediction horizon N >= 1.
    state_weight, state_weights : array_like
        Omega_t for every t (a length-n diagonal or an n×n symmetric PSD matrix),
        or N such weights for t = 1..N. Exactly one is given.
    input_weight, input_weights : array_like
        Positive diagonal of Psi_t for every t (length m), or N×m for t = 0..N-1.
    mu, mu_schedule, channel : array_like, or a channel.GilbertElliott (or its TOML table)
        Delivery probabilities in [0, 1]: one per actuator, N×m (non-stationary), or a Markov channel's mu_t.
    x0 : array_like
        The state X_k (length n).
    initial_weight : array_like, optional
        Q on X_k (vector or matrix, PSD); default zeros.
    noise_cov : array_like, optional
        Sigma_W (n×n, symmetric PSD); default zeros.
    name : str, optional

    Raises
    ------
    InputError, DimensionError, ProbabilityError
        With the offending field named. All subclass ValueError.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> s.n, s.m, s.horizon
    (1, 1, 3)
    """

    __slots__ = (
        "A", "B", "horizon", "state_weights", "input_weights", "mu_schedule",
        "x0", "initial_weight", "noise_cov", "name", "channel",
    )

    A: np.ndarray
    B: np.ndarray
    horizon: int
    state_weights: np.ndarray
    input_weights: np.ndarray
    mu_schedule: np.ndarray
    x0: np.ndarray
    initial_weight: np.ndarray
    noise_cov: np.ndarray
    name: str | None
    channel: GilbertElliott | None

    def __init__(
        self,
        *,
        A: npt.ArrayLike,
        B: npt.ArrayLike,
        horizon: int,
        x0: npt.ArrayLike,
        state_weight: npt.ArrayLike | None = None,
        state_weights: npt.ArrayLike | None = None,
        input_weight: npt.ArrayLike | None = None,
        input_weights: npt.ArrayLike | None = None,
        mu: npt.ArrayLike | None = None,
        mu_schedule: npt.ArrayLike | None = None,
        initial_weight: npt.ArrayLike | None = None,
        noise_cov: npt.ArrayLike | None = None,
        name: str | None = None,
        channel: Any = None,
    ) -> None:
        A_ = _matrix(A, "A", None, None, "(n, n)")
        n = A_.shape[0]
        if A_.shape != (n, n):
            raise _shape_error("A", "(n, n) (square)", A_.shape)
        if n < 1:
            raise _shape_error("A", "(n, n) with n >= 1", A_.shape)
        B_ = _matrix(B, "B", n, None, f"({n}, m)")
        m = B_.shape[1]
        if m < 1:
            raise _shape_error("B", f"({n}, m) with m >= 1", B_.shape)
        N = _horizon(horizon, "horizon", n, m)

        _one_of(state_weight, state_weights, ("state_weight", "state_weights"))
        if state_weight is not None:
            W = np.repeat(_psd_weight(state_weight, "state_weight", n)[None], N, axis=0)
        else:
            items = _sequence(state_weights, "state_weights", N)
            W = np.stack([_psd_weight(w, f"state_weights[{t}]", n) for t, w in enumerate(items)])

        _one_of(input_weight, input_weights, ("input_weight", "input_weights"))
        if input_weight is not None:
            psi = np.repeat(_vector(input_weight, "input_weight", m, f"({m},)")[None], N, axis=0)
            psi_field = "input_weight"
        else:
            psi = _matrix(input_weights, "input_weights", N, m, f"({N}, {m})")
            psi_field = "input_weights"
        if np.any(psi <= 0):
            raise InputError(psi_field, "expected positive entries (Psi is positive definite)")

        chan, mu_schedule = channel_schedule(channel, m, N, mu, mu_schedule)
        _one_of(mu, mu_schedule, ("mu", "mu_schedule"))
        if mu is not None:
            sched = np.repeat(_probabilities(_vector(mu, "mu", m, f"({m},)"), "mu")[None], N, axis=0)
        else:
            sched = _probabilities(
                _matrix(mu_schedule, "mu_schedule", N, m, f"({N}, {m})"), "mu_schedule"
            )

        x0_ = _vector(x0, "x0", n, f"({n},)")
        Q = np.zeros((n, n)) if initial_weight is None else _psd_weight(initial_weight, "initial_weight", n)
        if noise_cov is None:
            Sigma = np.zeros((n, n))
        else:
            Sigma = _symmetric_psd(_matrix(noise_cov, "noise_cov", n, n, f"({n}, {n})"), "noise_cov")
        if name is not None and not isinstance(name, str):
            raise InputError("name", f"expected a string, found {type(name).__name__}")

        for key, value in (
            ("A", _frozen(A_)), ("B", _frozen(B_)), ("horizon", N),
            ("state_weights", _frozen(W)), ("input_weights", _frozen(psi)),
            ("mu_schedule", _frozen(sched)), ("x0", _frozen(x0_)),
            ("initial_weight", _frozen(Q)), ("noise_cov", _frozen(Sigma)), ("name", name), ("channel", chan),
        ):
            object.__setattr__(self, key, value)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("System is immutable: use with_mu / with_x0 for a modified copy")

    __repr__ = system_repr      # the headline numbers, not the arrays (display.py)
    _repr_html_ = system_html
    to_json = to_json

    @property
    def n(self) -> int:
        """State dimension."""
        return self.A.shape[0]

    @property
    def m(self) -> int:
        """Number of actuators (channels)."""
        return self.B.shape[1]

    @property
    def is_stationary(self) -> bool:
        """True when every step has the same delivery probabilities."""
        return bool(np.all(self.mu_schedule == self.mu_schedule[0]))

    @property
    def mu(self) -> np.ndarray:
        """The stationary delivery probabilities (raises for a non-stationary channel)."""
        if not self.is_stationary:
            raise ValueError("mu: the channel is non-stationary; use mu_schedule")
        return self.mu_schedule[0]

    def _copy_with(self, **fields: Any) -> System:
        """A copy with already-validated fields replaced (no re-validation of the rest)."""
        new = object.__new__(System)
        for key in self.__slots__:
            object.__setattr__(new, key, fields.get(key, getattr(self, key)))
        return new

    def with_mu(self, mu: npt.ArrayLike) -> System:
        """A copy with new delivery probabilities: an m-vector or an N×m schedule (drops a Markov channel).

        Examples
        --------
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> s.with_mu([0.9]).mu_schedule.ravel().tolist(), s.with_mu([[0.2], [0.4]]).mu_schedule.ravel().tolist()
        ([0.9, 0.9], [0.2, 0.4])
        >>> s.mu_schedule.ravel().tolist()          # the original is unchanged (immutable)
        [0.5, 0.5]
        """
        N, m = self.horizon, self.m
        if np.ndim(mu) == 2:
            sched = _probabilities(_matrix(mu, "mu_schedule", N, m, f"({N}, {m})"), "mu_schedule")
        else:
            vec = _probabilities(_vector(mu, "mu", m, f"({m},)"), "mu")
            sched = np.repeat(vec[None], N, axis=0)
        return self._copy_with(mu_schedule=_frozen(sched), channel=None)

    @classmethod
    def from_statespace(cls, sys: Any, **fields: Any) -> System:
        """A System with the A, B of a discrete-time control.StateSpace (statespace.plant_matrices) and ``fields``."""
        taken = sorted(set(fields) & {"A", "B"})
        if taken:
            raise InputError(taken[0], "given by sys: from_statespace takes A and B from the StateSpace")
        return cls(**plant_matrices(sys), **fields)

    def with_x0(self, x0: npt.ArrayLike) -> System:
        """A copy with a new initial state.

        Examples
        --------
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> s.with_x0([2.0]).x0.tolist(), s.x0.tolist()
        ([2.0], [1.0])
        """
        return self._copy_with(x0=_frozen(_vector(x0, "x0", self.n, f"({self.n},)")))

    def to_dict(self) -> dict[str, Any]:
        """The system in the TOML schema's structure (plain lists), e.g. for JSON.

        Examples
        --------
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> d = s.to_dict()
        >>> d["cost"]["horizon"], d["cost"]["state_weight"], d["plant"]["A"]
        (2, [1.0], [[1.0]])
        """
        def weight(mat: np.ndarray) -> list:
            return np.diag(mat).tolist() if np.allclose(mat, np.diag(np.diag(mat)), rtol=0, atol=0) else mat.tolist()

        cost: dict[str, Any] = {"horizon": self.horizon}
        if np.all(self.state_weights == self.state_weights[0]):
            cost["state_weight"] = weight(self.state_weights[0])
        else:
            cost["state_weights"] = [weight(w) for w in self.state_weights]
        if np.all(self.input_weights == self.input_weights[0]):
            cost["input_weight"] = self.input_weights[0].tolist()
        else:
            cost["input_weights"] = self.input_weights.tolist()
        cost["initial_weight"] = weight(self.initial_weight)
        channel = self.channel.to_dict() if self.channel is not None else (
            {"mu": self.mu_schedule[0].tolist()} if self.is_stationary
            else {"mu_schedule": self.mu_schedule.tolist()}
        )
        out: dict[str, Any] = {
            "plant": {"A": self.A.tolist(), "B": self.B.tolist(), "noise_cov": self.noise_cov.tolist()},
            "cost": cost,
            "channel": channel,
            "state": {"x0": self.x0.tolist()},
        }
        if self.name:
            out = {"name": self.name, **out}
        return out


def _sequence(value: Any, field: str, N: int) -> list:
    if isinstance(value, np.ndarray):
        value = list(value)
    if not isinstance(value, (list, tuple)):
        raise InputError(field, f"expected a list of {N} weights, found {type(value).__name__}")
    if len(value) != N:
        raise DimensionError(field, f"expected {N} entries (one per step t = 1..N), found {len(value)}")
    return list(value)


def check_system(system: Any, field: str = "system") -> System:
    """``system`` if it is a :class:`System`; otherwise an InputError saying how to make one.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> check_system(s) is s
    True
    >>> check_system({"A": [[1.0]]})
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: system: expected a System (...), found dict
    """
    if not isinstance(system, System):
        raise InputError(field, f"expected a System (packetloss_cvx.System(...), load_system(path) or "
                                f"load_example(name)), found {type(system).__name__}")
    return system
