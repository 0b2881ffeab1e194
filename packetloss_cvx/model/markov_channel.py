"""General finite-state Markov channels, and the one place a System's channel model is chosen.

Channel i is a Markov chain S_{i,t} in {0, ..., k_i - 1} with a k_i×k_i row-stochastic transition matrix
``T_i[a, b] = P(S_{t+1} = b | S_t = a)``; a packet sent at step t arrives with probability ``d_i[S_{i,t}]``.
Channels are independent of each other and of the noise. The distribution of S_{i,0} (the information at
the first planned step) is a known ``state`` (an index), a ``belief`` (a k_i-vector), or, with neither, the
chain's unique stationary distribution. The predicted delivery probabilities ``mu_{i,t} = pi_{i,t} . d_i``,
``pi_{i,t+1} = pi_{i,t} T_i``, are the plug-in schedule a :class:`~packetloss_cvx.model.system.System` with this
channel carries, exactly as for :class:`~packetloss_cvx.model.channel.GilbertElliott` (the two-state chain with
``T = [[1 - p, p], [r, 1 - r]]``, ``d = (h_good, h_bad)``, state 0 = good).

The number of states may differ per channel. Arrays that hold every channel (beliefs (..., m, K), the
padded chain) use ``K = max k_i`` columns; the columns past k_i are states that cannot be reached (zero
probability, delivery 0, their own absorbing row), so they never change a number.

TOML (docs/design.md §4, "Bursty links"): ``[channel] model = "markov"`` with ``transition`` (a list of m
matrices), ``delivery`` (a list of m vectors), and at most one of ``state`` (m integers) or ``belief``
(m vectors). Every error names its field (``channel.transition``, ``channel.delivery[1]``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import DimensionError, InputError, ProbabilityError
from ..tolerances import ROW_SUM_ATOL, STATIONARY_GAP
from .channel import MODEL as GE_MODEL
from .channel import GilbertElliott

__all__ = ["MODEL", "MarkovChannel", "channel_schedule", "parse_channel"]

#: The general finite-state chain's name in the TOML schema.
MODEL = "markov"
_KEYS = ("model", "transition", "delivery", "state", "belief")


def _numbers(value: Any, field: str) -> np.ndarray:
    """A nested list (or array) of real numbers as a float array; booleans, strings and ragged lists refused."""
    def walk(item: Any) -> None:
        if isinstance(item, (list, tuple)):
            for sub in item:
                walk(sub)
        elif isinstance(item, (bool, np.bool_)) or not isinstance(item, (int, float, np.integer, np.floating)):
            raise InputError(field, f"expected numbers, found {type(item).__name__} {str(item)[:40]!r}")
    items = value.tolist() if isinstance(value, np.ndarray) else value
    walk(items)
    try:
        return np.array(items, dtype=float)
    except (ValueError, OverflowError):
        raise InputError(field, "expected a rectangular array of numbers in the double range") from None


def _per_channel(value: Any, field: str, m: int | None) -> list[Any]:
    if isinstance(value, np.ndarray):
        value = list(value)
    if not isinstance(value, (list, tuple)) or not value:
        raise InputError(field, f"expected a list with one entry per channel, found {str(value)[:40]!r}")
    if m is not None and len(value) != m:
        raise DimensionError(field, f"expected {m} entries (one per channel, as channel.transition) but found "
                                    f"{len(value)}")
    return list(value)


def _distribution(value: Any, field: str, k: int) -> np.ndarray:
    """A probability vector over k states: entries in [0, 1] summing to 1 within ROW_SUM_ATOL (then rescaled)."""
    arr = _numbers(value, field)
    if arr.shape != (k,):
        raise DimensionError(field, f"expected shape ({k},) (one probability per state) but found {arr.shape}")
    _probabilities(arr, field)
    total = float(arr.sum())
    if abs(total - 1.0) > ROW_SUM_ATOL:
        raise ProbabilityError(field, f"expected probabilities summing to 1 (within {ROW_SUM_ATOL:g}), found sum "
                                      f"{total!r}")
    return arr / total


def _probabilities(arr: np.ndarray, field: str) -> None:
    ok = np.isfinite(arr) & (arr >= 0.0) & (arr <= 1.0)
    if not np.all(ok):
        raise ProbabilityError(field, f"expected probabilities in [0, 1], found {arr[~ok].flat[0]}")


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


def _stationary(T: np.ndarray) -> np.ndarray | None:
    """The unique stationary distribution of T, or None when eigenvalue 1 is not simple.

    Solves ``pi (T - I) = 0, pi 1 = 1`` by least squares on the (k+1)×k stacked system, which has full column
    rank iff the stationary distribution is unique (one closed communicating class). The rank is read from the
    smallest singular value of the system against :data:`~packetloss_cvx.tolerances.STATIONARY_GAP`.
    Time O(k^3)."""
    k = T.shape[0]
    if k == 2 and T[0, 1] + T[1, 0] > 0:          # the closed form (r, p) / (p + r), as GilbertElliott.stationary
        total = T[0, 1] + T[1, 0]
        return np.array([T[1, 0] / total, T[0, 1] / total])
    system = np.vstack([T.T - np.eye(k), np.ones((1, k))])
    if np.linalg.svd(system, compute_uv=False)[-1] <= STATIONARY_GAP:
        return None
    pi = np.linalg.lstsq(system, np.r_[np.zeros(k), 1.0], rcond=None)[0]
    pi = np.clip(pi, 0.0, None)
    return pi / pi.sum()


def _cesaro(belief: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The long-run average distribution lim (1/n) sum_{t<n} belief T^t of a chain without a unique stationary
    one, by 60 doublings (average over 2^60 steps: the 1/n error is below 1e-18). Time O(k^3)."""
    avg, power = T.copy(), T.copy()
    for _ in range(60):
        avg, power = 0.5 * (avg + avg @ power), power @ power
    out = np.clip(belief @ avg, 0.0, None)
    return out / out.sum()


