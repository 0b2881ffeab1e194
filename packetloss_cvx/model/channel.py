"""Markov packet-loss channels: the one channel type, and the one place a System's channel model is chosen.

Channel i is a Markov chain S_{i,t} in {0, ..., k_i - 1} with a k_i×k_i row-stochastic transition matrix
``T_i[a, b] = P(S_{t+1} = b | S_t = a)``; a packet sent at step t arrives with probability ``d_i[S_{i,t}]``.
Channels are independent of each other and of the noise. The distribution of S_{i,0} (the information at
the first planned step) is a known ``state`` (an index), a ``belief`` (a k_i-vector), or, with neither, the
chain's unique stationary distribution. The predicted delivery probabilities ``mu_{i,t} = pi_{i,t} . d_i``,
``pi_{i,t+1} = pi_{i,t} T_i``, are the plug-in schedule a [`System`][packetloss_cvx.model.system.System] with this
channel carries. A Gilbert–Elliott channel is a constructor of this one type
([`GilbertElliott`][packetloss_cvx.model.channel.GilbertElliott]): the two-state chain with
``T = [[1 - p, p], [r, 1 - r]]``, ``d = (h_good, h_bad)``, state 0 = good; its rates ``p``, ``r``, ``h_good``, ``h_bad``
read back from any channel whose chains all have two states.

The number of states may differ per channel. Arrays that hold every channel (beliefs (..., m, K), the
padded chain) use ``K = max k_i`` columns; the columns past k_i are states that cannot be reached (zero
probability, delivery 0, their own absorbing row), so they never change a number.

TOML (docs/design.md §4; docs/mathematics.md, "Bursty links"): ``[channel] model = "markov"`` with
``transition`` (a list of m matrices), ``delivery`` (a list of m vectors), and at most one of ``state`` (m
integers) or ``belief`` (m vectors); or ``model = "gilbert-elliott"`` with per-channel arrays ``p``, ``r``,
optional ``h_good`` (default 1), ``h_bad`` (default 0), and at most one of ``state = ["good", "bad"]`` or
``belief = [0.9, 0.2]`` (P(good)). A channel remembers which of the two tables it was given (``form``) and
writes that one back. Every error names its field (``channel.transition``, ``channel.delivery[1]``, ``channel.p``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import DimensionError, InputError, ProbabilityError
from ..tolerances import ROW_SUM_ATOL, STATIONARY_GAP
from .validation import MAX_ENTRIES

__all__ = ["GE_MODEL", "MODEL", "GilbertElliott", "MarkovChannel", "channel_schedule", "gilbert_rates",
           "parse_channel"]

#: The general finite-state chain's name in the TOML schema.
MODEL = "markov"
#: The Gilbert–Elliott (two-state) table's name in the TOML schema.
GE_MODEL = "gilbert-elliott"
_KEYS = ("model", "transition", "delivery", "state", "belief")
_GE_KEYS = ("model", "p", "r", "h_good", "h_bad", "state", "belief")
_GE_STATES = {"good": 0, "bad": 1}


def _rates(value: Any, field: str, m: int | None) -> np.ndarray:
    """A length-m vector of probabilities in [0, 1] (a bare number is broadcast when m is known)."""
    items = value.tolist() if isinstance(value, np.ndarray) else value
    flat = items if isinstance(items, (list, tuple)) else [items]
    for item in flat:
        if isinstance(item, (bool, np.bool_)) or not isinstance(item, (int, float, np.integer, np.floating)):
            raise InputError(field, f"expected numbers in [0, 1], found {type(item).__name__} {str(item)[:40]!r}")
    try:
        arr = np.array(flat, dtype=float)
    except OverflowError:
        raise InputError(field, "expected numbers in [0, 1], found an integer beyond the double range") from None
    if not isinstance(items, (list, tuple)) and m is not None:
        arr = np.full(m, arr[0])
    if arr.ndim != 1 or arr.size < 1 or (m is not None and arr.size != m):
        raise DimensionError(field, f"expected shape ({m if m is not None else 'm'},) (one per channel) but found "
                                    f"{arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0.0) or np.any(arr > 1.0):
        bad = arr[~(np.isfinite(arr) & (arr >= 0.0) & (arr <= 1.0))][0]
        raise ProbabilityError(field, f"expected probabilities in [0, 1], found {bad}")
    return arr


def _ge_states(value: Any, field: str, m: int) -> list[int]:
    """The state index (0 good, 1 bad) of each of m channels from "good" / "bad"."""
    items = [value] * m if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)) or not all(isinstance(s, str) for s in items):
        raise InputError(field, f'expected a list of "good" / "bad", one per channel, found {str(value)[:40]!r}')
    if len(items) != m:
        raise DimensionError(field, f"expected {m} states (one per channel) but found {len(items)}")
    wrong = [s for s in items if s not in _GE_STATES]
    if wrong:
        raise InputError(field, f'expected "good" or "bad", found {wrong[0][:20]!r}')
    return [_GE_STATES[s] for s in items]


def gilbert_rates(rate: Any, correlation: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(p, r)`` of the two-state chains with stationary P(good) ``rate`` and second eigenvalue
    ``lambda = 1 - p - r = correlation``: ``p = (1 - rate)(1 - lambda)``, ``r = rate (1 - lambda)``
    (r / (p + r) = rate). No validation (the callers check their own ranges). O(size).

    Examples
    --------
    >>> [a.tolist() for a in gilbert_rates(np.array([0.8]), 0.5)]
    [[0.09999999999999998], [0.4]]
    """
    return (1.0 - rate) * (1.0 - correlation), rate * (1.0 - correlation)


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
    smallest singular value of the system against `STATIONARY_GAP`.
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
    """m independent finite-state Markov packet-loss channels (k_i states each): the one channel type.

    Parameters
    ----------
    transition : sequence of array_like
        One k_i×k_i row-stochastic matrix per channel: entries in [0, 1], rows summing to 1 within
        `ROW_SUM_ATOL` (1e-9; a row off by more than 4 eps is then divided by
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
                 "padded_delivery", "_stationary", "_unique", "form", "_below")

    transition: tuple[np.ndarray, ...]
    delivery: tuple[np.ndarray, ...]
    belief: tuple[np.ndarray, ...] | None
    state_given: bool
    sizes: tuple[int, ...]
    form: str

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
        self._freeze(Ts, ds, beliefs, state is not None, MODEL, f"{prefix}transition")

    def _freeze(self, Ts: list[np.ndarray], ds: list[np.ndarray], beliefs: list[np.ndarray] | None, state_given: bool,
                form: str, field: str) -> None:
        """Store validated chains (read-only), their padded arrays and stationary distributions. O(m K^3)."""
        m, sizes = len(Ts), tuple(T.shape[0] for T in Ts)
        stationary = [_stationary(T) for T in Ts]
        if beliefs is None and any(pi is None for pi in stationary):
            i = next(i for i, pi in enumerate(stationary) if pi is None)
            raise InputError(f"{field}[{i}]", "the chain has more than one stationary distribution "
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
                           ("belief", None if beliefs is None else tuple(beliefs)), ("state_given", state_given),
                           ("sizes", sizes), ("padded_transition", _frozen(PT)), ("padded_delivery", _frozen(Pd)),
                           ("_stationary", _frozen(stat)), ("_unique", all(pi is not None for pi in stationary)),
                           ("form", form), ("_below", _frozen(np.moveaxis(np.cumsum(PT, axis=2), 2, 0)[:-1]
                                                              .reshape(K - 1, m * K)))):
            object.__setattr__(self, key, value)

    @classmethod
    def gilbert_elliott(cls, *, p: Any, r: Any, h_good: Any = 1.0, h_bad: Any = 0.0, state: Any = None,
                        belief: Any = None, prefix: str = "") -> MarkovChannel:
        """m independent Gilbert–Elliott channels: two-state chains, state 0 = good,
        ``T = [[1 - p, p], [r, 1 - r]]``, ``d = (h_good, h_bad)``.

        Parameters
        ----------
        p, r : array_like
            P(good -> bad) and P(bad -> good) per channel, in [0, 1].
        h_good, h_bad : array_like, optional
            Delivery probability in each state (default 1 and 0: the Gilbert channel).
        state : sequence of {"good", "bad"}, optional
            The known state at the first planned step.
        belief : array_like, optional
            P(good) at the first planned step. At most one of ``state`` and ``belief``;
            with neither, the stationary distribution (which needs p + r > 0).
        prefix : str
            Prepended to every field name in errors (``"channel."`` inside a System).

        Raises
        ------
        InputError, DimensionError, ProbabilityError
            Naming the field (``channel.p`` ...).

        Examples
        --------
        >>> ch = MarkovChannel.gilbert_elliott(p=[0.1], r=[0.4])
        >>> ch.stationary.tolist(), ch.correlation.tolist(), ch.p.tolist()
        ([[0.8, 0.2]], [0.5], [0.1])
        >>> ch.delivery_schedule(3)[:, 0].tolist()
        [0.8, 0.8, 0.8]
        """
        p_ = _rates(p, prefix + "p", None)
        m = p_.size
        r_ = _rates(r, prefix + "r", m)
        hg, hb = _rates(h_good, prefix + "h_good", m), _rates(h_bad, prefix + "h_bad", m)
        if state is not None and belief is not None:
            raise InputError(prefix + "state/belief", "expected at most one of the two, found both")
        beliefs = None
        if state is not None:
            beliefs = [_frozen(np.eye(2)[s]) for s in _ge_states(state, prefix + "state", m)]
        elif belief is not None:
            beliefs = [_frozen([b, 1.0 - b]) for b in _rates(belief, prefix + "belief", m).tolist()]
        if beliefs is None and np.any(p_ + r_ == 0):
            i = int(np.argmax(p_ + r_ == 0))
            raise InputError(prefix + "p", f"channel {i} has p + r = 0: the chain never moves, so it has no unique "
                                           "stationary distribution; give state or belief")
        Ts = [_frozen([[1.0 - a, a], [b, 1.0 - b]]) for a, b in zip(p_.tolist(), r_.tolist(), strict=True)]
        ds = [_frozen([g, b]) for g, b in zip(hg.tolist(), hb.tolist(), strict=True)]
        out = object.__new__(cls)
        out._freeze(Ts, ds, beliefs, state is not None, GE_MODEL, prefix + "p")
        return out

    @classmethod
    def from_table(cls, table: Mapping[str, Any], prefix: str = "channel.") -> MarkovChannel:
        """Build from the TOML ``[channel]`` table of either model (by its ``model`` key): ``"markov"`` (keys
        model, transition, delivery, state, belief) or ``"gilbert-elliott"`` (keys model, p, r, h_good, h_bad,
        state, belief; the model the table is read as when it names none).

        Examples
        --------
        >>> ch = MarkovChannel.from_table({"model": "markov", "transition": [[[0.5, 0.5], [1.0, 0.0]]],
        ...                                "delivery": [[1.0, 0.0]], "state": [1]})
        >>> ch.initial_belief.tolist(), MarkovChannel.from_table(ch.to_dict()) == ch
        ([[0.0, 1.0]], True)
        >>> ge = MarkovChannel.from_table({"model": "gilbert-elliott", "p": [0.1], "r": [0.4], "state": ["bad"]})
        >>> ge.initial_belief.tolist(), MarkovChannel.from_table(ge.to_dict()).to_dict() == ge.to_dict()
        ([[0.0, 1.0]], True)
        """
        if not isinstance(table, Mapping):
            raise InputError(prefix.rstrip("."), f"expected a table, found {type(table).__name__}")
        if table.get("model") != MODEL:
            if table.get("model") not in (GE_MODEL, None):
                raise InputError(prefix + "model", f'expected "{GE_MODEL}" or "{MODEL}", found '
                                                   f'{str(table["model"])[:40]!r}')
            return cls.gilbert_elliott_table(table, prefix)
        unknown = [k for k in table if k not in _KEYS]
        if unknown:
            raise InputError(prefix + str(unknown[0]), f"unknown key for model \"{MODEL}\"; expected one of "
                                                       f"{', '.join(_KEYS)}")
        for key in ("transition", "delivery"):
            if key not in table:
                raise InputError(prefix + key, "missing field (one per channel)")
        return cls(**{k: table[k] for k in _KEYS[1:] if k in table}, prefix=prefix)

    @classmethod
    def bernoulli(cls, rate: Any, prefix: str = "") -> MarkovChannel:
        """m independent Bernoulli (i.i.d.) channels as one-state chains: ``T = [[1]]``, ``d = (rate_i,)``; the
        predicted schedule is ``rate`` at every step and deliveries are uncorrelated (the covariance is exactly zero
        off the diagonal). The chain of a System whose mu does not change in time. O(m).

        Raises
        ------
        InputError, DimensionError, ProbabilityError
            ``rate`` not m probabilities in [0, 1] (field ``{prefix}rate``).

        Examples
        --------
        >>> ch = MarkovChannel.bernoulli([0.9, 0.5])
        >>> ch.sizes, ch.delivery_schedule(2).tolist(), ch.correlated
        ((1, 1), [[0.9, 0.5], [0.9, 0.5]], False)
        """
        rates = _rates(rate, prefix + "rate", None)
        return cls(transition=[[[1.0]]] * rates.size, delivery=[[g] for g in rates.tolist()], prefix=prefix)

    @classmethod
    def gilbert_elliott_table(cls, table: Mapping[str, Any], prefix: str = "channel.") -> MarkovChannel:
        """Build from a ``model = "gilbert-elliott"`` table (keys model, p, r, h_good, h_bad, state, belief); any
        other model is refused, naming the field.

        Examples
        --------
        >>> ch = MarkovChannel.gilbert_elliott_table({"model": "gilbert-elliott", "p": [0.1], "r": [0.4]})
        >>> ch.to_dict()
        {'model': 'gilbert-elliott', 'p': [0.1], 'r': [0.4], 'h_good': [1.0], 'h_bad': [0.0]}
        """
        if not isinstance(table, Mapping):
            raise InputError(prefix.rstrip("."), f"expected a table, found {type(table).__name__}")
        unknown = [k for k in table if k not in _GE_KEYS]
        if unknown:
            raise InputError(prefix + str(unknown[0]), f"unknown key; expected one of {', '.join(_GE_KEYS)}")
        if table.get("model") != GE_MODEL:
            found = "nothing" if "model" not in table else repr(table["model"])[:40]
            raise InputError(prefix + "model", f'expected "{GE_MODEL}" (the Markov channel model), found {found}')
        for key in ("p", "r"):
            if key not in table:
                raise InputError(prefix + key, "missing field (one per channel)")
        return cls.gilbert_elliott(**{k: table[k] for k in _GE_KEYS[1:] if k in table}, prefix=prefix)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("MarkovChannel is immutable: build a new one")

    def __copy__(self) -> MarkovChannel:
        return self          # immutable, its arrays read-only

    def __deepcopy__(self, memo: dict) -> MarkovChannel:
        return self

    def __reduce__(self) -> tuple:
        """Pickling keeps the validated arrays and the table form (a belief that a table rounds, e.g. a filtered
        one, comes back to the bit). O(m K^2)."""
        beliefs = None if self.belief is None else [b.tolist() for b in self.belief]
        return _restore, ([T.tolist() for T in self.transition], [d.tolist() for d in self.delivery], beliefs,
                          self.state_given, self.form)

    def __repr__(self) -> str:
        """``MarkovChannel(m=1, states=[3], transition=..., delivery=..., state=[2])``; a channel given as a
        Gilbert–Elliott table, the parameters that differ from the defaults (``GilbertElliott(m=1, p=[0.1],
        r=[0.4], state=['bad'])``: h_good, h_bad only when not the Gilbert (1, 0), the state or belief only when
        given)."""
        if self.form == GE_MODEL:
            table = self.to_dict()
            extra = "" if np.all(self.h_good == 1) and np.all(self.h_bad == 0) else (
                f", h_good={table['h_good']}, h_bad={table['h_bad']}")
            extra += "".join(f", {key}={table[key]}" for key in ("state", "belief") if key in table)
            return f"GilbertElliott(m={self.m}, p={table['p']}, r={table['r']}{extra})"
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
    def two_state(self) -> bool:
        """Whether every chain has two states (a Gilbert–Elliott channel: ``p``, ``r``, ``h_good``, ``h_bad`` are
        defined). O(m)."""
        return all(k == 2 for k in self.sizes)

    def _two_states(self, name: str) -> None:
        if not self.two_state:
            raise InputError("channel", f"{name} is a two-state (Gilbert–Elliott) chain's parameter; this channel's "
                                        f"chains have {list(self.sizes)} states")

    @property
    def p(self) -> np.ndarray:
        """P(good -> bad) = T_i[0, 1] per channel, (m,), of a channel whose chains all have two states. O(1).

        Raises
        ------
        InputError
            A chain with other than two states.
        """
        self._two_states("p")
        return self.padded_transition[:, 0, 1]

    @property
    def r(self) -> np.ndarray:
        """P(bad -> good) = T_i[1, 0] per channel, (m,), of a two-state channel (as
            [`p`][packetloss_cvx.model.channel.MarkovChannel.p]). O(1)."""
        self._two_states("r")
        return self.padded_transition[:, 1, 0]

    @property
    def h_good(self) -> np.ndarray:
        """The delivery probability in state 0 (good) per channel, (m,), of a two-state channel. O(1)."""
        self._two_states("h_good")
        return self.padded_delivery[:, 0]

    @property
    def h_bad(self) -> np.ndarray:
        """The delivery probability in state 1 (bad) per channel, (m,), of a two-state channel. O(1)."""
        self._two_states("h_bad")
        return self.padded_delivery[:, 1]

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

    @staticmethod
    def check_horizon(horizon: Any, per_step: int) -> None:
        """``horizon`` an integer >= 1 whose arrays (``per_step`` numbers a step) fit in MAX_ENTRIES."""
        if isinstance(horizon, bool) or not isinstance(horizon, int | np.integer) or horizon < 1:
            raise InputError("horizon", f"expected an integer >= 1, found {horizon!r}")
        if horizon * max(per_step, 1) > MAX_ENTRIES:
            raise InputError("horizon", f"expected at most {MAX_ENTRIES} numbers ({MAX_ENTRIES // max(per_step, 1)} "
                                        f"steps), found {horizon} steps")

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
        """One step of the prior: ``pi_{t+1} = pi_t T`` per channel; ``belief`` (..., m, K). O(m K^2) per belief."""
        return np.einsum("...ia,iab->...ib", belief, self.padded_transition)

    def beliefs(self, horizon: int, belief: np.ndarray | None = None) -> np.ndarray:
        """The state distributions at t = 0..horizon-1 from ``belief`` (default the initial one), (N, m, K).
        Constant from the stationary distribution, and from the first step whose propagated belief is the same floats
        (the rest are then copies, to the bit). Time O(N m K^2), O(L m K^2 + N m K) for a belief that reaches its
        float fixed point in L steps.

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
            if np.array_equal(b, out[t]):            # a fixed point of the float step: every later belief is b
                out[t + 1:] = b
                break
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
            at = tuple(np.argwhere(total[..., 0] <= 0.0)[0])
            raise InputError("delivered", f"channel {at[-1]}: outcome {'delivered' if v[at][0] else 'lost'} has "
                                          "probability 0 under the belief and the channel")
        return np.clip(self.propagate(joint / total), 0.0, 1.0)

    @property
    def state_dtype(self) -> type:
        """The integer type of sampled state indices: int8 (up to 127 states a chain), else int64. O(1)."""
        return np.int8 if self._stationary.shape[1] <= 127 else np.int64

    def draw_start(self, u: np.ndarray) -> np.ndarray:
        """The state index of each channel at the first planned step, drawn from the initial belief by inverting its
        cumulative distribution at the uniform numbers ``u`` (..., m): the number of cumulative probabilities
        ``P(state <= k)``, k < K - 1, at or below u (state 0 iff u < P(state 0)). O(size K).

        Examples
        --------
        >>> GilbertElliott(p=[0.1], r=[0.4], belief=[0.75]).draw_start(np.array([[0.7], [0.8]])).tolist()
        [[0], [1]]
        """
        below = np.cumsum(self.initial_belief, axis=1)
        out = np.zeros(u.shape, dtype=self.state_dtype)
        for k in range(below.shape[1] - 1):
            out += u >= below[:, k]
        return out

    def draw_next(self, states: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One step of every chain from state indices ``states`` (..., m): the row ``T_i[state]`` inverted at the
        uniform numbers ``u`` (..., m), as [`draw_start`][packetloss_cvx.model.channel.MarkovChannel.draw_start] inverts
        the start (Gilbert–Elliott: good iff u < 1 - p from good, u < r from bad). O(size K).

        Examples
        --------
        >>> ch = GilbertElliott(p=[0.1], r=[0.4])          # from good: good below 0.9; from bad: good below 0.4
        >>> ch.draw_next(np.array([[0], [0], [1]]), np.array([[0.85], [0.95], [0.3]])).tolist()
        [[0], [1], [0]]
        """
        rows = np.arange(self.m) * self._stationary.shape[1] + states        # (channel, state) in the flat rows
        out = np.zeros(u.shape, dtype=self.state_dtype)
        for below in self._below:                                           # P(next <= k | state), k < K - 1
            out += u >= below[rows]
        return out

    def with_belief(self, belief: Any) -> MarkovChannel:
        """The same chains (and table form) with another initial belief ((m, K), rescaled to sum to one per
        channel). O(m K^2).

        Examples
        --------
        >>> GilbertElliott(p=[0.1], r=[0.4]).with_belief([[0.3, 0.7]]).to_dict()["belief"]
        [0.3]
        """
        b = np.clip(np.asarray(belief, dtype=float), 0.0, 1.0)
        rows = [b[i, :k] / b[i, :k].sum() for i, k in enumerate(self.sizes)]
        out = MarkovChannel(transition=self.transition, delivery=self.delivery, belief=rows)
        object.__setattr__(out, "form", self.form)
        return out

    def reveals_state(self) -> bool:
        """True when every outcome reveals its channel's state: the delivery is certain in each state and the
        states' outcomes differ (so at most two states). O(m K)."""
        return all(np.all((d == 0) | (d == 1)) and len(set(d.tolist())) == d.size for d in self.delivery)

    def to_dict(self) -> dict[str, Any]:
        """The TOML ``[channel]`` table in the channel's form (``from_table`` reads it back).

        Examples
        --------
        >>> MarkovChannel(transition=[[[1.0]]], delivery=[[0.5]]).to_dict()
        {'model': 'markov', 'transition': [[[1.0]]], 'delivery': [[0.5]]}
        >>> GilbertElliott(p=[0.1], r=[0.3], state=["good"]).to_dict()
        {'model': 'gilbert-elliott', 'p': [0.1], 'r': [0.3], 'h_good': [1.0], 'h_bad': [0.0], 'state': ['good']}
        """
        if self.form == GE_MODEL:
            ge: dict[str, Any] = {"model": GE_MODEL, "p": self.p.tolist(), "r": self.r.tolist(),
                                  "h_good": self.h_good.tolist(), "h_bad": self.h_bad.tolist()}
            if self.belief is not None and self.state_given:
                ge["state"] = ["good" if b[0] == 1.0 else "bad" for b in self.belief]
            elif self.belief is not None:
                ge["belief"] = [float(b[0]) for b in self.belief]
            return ge
        out: dict[str, Any] = {"model": MODEL, "transition": [T.tolist() for T in self.transition],
                               "delivery": [d.tolist() for d in self.delivery]}
        if self.belief is not None and self.state_given:
            out["state"] = [int(np.argmax(b)) for b in self.belief]
        elif self.belief is not None:
            out["belief"] = [b.tolist() for b in self.belief]
        return out


def _restore(transition: list, delivery: list, belief: list | None, state_given: bool, form: str) -> MarkovChannel:
    """A pickled channel from its validated arrays (`MarkovChannel.__reduce__`). O(m K^3)."""
    out = object.__new__(MarkovChannel)
    out._freeze([_frozen(T) for T in transition], [_frozen(d) for d in delivery],
                None if belief is None else [_frozen(b) for b in belief], state_given, form, "transition")
    return out


def GilbertElliott(*, p: Any, r: Any, h_good: Any = 1.0, h_bad: Any = 0.0, state: Any = None, belief: Any = None,
                   prefix: str = "") -> MarkovChannel:
    """m independent Gilbert–Elliott channels as the one channel type:
        [`MarkovChannel.gilbert_elliott`][packetloss_cvx.model.channel.MarkovChannel.gilbert_elliott].

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.1], r=[0.4])
    >>> type(ch).__name__, ch.p.tolist(), ch.r.tolist(), ch.mean_rate.tolist()
    ('MarkovChannel', [0.1], [0.4], [0.8])
    """
    return MarkovChannel.gilbert_elliott(p=p, r=r, h_good=h_good, h_bad=h_bad, state=state, belief=belief,
                                         prefix=prefix)


def parse_channel(channel: Any) -> MarkovChannel:
    """A channel object, or the TOML ``[channel]`` table of either model (by its ``model`` key), validated. O(m K^3).

    Examples
    --------
    >>> type(parse_channel({"model": "markov", "transition": [[[1.0]]], "delivery": [[0.5]]})).__name__
    'MarkovChannel'
    """
    if isinstance(channel, MarkovChannel):
        return channel
    return MarkovChannel.from_table(channel)


def channel_schedule(channel: Any, m: int, horizon: int, mu: Any,
                     mu_schedule: Any) -> tuple[MarkovChannel | None, Any]:
    """For [`System`][packetloss_cvx.model.system.System]: ``(None, mu_schedule)`` without a channel; with one
    (a [`MarkovChannel`][packetloss_cvx.model.channel.MarkovChannel], e.g. a
    [`GilbertElliott`][packetloss_cvx.model.channel.GilbertElliott] one, or the TOML table of either model), the
    validated channel and its predicted schedule ``delivery_schedule(horizon)`` in place of mu. Giving mu or mu_schedule
    as well is an InputError. Time O(N m K^2).

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
        field = "channel.p" if chan.form == GE_MODEL else "channel.transition"
        raise DimensionError(field, f"expected {m} channels (one per actuator, the columns of B) but found {chan.m}")
    return chan, chan.delivery_schedule(horizon)
