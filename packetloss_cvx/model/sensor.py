"""Lossy sensor links: the validated, immutable description of what the controller measures.

Measurements ``y_k = C x_k + r_k``, ``r_k ~ N(0, R)`` (R = ``noise_cov``), are sent over g sensor channels,
channel j carrying the output rows ``groups[j]`` and delivering them with probability ``gamma[j]``
(Bernoulli, independent across channels, steps and of the actuator links), or through a Gilbert–Elliott
chain per channel (``model = "gilbert-elliott"``, the keys of ``[channel]``:
[`packetloss_cvx.model.channel`][packetloss_cvx.model.channel]), whose long-run rate is then ``gamma``. The initial
state is ``x_0 ~ N(x0, P0)``.

TOML (docs/design.md §4; docs/mathematics.md, "Lossy sensors")::

    [sensor]
    C = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
    noise_cov = [[1e-4, 0.0], [0.0, 1e-4]]     # R, optional, default zeros
    gamma = [0.8]                               # one per channel (group)
    # groups = [[0], [1]]                       # output rows per channel; default one channel for all rows
    # model = "gilbert-elliott"                 # instead of gamma: p, r, h_good, h_bad, state/belief per channel
    [state]
    x0 = [...]
    P0 = [[...]]                                # optional, default zeros (x0 known)

A System without a sensor measures its full state without loss (the paper's model).
Every error names its field (``sensor.C``, ``sensor.gamma``, ``state.P0``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DimensionError, InputError
from .channel import MarkovChannel
from .validation import frozen, matrix_field, probabilities, shape_error, symmetric_psd, vector_field

__all__ = ["SENSOR_KEYS", "Sensor"]

#: The keys of the TOML ``[sensor]`` table (the Gilbert–Elliott keys as in ``[channel]``).
SENSOR_KEYS = ("C", "noise_cov", "gamma", "groups", "model", "p", "r", "h_good", "h_bad", "state", "belief")
_MARKOV_KEYS = ("model", "p", "r", "h_good", "h_bad", "state", "belief")


def _groups(value: Any, p: int) -> tuple[tuple[int, ...], ...]:
    """The output rows of each channel: lists of row indices covering 0..p-1 exactly once."""
    if value is None:
        return (tuple(range(p)),)
    if not isinstance(value, (list, tuple)) or not value:
        raise InputError("sensor.groups", "expected a non-empty list of lists of output rows, found "
                                          f"{str(value)[:40]!r}")
    out, seen = [], []
    for j, rows in enumerate(value):
        if not isinstance(rows, (list, tuple)) or not rows:
            raise InputError("sensor.groups", f"channel {j}: expected a non-empty list of output rows, found "
                                              f"{str(rows)[:40]!r}")
        for row in rows:
            if isinstance(row, bool) or not isinstance(row, (int, np.integer)) or not 0 <= row < p:
                raise InputError("sensor.groups", f"channel {j}: expected output rows 0..{p - 1} (rows of C), "
                                                  f"found {str(row)[:20]!r}")
        out.append(tuple(int(r) for r in rows))
        seen += out[-1]
    if sorted(seen) != list(range(p)):
        twice = sorted({r for r in seen if seen.count(r) > 1})
        missing = sorted(set(range(p)) - set(seen))
        what = f"row {twice[0]} in two channels" if twice else f"row {missing[0]} in none"
        raise InputError("sensor.groups", f"expected every output row 0..{p - 1} in exactly one channel, found {what}")
    return tuple(out)


class Sensor:
    """Measurements ``y = C x + r`` sent over g lossy sensor channels.

    Parameters
    ----------
    C : array_like
        p×n output matrix (n: the plant's state dimension, checked by the System).
    gamma : array_like, optional
        Delivery probability of each channel (length g), in [0, 1]. Exactly one of ``gamma`` and ``channel``.
    noise_cov : array_like, optional
        R (p×p, symmetric PSD), default zeros.
    groups : list of lists of int, optional
        The output rows each channel carries; together every row exactly once. Default: one channel.
    channel : GilbertElliott or its TOML table, optional
        Bursty sensor links (one chain per channel); ``gamma`` is then the chain's long-run rate.
    P0 : array_like, optional
        Covariance of the initial state (n×n, symmetric PSD), default zeros (x0 known).
    n : int, optional
        The plant's state dimension, when known: C of another width is a DimensionError naming ``sensor.C``.

    Raises
    ------
    InputError, DimensionError, ProbabilityError
        Naming the field (``sensor.C``, ``sensor.noise_cov``, ``sensor.gamma``, ``sensor.groups``, ``state.P0``).

    Examples
    --------
    >>> s = Sensor(C=[[1.0, 0.0], [0.0, 1.0]], gamma=[0.9, 0.5], groups=[[0], [1]])
    >>> s.p, s.n, s.g, s.groups
    (2, 2, 2, ((0,), (1,)))
    >>> Sensor(C=[[1.0, 0.0]], gamma=[1.5])
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.ProbabilityError: sensor.gamma: expected probabilities in [0, 1], found 1.5
    """

    __slots__ = ("C", "noise_cov", "gamma", "groups", "channel", "P0")

    C: np.ndarray
    noise_cov: np.ndarray
    gamma: np.ndarray
    groups: tuple[tuple[int, ...], ...]
    channel: MarkovChannel | None
    P0: np.ndarray

    def __init__(self, *, C: npt.ArrayLike, gamma: npt.ArrayLike | None = None, noise_cov: npt.ArrayLike | None = None,
                 groups: Any = None, channel: Any = None, P0: npt.ArrayLike | None = None,
                 n: int | None = None) -> None:
        C_ = matrix_field(C, "sensor.C", None, n, "(p, n)" if n is None else f"(p, {n}) (one column per state)")
        p, n = C_.shape
        if p < 1 or n < 1:
            raise shape_error("sensor.C", "(p, n) with p, n >= 1", C_.shape)
        R = np.zeros((p, p)) if noise_cov is None else symmetric_psd(
            matrix_field(noise_cov, "sensor.noise_cov", p, p, f"({p}, {p})"), "sensor.noise_cov")
        groups_ = _groups(groups, p)
        g = len(groups_)
        if (gamma is None) == (channel is None):
            raise InputError("sensor.gamma", "expected exactly one of gamma and model = \"gilbert-elliott\", found "
                                             + ("both" if gamma is not None else "neither"))
        chan = None
        if channel is not None:
            chan = (channel if isinstance(channel, MarkovChannel) else
                    MarkovChannel.gilbert_elliott_table(channel, "sensor."))
            if not chan.two_state:
                raise InputError("sensor.channel", f"expected Gilbert-Elliott (two-state) links, found chains of "
                                                   f"{list(chan.sizes)} states")
            if chan.m != g:
                raise DimensionError("sensor.p", f"expected {g} channels (one per group) but found {chan.m}")
            gamma_ = np.array(chan.mean_rate, dtype=float)
        else:
            gamma_ = probabilities(vector_field(gamma, "sensor.gamma", g, f"({g},) (one per channel)"), "sensor.gamma")
        P0_ = np.zeros((n, n)) if P0 is None else symmetric_psd(
            matrix_field(P0, "state.P0", n, n, f"({n}, {n})"), "state.P0")
        for key, value in (("C", frozen(C_)), ("noise_cov", frozen(R)), ("gamma", frozen(gamma_)),
                           ("groups", groups_), ("channel", chan), ("P0", frozen(P0_))):
            object.__setattr__(self, key, value)

    @classmethod
    def from_table(cls, table: Mapping[str, Any], P0: Any = None, n: int | None = None) -> Sensor:
        """Build from the TOML ``[sensor]`` table (keys `SENSOR_KEYS`) and ``[state] P0``.

        Examples
        --------
        >>> s = Sensor.from_table({"C": [[1.0]], "gamma": [0.7]})
        >>> Sensor.from_table(s.to_dict()).gamma.tolist()
        [0.7]
        """
        if not isinstance(table, Mapping):
            raise InputError("sensor", f"expected a table, found {type(table).__name__}")
        unknown = [k for k in table if k not in SENSOR_KEYS]
        if unknown:
            raise InputError(f"sensor.{unknown[0]}", f"unknown key; expected one of {', '.join(SENSOR_KEYS)}")
        if "C" not in table:
            raise InputError("sensor.C", "missing field")
        markov = {k: table[k] for k in _MARKOV_KEYS if k in table}
        return cls(C=table["C"], gamma=table.get("gamma"), noise_cov=table.get("noise_cov"),
                   groups=table.get("groups"), channel=markov or None, P0=P0, n=n)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("Sensor is immutable: build a new one")

    def __copy__(self) -> Sensor:
        return self

    def __deepcopy__(self, memo: dict) -> Sensor:
        return self

    def __reduce__(self) -> tuple:
        """Pickling rebuilds the sensor from its table through the validating constructor. O(p^2 + n^2)."""
        return Sensor.from_table, (self.to_dict(), self.P0)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Sensor):
            return NotImplemented
        return (all(np.array_equal(getattr(self, k), getattr(other, k)) for k in ("C", "noise_cov", "gamma", "P0"))
                and self.groups == other.groups and self.channel == other.channel)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"Sensor(p={self.p}, n={self.n}, gamma={self.gamma.tolist()}, groups={[list(g) for g in self.groups]})"

    @property
    def p(self) -> int:
        """Number of outputs (rows of C)."""
        return self.C.shape[0]

    @property
    def n(self) -> int:
        """State dimension (columns of C)."""
        return self.C.shape[1]

    @property
    def g(self) -> int:
        """Number of sensor channels."""
        return len(self.groups)

    def with_gamma(self, gamma: npt.ArrayLike) -> Sensor:
        """A copy with Bernoulli channels of rates ``gamma`` (drops a Gilbert–Elliott model). O(p^3 + n^3).

        >>> Sensor(C=[[1.0]], gamma=[0.5]).with_gamma([0.9]).gamma.tolist()
        [0.9]
        """
        return Sensor(C=self.C, gamma=gamma, noise_cov=self.noise_cov, groups=[list(g) for g in self.groups],
                      P0=self.P0)

    def to_dict(self) -> dict[str, Any]:
        """The TOML ``[sensor]`` table (without P0, which is ``[state] P0``)."""
        out: dict[str, Any] = {"C": self.C.tolist(), "noise_cov": self.noise_cov.tolist()}
        if self.channel is not None:
            out.update(self.channel.to_dict())
        else:
            out["gamma"] = self.gamma.tolist()
        if self.g > 1:
            out["groups"] = [list(g) for g in self.groups]
        return out