class MarkovChannel:
    """m independent finite-state Markov packet-loss channels (k_i states each).

    Parameters
    ----------
    transition : sequence of array_like
        One k_i×k_i row-stochastic matrix per channel: entries in [0, 1], rows summing to 1 within
        :data:`~packetloss_cvx.tolerances.ROW_SUM_ATOL` (1e-9; a row off by more than 4 eps is then divided by
        its sum, so the stored chain reads back unchanged from its own table).
    delivery : sequence of array_like
        One k_i-vector per channel: the probability that a packet sent in each state arrives.
    state : sequence of int, optional
        The known state index (0-based) of each channel at the first planned step.
    belief : sequence of array_like, optional
        The state distribution of each channel at the first planned step (k_i probabilities summing to 1).
        At most one of ``state`` and ``belief``; with neither, the stationary distribution, which must be
        unique (eigenvalue 1 of every T_i simple).
    prefix : str
        Prepended to every field name in errors (``"channel."`` inside a System).

    Raises
    ------
    InputError, DimensionError, ProbabilityError
        Naming the field (``channel.transition[0]``, ``channel.delivery``, ...).

    Examples
    --------
    >>> ch = MarkovChannel(transition=[[[0.9, 0.1], [0.4, 0.6]]], delivery=[[1.0, 0.0]])   # a Gilbert channel
    >>> bool(np.allclose(ch.stationary, [[0.8, 0.2]])), bool(np.allclose(ch.mean_rate, [0.8]))
    (True, True)
    >>> three = MarkovChannel(transition=[[[0.8, 0.2, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]]],
    ...                       delivery=[[1.0, 0.5, 0.0]], state=[2])
    >>> # pi: (0, 0, 1), then row 2 = (0.5, 0, 0.5), then 0.5 row 0 + 0.5 row 2 = (0.65, 0.1, 0.25); mu = pi . d
    >>> bool(np.allclose(three.delivery_schedule(3)[:, 0], [0.0, 0.5, 0.65 + 0.1 * 0.5]))
    True
    """

    __slots__ = ("transition", "delivery", "belief", "state_given", "sizes", "padded_transition",
                 "padded_delivery", "_stationary", "_unique")

    transition: tuple[np.ndarray, ...]
    delivery: tuple[np.ndarray, ...]
    belief: tuple[np.ndarray, ...] | None
    state_given: bool
    sizes: tuple[int, ...]

    def __init__(self, *, transition: Any, delivery: Any, state: Any = None, belief: Any = None,
                 prefix: str = "") -> None:
        rows = _per_channel(transition, prefix + "transition", None)
        m = len(rows)
        Ts = []
        for i, item in enumerate(rows):
            field = f"{prefix}transition[{i}]"
            T = _numbers(item, field)
            if T.ndim != 2 or T.shape[0] != T.shape[1] or T.shape[0] < 1:
                raise DimensionError(field, f"expected a square k×k matrix (k >= 1 states) but found shape {T.shape}")
            _probabilities(T, field)
            sums = T.sum(axis=1)
            bad = np.abs(sums - 1.0) > ROW_SUM_ATOL
            if np.any(bad):
                row = int(np.argmax(bad))
                raise ProbabilityError(field, f"expected rows summing to 1 (within {ROW_SUM_ATOL:g}); row {row} sums "
                                              f"to {float(sums[row])!r}")
            off = np.abs(sums - 1.0) > 4 * np.finfo(float).eps      # rounding-level sums kept as written
            Ts.append(_frozen(np.where(off[:, None], T / sums[:, None], T)))
        sizes = tuple(T.shape[0] for T in Ts)
        ds = []
        for i, item in enumerate(_per_channel(delivery, prefix + "delivery", m)):
            field = f"{prefix}delivery[{i}]"
            d = _numbers(item, field)
            if d.shape != (sizes[i],):
                raise DimensionError(field, f"expected shape ({sizes[i]},) (one probability per state of "
                                            f"transition[{i}]) but found {d.shape}")
            _probabilities(d, field)
            ds.append(_frozen(d))
        if state is not None and belief is not None:
            raise InputError(prefix + "state/belief", "expected at most one of the two, found both")
        beliefs = None
        if state is not None:
            items = _per_channel(state, prefix + "state", m)
            beliefs = []
            for i, s in enumerate(items):
                if isinstance(s, (bool, np.bool_)) or not isinstance(s, (int, np.integer)) or not 0 <= s < sizes[i]:
                    raise InputError(f"{prefix}state[{i}]", f"expected a state index 0..{sizes[i] - 1}, found "
                                                            f"{s!r}"[:120])
                beliefs.append(_frozen(np.eye(sizes[i])[int(s)]))
        elif belief is not None:
            items = _per_channel(belief, prefix + "belief", m)
            beliefs = [_frozen(_distribution(b, f"{prefix}belief[{i}]", sizes[i])) for i, b in enumerate(items)]
        stationary = [_stationary(T) for T in Ts]
        if beliefs is None and any(pi is None for pi in stationary):
            i = next(i for i, pi in enumerate(stationary) if pi is None)
            raise InputError(f"{prefix}transition[{i}]", "the chain has more than one stationary distribution "
                                                          "(eigenvalue 1 is not simple: more than one closed class of "
                                                          "states), so the stationary start is not defined; give "
                                                          "state or belief")
        K = max(sizes)
        PT, Pd, stat = np.zeros((m, K, K)), np.zeros((m, K)), np.zeros((m, K))
        for i, k in enumerate(sizes):
            PT[i] = np.eye(K)
            PT[i, :k, :k] = Ts[i]
            Pd[i, :k] = ds[i]
            stat[i, :k] = stationary[i] if stationary[i] is not None else _cesaro(beliefs[i], Ts[i])
        for key, value in (("transition", tuple(Ts)), ("delivery", tuple(ds)),
                           ("belief", None if beliefs is None else tuple(beliefs)), ("state_given", state is not None),
                           ("sizes", sizes), ("padded_transition", _frozen(PT)), ("padded_delivery", _frozen(Pd)),
                           ("_stationary", _frozen(stat)), ("_unique", all(pi is not None for pi in stationary))):
            object.__setattr__(self, key, value)

    @classmethod
    def from_table(cls, table: Mapping[str, Any], prefix: str = "channel.") -> MarkovChannel:
        """Build from the TOML ``[channel]`` table (keys model, transition, delivery, state, belief).

        Examples
        --------
        >>> ch = MarkovChannel.from_table({"model": "markov", "transition": [[[0.5, 0.5], [1.0, 0.0]]],
        ...                                "delivery": [[1.0, 0.0]], "state": [1]})
        >>> ch.initial_belief.tolist(), MarkovChannel.from_table(ch.to_dict()) == ch
        ([[0.0, 1.0]], True)
        """
        if not isinstance(table, Mapping):
            raise InputError(prefix.rstrip("."), f"expected a table, found {type(table).__name__}")
        unknown = [k for k in table if k not in _KEYS]
        if unknown:
            raise InputError(prefix + str(unknown[0]), f"unknown key for model \"{MODEL}\"; expected one of "
                                                       f"{', '.join(_KEYS)}")
        for key in ("transition", "delivery"):
            if key not in table:
                raise InputError(prefix + key, "missing field (one per channel)")
        return cls(**{k: table[k] for k in _KEYS[1:] if k in table}, prefix=prefix)

    @classmethod
    def from_gilbert_elliott(cls, channel: GilbertElliott) -> MarkovChannel:
        """The two-state twin of a Gilbert–Elliott channel: state 0 = good, ``T = [[1 - p, p], [r, 1 - r]]``,
        ``d = (h_good, h_bad)``, the same state or belief. O(m).

        Examples
        --------
        >>> MarkovChannel.from_gilbert_elliott(GilbertElliott(p=[0.25], r=[0.5], state=["bad"])).to_dict()
        {'model': 'markov', 'transition': [[[0.75, 0.25], [0.5, 0.5]]], 'delivery': [[1.0, 0.0]], 'state': [1]}
        """
        T = [[[1.0 - p, p], [r, 1.0 - r]] for p, r in zip(channel.p.tolist(), channel.r.tolist(), strict=True)]
        d = [[g, b] for g, b in zip(channel.h_good.tolist(), channel.h_bad.tolist(), strict=True)]
        if channel.belief is None:
            return cls(transition=T, delivery=d)
        if channel.state_given:
            return cls(transition=T, delivery=d, state=[0 if b == 1.0 else 1 for b in channel.belief.tolist()])
        return cls(transition=T, delivery=d, belief=[[b, 1.0 - b] for b in channel.belief.tolist()])

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("MarkovChannel is immutable: build a new one")

    def __copy__(self) -> MarkovChannel:
        return self          # immutable, its arrays read-only

    def __deepcopy__(self, memo: dict) -> MarkovChannel:
        return self

    def __reduce__(self) -> tuple:
        """Pickling rebuilds the channel from its TOML table through the validating constructor. O(m K^2)."""
        return MarkovChannel.from_table, (self.to_dict(),)

    def __repr__(self) -> str:
        """``MarkovChannel(m=1, states=[3], transition=..., delivery=..., state=[2])``."""
        extra = ""
        if self.belief is not None:
            extra = (f", state={[int(np.argmax(b)) for b in self.belief]}" if self.state_given
                     else f", belief={[b.tolist() for b in self.belief]}")
        return (f"MarkovChannel(m={self.m}, states={list(self.sizes)}, "
                f"transition={[T.tolist() for T in self.transition]}, "
                f"delivery={[d.tolist() for d in self.delivery]}{extra})")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, MarkovChannel):
            return NotImplemented
        if self.sizes != other.sizes or (self.belief is None) != (other.belief is None):
            return False
        pairs = [*zip(self.transition, other.transition, strict=True), *zip(self.delivery, other.delivery, strict=True)]
        if self.belief is not None:
            pairs += list(zip(self.belief, other.belief, strict=True))
        return all(np.array_equal(a, b) for a, b in pairs)

    __hash__ = None  # type: ignore[assignment]

    @property
    def m(self) -> int:
        """Number of channels."""
        return len(self.sizes)

    @property
    def stationary(self) -> np.ndarray:
        """The stationary distribution per channel, (m, K) (zeros past k_i). Where it is not unique (a belief or
        state is then given), the long-run average distribution from the initial belief."""
        return self._stationary

    @property
    def initial_belief(self) -> np.ndarray:
        """The state distribution at the first planned step, (m, K): the given state or belief, else stationary."""
        if self.belief is None:
            return self._stationary
        out = np.zeros((self.m, max(self.sizes)))
        for i, b in enumerate(self.belief):
            out[i, :b.size] = b
        return out

    @property
    def mean_rate(self) -> np.ndarray:
        """The long-run delivery rate ``stationary . d`` per channel, (m,)."""
        return np.einsum("ik,ik->i", self._stationary, self.padded_delivery)

    @property
    def correlation(self) -> np.ndarray:
        """The chain's slowest memory per channel: its eigenvalue of largest modulus after one eigenvalue 1 (real
        when real, else its modulus; 0 for one state). For two states exactly ``1 - p - r``. For k >= 3 a zero
        does not mean memoryless (a nilpotent part still correlates neighbouring steps). O(m K^3)."""
        out = np.zeros(self.m)
        for i, T in enumerate(self.transition):
            if T.shape[0] == 1:
                continue
            if T.shape[0] == 2:
                out[i] = T[0, 0] - T[1, 0]
                continue
            vals = np.linalg.eigvals(T)
            vals = np.delete(vals, int(np.argmin(np.abs(vals - 1.0))))
            top = vals[int(np.argmax(np.abs(vals)))]
            out[i] = top.real if abs(top.imag) <= 1e-12 else abs(top)
        return out

    @property
    def correlated(self) -> bool:
        """Whether deliveries may be correlated across steps: False when every chain has identical rows (its states
        are drawn independently each step) or equal delivery probabilities in every state. O(m K^2)."""
        return any(not (np.all(T == T[0]) or np.all(d == d[0])) for T, d in zip(self.transition, self.delivery,
                                                                              strict=True))

    @property
    def belief_settles(self) -> bool:
        """Whether the propagated belief converges from the initial one: False when a chain has an eigenvalue of
        modulus 1 other than 1 (periodic) and the initial belief is not already its long-run one. O(m K^3)."""
        for i, T in enumerate(self.transition):
            vals = np.linalg.eigvals(T)
            periodic = np.sum(np.abs(np.abs(vals) - 1.0) <= 1e-12) > np.sum(np.abs(vals - 1.0) <= 1e-12)
            k = T.shape[0]
            if periodic and not np.allclose(self.initial_belief[i, :k], self._stationary[i, :k], rtol=0, atol=1e-12):
                return False
        return True

    def chain_matrices(self) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
        """Per channel ``(T, d, pi0)``: the k_i×k_i transition matrix, the k_i delivery probabilities and the state
        distribution at the first planned step, read-only float arrays. O(m K).

        Examples
        --------
        >>> ch = MarkovChannel(transition=[[[0.9, 0.1], [0.4, 0.6]]], delivery=[[1.0, 0.0]], state=[1])
        >>> [a.tolist() for a in ch.chain_matrices()[0]]
        [[[0.9, 0.1], [0.4, 0.6]], [1.0, 0.0], [0.0, 1.0]]
        """
        start = self.initial_belief
        return tuple((T, d, _frozen(start[i, :k])) for i, (T, d, k) in
                     enumerate(zip(self.transition, self.delivery, self.sizes, strict=True)))

    #: ``horizon`` an integer >= 1 whose arrays fit in MAX_ENTRIES (the one check, GilbertElliott's)
    check_horizon = staticmethod(GilbertElliott.check_horizon)

    def check_belief(self, belief: Any, field: str = "belief") -> np.ndarray:
        """A belief as an (m, K) array (K = max k_i, zeros past k_i): probabilities summing to one per channel.
        O(m K)."""
        arr = _numbers(belief, field)
        K = max(self.sizes)
        if arr.shape != (self.m, K):
            raise DimensionError(field, f"expected shape ({self.m}, {K}) (a distribution per channel) but found "
                                        f"{arr.shape}")
        for i, k in enumerate(self.sizes):
            _distribution(arr[i, :k], f"{field}[{i}]", k)
            if np.any(arr[i, k:] != 0):
                raise ProbabilityError(f"{field}[{i}]", f"expected zeros past the channel's {k} states")
        return arr

    def propagate(self, belief: np.ndarray) -> np.ndarray:
        """One step of the prior: ``pi_{t+1} = pi_t T`` per channel; ``belief`` (..., m, K). A two-state channel
        takes the same step in Gilbert–Elliott's form, ``b+ = T[1, 0] + (T[0, 0] - T[1, 0]) b``, ``1 - b+`` (equal
        in exact arithmetic for a distribution), so that a channel and its two-state twin give the same bits.
        O(m K^2) per belief."""
        out = np.einsum("...ia,iab->...ib", belief, self.padded_transition)
        for i, T in enumerate(self.transition):
            if T.shape[0] == 2:
                good = T[1, 0] + (T[0, 0] - T[1, 0]) * belief[..., i, 0]
                out[..., i, 0], out[..., i, 1] = good, 1.0 - good
        return out

    def beliefs(self, horizon: int, belief: np.ndarray | None = None) -> np.ndarray:
        """The state distributions at t = 0..horizon-1 from ``belief`` (default the initial one), (N, m, K).
        Constant from the stationary distribution. Time O(N m K^2).

        Raises
        ------
        InputError
            ``horizon`` not an integer >= 1 or beyond MAX_ENTRIES numbers; ``belief`` not a distribution each.
        """
        K = max(self.sizes)
        self.check_horizon(horizon, self.m * K)
        if belief is None and self.belief is None:
            return np.repeat(self._stationary[None], horizon, axis=0)
        b = self.initial_belief if belief is None else self.check_belief(belief)
        out = np.empty((horizon, self.m, K))
        for t in range(horizon):
            out[t] = b
            b = self.propagate(b)
        return out

    def delivery_schedule(self, horizon: int, belief: np.ndarray | None = None) -> np.ndarray:
        """Predicted ``mu_{i,t} = pi_{i,t} . d_i``, (N, m), clipped to [0, 1]. Time O(N m K^2)."""
        mu = np.einsum("tik,ik->ti", self.beliefs(horizon, belief), self.padded_delivery)
        return np.clip(mu, 0.0, 1.0)

    def filter(self, belief: np.ndarray, delivered: np.ndarray) -> np.ndarray:
        """One step of the HMM filter: the state distribution at t+1 given the outcome at t.

        .. math:: \\pi^+ \\propto \\pi \\circ (d^v (1 - d)^{1 - v}), \\qquad \\pi_{t+1} = \\pi^+ T

        ``belief`` (..., m, K) and ``delivered`` (..., m). Time O(m K^2) per belief.

        Raises
        ------
        InputError
            An outcome the belief gives probability zero.
        """
        v = np.asarray(delivered).astype(bool)[..., None]
        like = np.where(v, self.padded_delivery, 1.0 - self.padded_delivery)
        joint = belief * like
        total = joint.sum(axis=-1, keepdims=True)
        if np.any(total <= 0.0):
            i = int(np.argwhere(total[..., 0] <= 0.0)[0][-1])
            raise InputError("delivered", f"channel {i}: an outcome has probability 0 under the belief and the channel")
        return np.clip(self.propagate(joint / total), 0.0, 1.0)

    def with_belief(self, belief: Any) -> MarkovChannel:
        """The same chains with another initial belief ((m, K), rescaled to sum to one per channel). O(m K^2)."""
        b = np.clip(np.asarray(belief, dtype=float), 0.0, 1.0)
        rows = [b[i, :k] / b[i, :k].sum() for i, k in enumerate(self.sizes)]
        return MarkovChannel(transition=self.transition, delivery=self.delivery, belief=rows)

    def reveals_state(self) -> bool:
        """True when every outcome reveals its channel's state: the delivery is certain in each state and the
        states' outcomes differ (so at most two states). O(m K)."""
        return all(np.all((d == 0) | (d == 1)) and len(set(d.tolist())) == d.size for d in self.delivery)

    def to_dict(self) -> dict[str, Any]:
        """The TOML ``[channel]`` table (``from_table`` reads it back).

        Examples
        --------
        >>> MarkovChannel(transition=[[[1.0]]], delivery=[[0.5]]).to_dict()
        {'model': 'markov', 'transition': [[[1.0]]], 'delivery': [[0.5]]}
        """
        out: dict[str, Any] = {"model": MODEL, "transition": [T.tolist() for T in self.transition],
                               "delivery": [d.tolist() for d in self.delivery]}
        if self.belief is not None and self.state_given:
            out["state"] = [int(np.argmax(b)) for b in self.belief]
        elif self.belief is not None:
            out["belief"] = [b.tolist() for b in self.belief]
        return out


