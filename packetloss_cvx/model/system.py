"""The validated, immutable model: plant, weights, horizon, channel, initial state.

TOML files are read and written by [`packetloss_cvx.model.files`][packetloss_cvx.model.files].

Conventions (paper eq:plant, big):

* ``state_weights[t]`` is Omega_{t+1}, the weight on X_{k+t+1}, t = 0..N-1;
* ``input_weights[t]`` is the diagonal of Psi_t, the weight on U_{k+t};
* ``mu_schedule[t, i]`` is the delivery probability of actuator i at step t;
* ``initial_weight`` is Q, the weight on X_k; ``noise_cov`` is Sigma_W.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from ..display import system_html, system_repr, to_json
from ..errors import InputError
from .channel import (
    GilbertElliott,  # noqa: F401 (GilbertElliott: the doctests' constructor)
    MarkovChannel,
    channel_schedule,
)
from .sensor import Sensor
from .statespace import labels_field, plant_matrices, plant_statespace, sampling_time
from .validation import (
    diagonal_weight,
    every_channel,
    exactly_one,
    frozen,
    horizon_field,
    matrix_field,
    numeric_array,
    probabilities,
    psd_weight,
    psd_weights,
    shape_error,
    symmetric_psd,
    vector_field,
    weight_alias,
    weight_sequence,
)

__all__ = ["STRUCTURE_CACHE_MAX_BYTES", "STRUCTURE_FIELDS", "SYSTEM_FIELDS", "CacheKey", "StructureStore", "System",
           "SystemStore", "check_system", "loop_weights", "numeric_array"]

T = TypeVar("T")

#: The fields a derived quantity kept in a :class:`StructureStore` may depend on: what ``with_mu``, ``with_x0``,
#: ``with_channel`` and ``with_sensor`` keep (they replace only mu_schedule, channel, x0 and sensor).
STRUCTURE_FIELDS = ("A", "B", "horizon", "state_weights", "input_weights", "initial_weight", "noise_cov")
#: A value larger than this is rebuilt on each call rather than kept for the system's life (a long horizon's
#: dense (N n)×(N m) prediction matrices): :meth:`StructureStore.put`.
STRUCTURE_CACHE_MAX_BYTES = 8 * 2**20
#: Every field of a System (what a :class:`CacheKey` may say its value depends on).
SYSTEM_FIELDS = (*STRUCTURE_FIELDS, "mu_schedule", "x0", "channel", "name", "dt", "sensor", "input_labels",
                 "state_labels")


@dataclass(frozen=True, eq=False)
class CacheKey:
    """One quantity derived from a [`System`][packetloss_cvx.model.system.System]: the key of a `StructureStore` or a
        `SystemStore`.

    A key is a typed object, declared once by the module that builds the quantity, and compared by
    identity: two modules cannot collide on a name, and a key says which fields of the system its value
    depends on (``depends_on``, names from `SYSTEM_FIELDS`). A key whose fields are all in
    `STRUCTURE_FIELDS` may be kept in a `StructureStore` (shared by ``with_mu``, ``with_x0`` and
    ``with_channel`` copies); any other only per system (`SystemStore`). ``tests/lq/test_cache_keys.py`` holds
    every key of the package to what it says. ``name`` is for reading (repr, errors) only.

    Examples
    --------
    >>> square = CacheKey("demo.square", ("A",))
    >>> square.structural, CacheKey("demo.mu", ("mu_schedule",)).structural
    (True, False)
    >>> CacheKey("demo.square", ("A",)) == square      # identity: another declaration is another key
    False
    """

    name: str
    depends_on: frozenset[str]

    def __init__(self, name: str, depends_on: Iterable[str]) -> None:
        fields = frozenset(depends_on)
        unknown = sorted(fields - set(SYSTEM_FIELDS))
        if not isinstance(name, str) or not name or unknown or not fields:
            raise InputError("depends_on", f"a cache key needs a name and fields of System {SYSTEM_FIELDS}, "
                                           f"found {name!r} depending on {sorted(fields)}")
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "depends_on", fields)

    @property
    def structural(self) -> bool:
        """True when the value depends only on `STRUCTURE_FIELDS` (shared with with_mu/x0/channel copies)."""
        return self.depends_on <= set(STRUCTURE_FIELDS)

    def __repr__(self) -> str:
        return f"CacheKey({self.name!r}, depends_on={sorted(self.depends_on)})"


class _Token:
    """An identity that systems hand to the stores of the layers above
    ([`System.structure_token`][packetloss_cvx.model.system.System.structure_token],
    [`System.own_token`][packetloss_cvx.model.system.System.own_token]): weakly referable, nothing else."""

    __slots__ = ("__weakref__",)


class _Store:
    """Values derived from systems, kept by the module that builds them (not on the System), weakly keyed by a
    token of the system: the value lives as long as the token's systems do. `get` then `put` on a
    miss: no callback into the System. A value must not refer to a system (it would keep its key alive); arrays in
    it are read-only (it is shared). O(1)."""

    __slots__ = ("key", "max_bytes", "_values")

    def __init__(self, key: CacheKey, max_bytes: int = STRUCTURE_CACHE_MAX_BYTES) -> None:
        self.key, self.max_bytes = _key(key), max_bytes
        self._values: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    @staticmethod
    def _token(system: System) -> _Token:
        raise NotImplementedError

    def get(self, system: System) -> Any:
        """The value kept for ``system``, or None. O(1)."""
        return self._values.get(self._token(system))

    def put(self, system: System, value: T, nbytes: int = 0) -> T:
        """Keep ``value`` for ``system`` (unless ``nbytes`` exceeds the store's ``max_bytes``: then it is returned and
        not kept) and return the value kept: the first one, if another thread kept one meanwhile. O(1)."""
        if nbytes > self.max_bytes:
            return value
        return self._values.setdefault(self._token(system), value)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.key!r})"


class StructureStore(_Store):
    """Values that depend only on a system's structure (`STRUCTURE_FIELDS`), one store per quantity declared
    beside its builder with the quantity's `CacheKey`, keyed by
    [`System.structure_token`][packetloss_cvx.model.system.System.structure_token] (shared by ``with_mu``, ``with_x0``,
    ``with_channel`` and ``with_sensor`` copies): a value is never found by another structure. A key that names a field
    outside the structure is a TypeError (use `SystemStore`).

    Examples
    --------
    >>> SQUARE = StructureStore(CacheKey("demo.square", ("A",)))
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> SQUARE.get(s) is None
    True
    >>> SQUARE.put(s, float(s.A[0, 0]) ** 2), SQUARE.get(s.with_mu([0.9]))       # with_mu keeps A
    (4.0, 4.0)
    >>> StructureStore(CacheKey("demo.mu", ("mu_schedule",)))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    TypeError: CacheKey('demo.mu', ...) depends on more than the structure: keep it in a SystemStore
    """

    __slots__ = ()

    def __init__(self, key: CacheKey, max_bytes: int = STRUCTURE_CACHE_MAX_BYTES) -> None:
        super().__init__(key, max_bytes)
        if not key.structural:
            raise TypeError(f"{key!r} depends on more than the structure: keep it in a SystemStore")

    @staticmethod
    def _token(system: System) -> _Token:
        return system.structure_token


class SystemStore(_Store):
    """Values of one system (any field may enter them: the system is immutable, and every copy has its own
    [`System.own_token`][packetloss_cvx.model.system.System.own_token]), one store per quantity declared beside its
    builder with its `CacheKey`.

    Examples
    --------
    >>> MU = SystemStore(CacheKey("demo.mu", ("mu_schedule",)))
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> MU.put(s, float(s.mu[0])), MU.get(s), MU.get(s.with_mu([0.9])) is None
    (0.5, 0.5, True)
    """

    __slots__ = ()

    @staticmethod
    def _token(system: System) -> _Token:
        return system.own_token


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
        Positive diagonal of Psi_t for every t (length m, or a diagonal m×m matrix), or N×m for t = 0..N-1.
        Psi must be diagonal: the cost weighs the applied input V u (V = diag(v), v_i = 1 when channel i
        delivers), and the paper's closed forms (Lemma 1, Theorem 1) use E[(V u)' Psi (V u)] = u' Vbar Psi u,
        true for a diagonal Psi only (a full Psi adds the cross terms Psi_ij mu_i mu_j u_i u_j of two channels'
        deliveries, which no kernel of this package carries). A full matrix is refused, saying so.
    Q, R : array_like, optional
        python-control's names (``control.lqr(sys, Q, R)``): ``Q`` is ``state_weight`` (Omega_t, the stage
        weight on the state) and ``R`` is ``input_weight`` (Psi_t). Give each weight once: ``Q`` beside
        ``state_weight`` or ``state_weights`` (or ``R`` beside ``input_weight`` or ``input_weights``) is refused.
        The paper's Q, the weight on X_k, is ``initial_weight``.
    mu, mu_schedule, channel : array_like, or a channel.MarkovChannel (GilbertElliott(...)) or a TOML table
        Delivery probabilities in [0, 1]: one per actuator (one number: every actuator, as ``--mu 0.5`` on the
        command line), N×m (non-stationary), or a Markov channel's mu_t.
    x0 : array_like
        The state X_k (length n).
    initial_weight : array_like, optional
        Q on X_k (vector or matrix, PSD); default zeros.
    noise_cov : array_like, optional
        Sigma_W (n×n, symmetric PSD); default zeros.
    name : str, optional
    dt : float, optional
        Sampling time in seconds (python-control interop), metadata: nothing depends on it. None: unspecified.
    sensor : sensor.Sensor or its TOML table, optional
        Measurements over lossy sensor links (packetloss_cvx.sensing). None: the full state is known
        (the paper's model); every computation that ignores the sensor is the same with or without one.
    input_labels, state_labels : list of str, optional
        Names of the m inputs and the n states (python-control's ``inputs`` / ``states``), metadata kept through
        [`from_statespace`][packetloss_cvx.model.system.System.from_statespace] and
        [`to_statespace`][packetloss_cvx.model.system.System.to_statespace]; nothing depends on them. None: unnamed.

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

    python-control's names, and one mu for every channel:

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=3, Q=np.eye(2), R=np.diag([1.0, 2.0]), mu=0.5, x0=[1.0, 1.0])
    >>> t.input_weights[0].tolist(), t.mu.tolist()
    ([1.0, 2.0], [0.5, 0.5])
    """

    __slots__ = (
        "A", "B", "horizon", "state_weights", "input_weights", "mu_schedule",
        "x0", "initial_weight", "noise_cov", "name", "channel", "dt", "sensor", "input_labels", "state_labels",
        "_structure", "_own",
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
    channel: MarkovChannel | None
    dt: float | None
    sensor: Sensor | None
    input_labels: tuple[str, ...] | None
    state_labels: tuple[str, ...] | None

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
        dt: float | None = None,
        sensor: Any = None,
        Q: npt.ArrayLike | None = None,
        R: npt.ArrayLike | None = None,
        input_labels: Any = None,
        state_labels: Any = None,
    ) -> None:
        state_weight = weight_alias("Q", Q, "state_weight", state_weight, state_weights)
        input_weight = weight_alias("R", R, "input_weight", input_weight, input_weights)
        A_ = matrix_field(A, "A", None, None, "(n, n)")
        n = A_.shape[0]
        if A_.shape != (n, n):
            raise shape_error("A", "(n, n) (square)", A_.shape)
        if n < 1:
            raise shape_error("A", "(n, n) with n >= 1", A_.shape)
        B_ = matrix_field(B, "B", n, None, f"({n}, m)")
        m = B_.shape[1]
        if m < 1:
            raise shape_error("B", f"({n}, m) with m >= 1", B_.shape)
        N = horizon_field(horizon, "horizon", n, m)

        exactly_one(state_weight, state_weights, ("state_weight", "state_weights"))
        if state_weight is not None:
            W = np.repeat(psd_weight(state_weight, "state_weight", n)[None], N, axis=0)
        else:
            items = weight_sequence(state_weights, "state_weights", N)
            W = psd_weights(items, "state_weights", n)

        exactly_one(input_weight, input_weights, ("input_weight", "input_weights"))
        if input_weight is not None:
            field = "R" if R is not None else "input_weight"
            psi = np.repeat(diagonal_weight(input_weight, field, m)[None], N, axis=0)
            psi_field = field
        else:
            psi = matrix_field(input_weights, "input_weights", N, m, f"({N}, {m})")
            psi_field = "input_weights"
        if np.any(psi <= 0):
            raise InputError(psi_field, "expected positive entries (Psi is positive definite)")

        chan, mu_schedule = channel_schedule(channel, m, N, mu, mu_schedule)
        exactly_one(mu, mu_schedule, ("mu", "mu_schedule"))
        if mu is not None:
            sched = np.repeat(probabilities(vector_field(every_channel(mu, m), "mu", m, f"({m},)"), "mu")[None],
                              N, axis=0)
        else:
            sched = probabilities(
                matrix_field(mu_schedule, "mu_schedule", N, m, f"({N}, {m})"), "mu_schedule"
            )

        x0_ = vector_field(x0, "x0", n, f"({n},)")
        Q = np.zeros((n, n)) if initial_weight is None else psd_weight(initial_weight, "initial_weight", n)
        if noise_cov is None:
            Sigma = np.zeros((n, n))
        else:
            Sigma = symmetric_psd(matrix_field(noise_cov, "noise_cov", n, n, f"({n}, {n})"), "noise_cov")
        if name is not None and not isinstance(name, str):
            raise InputError("name", f"expected a string, found {type(name).__name__}")
        sensor_ = sensor_field(sensor, n)
        inputs_, states_ = labels_field(input_labels, "input_labels", m), labels_field(state_labels, "state_labels", n)

        for key, value in (
            ("A", frozen(A_)), ("B", frozen(B_)), ("horizon", N),
            ("state_weights", frozen(W)), ("input_weights", frozen(psi)),
            ("mu_schedule", frozen(sched)), ("x0", frozen(x0_)),
            ("initial_weight", frozen(Q)), ("noise_cov", frozen(Sigma)), ("name", name), ("channel", chan),
            ("dt", sampling_time(dt)), ("sensor", sensor_), ("input_labels", inputs_), ("state_labels", states_),
            ("_structure", _Token()),
            ("_own", _Token()),
        ):
            object.__setattr__(self, key, value)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("System is immutable: use with_mu / with_x0 for a modified copy")

    def __copy__(self) -> System:
        return self          # immutable, its arrays read-only: a copy is the system itself

    def __deepcopy__(self, memo: dict) -> System:
        return self

    def __reduce__(self) -> tuple:
        """Pickling (multiprocessing, joblib, Dask) rebuilds the system through the validating
        constructor from its fields; the cached structure is not sent. O(N (n^2 + m))."""
        fields = {"A": self.A, "B": self.B, "horizon": self.horizon, "x0": self.x0,
                  "state_weights": self.state_weights, "input_weights": self.input_weights,
                  "initial_weight": self.initial_weight, "noise_cov": self.noise_cov, "name": self.name, "dt": self.dt}
        if self.sensor is not None:
            fields["sensor"] = self.sensor
        for key in ("input_labels", "state_labels"):
            if getattr(self, key) is not None:
                fields[key] = getattr(self, key)
        if self.channel is not None:
            fields["channel"] = self.channel
        else:
            fields["mu_schedule"] = self.mu_schedule
        return _from_fields, (fields,)

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
        """A copy with already-validated fields replaced (no re-validation of the rest). The copy shares
        the [`structure_token`][packetloss_cvx.model.system.System.structure_token] unless a field of STRUCTURE_FIELDS
        is replaced."""
        new = object.__new__(System)
        for key in self.__slots__:
            object.__setattr__(new, key, fields.get(key, getattr(self, key)))
        if "_structure" in fields or any(key in fields for key in STRUCTURE_FIELDS):
            object.__setattr__(new, "_structure", _Token())
        object.__setattr__(new, "_own", _Token())
        return new

    @property
    def structure_token(self) -> object:
        """An object this system shares with its copies of the same structure (``with_mu``, ``with_x0``,
        ``with_channel``, ``with_sensor``) and with no other system: the weak key of every
        `StructureStore`. O(1)."""
        return self._structure

    @property
    def own_token(self) -> object:
        """An object of this system alone (every copy gets its own): the weak key of every `SystemStore`.
        O(1)."""
        return self._own

    def with_mu(self, mu: npt.ArrayLike) -> System:
        """A copy with new delivery probabilities: an m-vector (one number: every channel) or an N×m schedule
        (drops a Markov channel).

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
            sched = probabilities(matrix_field(mu, "mu_schedule", N, m, f"({N}, {m})"), "mu_schedule")
        else:
            vec = probabilities(vector_field(every_channel(mu, m), "mu", m, f"({m},)"), "mu")
            sched = np.repeat(vec[None], N, axis=0)
        return self._copy_with(mu_schedule=frozen(sched), channel=None)

    @classmethod
    def from_statespace(cls, sys: Any, **fields: Any) -> System:
        """A System with the A, B and sampling time dt of a discrete-time control.StateSpace
        (statespace.plant_matrices; python-control's ``dt = True`` is None) and ``fields``; its name and signal
        names (``input_labels``, ``state_labels``) where the StateSpace has its own (``fields`` may rename).
        O(n (n + m))."""
        taken = sorted(set(fields) & {"A", "B", "dt"})
        if taken:
            raise InputError(taken[0], "given by sys: from_statespace takes A, B and dt from the StateSpace")
        return cls(**{**plant_matrices(sys), **fields})

    def to_statespace(self) -> Any:
        """The plant as a discrete-time control.StateSpace (statespace.plant_statespace): A, B, C = I, D = 0 and
        the system's ``dt`` (True when None), named as the system and its signals where they are named; every
        packet delivered. O(n (n + m))."""
        return plant_statespace(self.A, self.B, self.dt, self.name, self.input_labels, self.state_labels)

    def with_x0(self, x0: npt.ArrayLike) -> System:
        """A copy with a new initial state.

        Examples
        --------
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> s.with_x0([2.0]).x0.tolist(), s.x0.tolist()
        ([2.0], [1.0])
        """
        return self._copy_with(x0=frozen(vector_field(x0, "x0", self.n, f"({self.n},)")))

    def with_channel(self, channel: Any) -> System:
        """A copy behind the Markov ``channel`` (a MarkovChannel, e.g. GilbertElliott(...), or a TOML table): its
        mu_schedule is the channel's predicted schedule. The channel and that schedule are validated as
        ``System(..., channel=channel)`` validates them; the other fields, already validated, are kept.
        Time O(N m).

        Examples
        --------
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> s.with_channel(GilbertElliott(p=[0.1], r=[0.3], state=["bad"])).mu_schedule[:, 0].tolist()
        [0.0, 0.3]
        >>> s.with_channel(GilbertElliott(p=[0.1, 0.2], r=[0.3, 0.3]))  # doctest: +ELLIPSIS
        Traceback (most recent call last):
            ...
        packetloss_cvx.errors.DimensionError: channel.p: expected 1 channels (one per actuator, ...) but found 2
        """
        if channel is None:
            raise InputError("channel", "expected a Markov channel, found None (with_mu sets mu without one)")
        N, m = self.horizon, self.m
        chan, schedule = channel_schedule(channel, m, N, None, None)
        sched = probabilities(matrix_field(schedule, "mu_schedule", N, m, f"({N}, {m})"), "mu_schedule")
        return self._copy_with(mu_schedule=frozen(sched), channel=chan)

    def with_sensor(self, sensor: Any) -> System:
        """A copy measuring through ``sensor`` (a sensor.Sensor or its TOML table; None: full state). Time O(n^3).

        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> s.with_sensor({"C": [[1.0]], "gamma": [0.9]}).sensor.gamma.tolist(), s.sensor is None
        ([0.9], True)
        """
        return self._copy_with(sensor=sensor_field(sensor, self.n))

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
            return np.diag(mat).tolist() if np.array_equal(mat, np.diag(np.diag(mat))) else mat.tolist()   # finite

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
            "plant": {"A": self.A.tolist(), "B": self.B.tolist(), "noise_cov": self.noise_cov.tolist(),
                      **({"dt": self.dt} if self.dt is not None else {}),
                      **({"input_labels": list(self.input_labels)} if self.input_labels is not None else {}),
                      **({"state_labels": list(self.state_labels)} if self.state_labels is not None else {})},
            "cost": cost,
            "channel": channel,
            "state": {"x0": self.x0.tolist()},
        }
        if self.sensor is not None:
            out["sensor"] = self.sensor.to_dict()
            out["state"]["P0"] = self.sensor.P0.tolist()
        if self.name:
            out = {"name": self.name, **out}
        return out


def sensor_field(sensor: Any, n: int) -> Sensor | None:
    """The System's ``sensor``: None, a [`Sensor`][packetloss_cvx.model.sensor.Sensor] or its TOML table (with
    ``P0`` as a key), its C of width n (else a DimensionError naming ``sensor.C``). O(p^3 + n^3).

    >>> sensor_field({"C": [[1.0, 0.0]], "gamma": [0.5]}, 1)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.DimensionError: sensor.C: expected shape (p, 1) (one column per state) but found (1, 2)
    """
    if sensor is None:
        return None
    if isinstance(sensor, Mapping):
        table = {k: v for k, v in sensor.items() if k != "P0"}
        return Sensor.from_table(table, sensor.get("P0"), n=n)
    if not isinstance(sensor, Sensor):
        raise InputError("sensor", f"expected a packetloss_cvx.Sensor or its table, found {type(sensor).__name__}")
    if sensor.n != n:
        raise shape_error("sensor.C", f"(p, {n}) (one column per state)", sensor.C.shape)
    return sensor


def _key(key: Any) -> CacheKey:
    """``key`` if it is a `CacheKey`; a TypeError otherwise (a string key would couple modules by name)."""
    if not isinstance(key, CacheKey):
        raise TypeError(f"a cache key is a model.CacheKey declared by the module that builds the value, "
                        f"found {type(key).__name__} {key!r}")
    return key


def check_system(system: Any, field: str = "system") -> System:
    """``system`` if it is a [`System`][packetloss_cvx.model.system.System]; otherwise an InputError saying how to make
        one.

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


def loop_weights(system: System, field: str = "state_weights") -> tuple[np.ndarray, np.ndarray]:
    """The one stage weight ``(Omega, psi)`` of a loop's cost (a closed loop, a law's cost over an unbounded or
    another horizon, the DP's cost-to-go), refusing time-varying weights: such a cost needs one weight for every step
    of a loop that runs past the horizon, and a plan's weights (``state_weights``, ``input_weights``) speak of the
    steps of the plan, not of the loop. ``field`` names the state weights in the message (the command line's
    ``cost.state_weights``); the input weights are named alike. O(N (n^2 + m)).

    Raises
    ------
    InputError
        Weights that change along the horizon.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weights=[[1.0], [2.0]], input_weight=[1.0], mu=[0.5],
    ...            x0=[1.0])
    >>> loop_weights(s)
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: state_weights: the loop's stage cost needs one weight for every step; \
time-varying weights speak of the plan's steps: give one state_weight
    >>> one = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[3.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> [w.tolist() for w in loop_weights(one)]
    [[[3.0]], [1.0]]
    """
    for weights, name in ((system.state_weights, field), (system.input_weights, field.replace("state", "input"))):
        if not np.all(weights == weights[0]):
            single = name.rsplit(".", 1)[-1].removesuffix("s")
            raise InputError(name, "the loop's stage cost needs one weight for every step; time-varying weights "
                                   f"speak of the plan's steps: give one {single}")
    return system.state_weights[0], system.input_weights[0]


def _from_fields(fields: dict[str, Any]) -> System:
    """`System.__reduce__`'s rebuild: the constructor, which validates every field again."""
    return System(**fields)