def parse_channel(channel: Any) -> GilbertElliott | MarkovChannel:
    """A channel object, or the TOML ``[channel]`` table of either model (by its ``model`` key), validated. O(m K^3).

    Examples
    --------
    >>> type(parse_channel({"model": "markov", "transition": [[[1.0]]], "delivery": [[0.5]]})).__name__
    'MarkovChannel'
    """
    if isinstance(channel, (GilbertElliott, MarkovChannel)):
        return channel
    if isinstance(channel, Mapping) and channel.get("model") == MODEL:
        return MarkovChannel.from_table(channel)
    if isinstance(channel, Mapping) and channel.get("model") not in (GE_MODEL, None):
        raise InputError("channel.model", f'expected "{GE_MODEL}" or "{MODEL}", found {str(channel["model"])[:40]!r}')
    return GilbertElliott.from_table(channel)


def channel_schedule(channel: Any, m: int, horizon: int, mu: Any,
                     mu_schedule: Any) -> tuple[GilbertElliott | MarkovChannel | None, Any]:
    """For :class:`~packetloss_cvx.model.system.System`: ``(None, mu_schedule)`` without a channel; with one
    (a :class:`~packetloss_cvx.model.channel.GilbertElliott`, a :class:`MarkovChannel` or the TOML table of either),
    the validated channel and its predicted schedule ``delivery_schedule(horizon)`` in place of mu. Giving mu or
    mu_schedule as well is an InputError. Time O(N m K^2).

    Examples
    --------
    >>> channel_schedule(None, m=1, horizon=2, mu=None, mu_schedule=[[0.5], [0.7]])
    (None, [[0.5], [0.7]])
    >>> chan, schedule = channel_schedule({"model": "gilbert-elliott", "p": [0.1], "r": [0.4]}, 1, 2, None, None)
    >>> schedule[:, 0].tolist()                  # from the stationary belief r / (p + r) = 0.8
    [0.8, 0.8]
    """
    if channel is None:
        return None, mu_schedule
    if mu is not None or mu_schedule is not None:
        raise InputError("channel", "expected either a Gilbert-Elliott channel (model, p, r, ...), a Markov one "
                                    "(model, transition, delivery, ...) or mu/mu_schedule, found both")
    chan = parse_channel(channel)
    if chan.m != m:
        field = "channel.p" if isinstance(chan, GilbertElliott) else "channel.transition"
        raise DimensionError(field, f"expected {m} channels (one per actuator, the columns of B) but found {chan.m}")
    return chan, chan.delivery_schedule(horizon)
