"""Gilbert–Elliott channels: the validated, immutable description of bursty (Markov) links.

Channel i is a two-state Markov chain S_{i,t} in {good, bad} with

    p_i = P(S_{t+1} = bad | S_t = good),   r_i = P(S_{t+1} = good | S_t = bad),

and a packet sent at step t arrives with probability ``h_good_i`` in the good state and
``h_bad_i`` in the bad one (the Gilbert channel: ``h_good = 1, h_bad = 0``). Channels are
independent of each other and of the noise. ``belief[i] = P(S_{i,0} = good)`` is the
information at the first planned step; without one, the stationary distribution
``pi_good = r / (p + r)`` is used. Its predicted delivery probabilities
``mu_{i,t} = h_bad + (h_good - h_bad) b_{i,t}``, ``b_{t+1} = r + (1 - p - r) b_t``, are the
schedule a :class:`~packetloss_cvx.model.system.System` with this channel carries (the "plug-in" mu_t).

TOML (docs/design.md §4 and "Bursty links"): ``[channel] model = "gilbert-elliott"`` with per-channel arrays
``p``, ``r``, optional ``h_good`` (default 1), ``h_bad`` (default 0), and at most one of
``state = ["good", "bad"]`` or ``belief = [0.9, 0.2]``.

Every error names its field (``channel.p``, ``channel.belief``) and says what was expected.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import DimensionError, InputError, ProbabilityError
from .validation import MAX_ENTRIES

__all__ = ["MODEL", "GilbertElliott"]

#: The one Markov channel model the TOML schema knows.
MODEL = "gilbert-elliott"
_KEYS = ("model", "p", "r", "h_good", "h_bad", "state", "belief")
_STATES = {"good": 1.0, "bad": 0.0}


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
    arr.setflags(write=False)
    return arr


def _states(value: Any, field: str, m: int) -> np.ndarray:
    items = [value] * m if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)) or not all(isinstance(s, str) for s in items):
        raise InputError(field, f'expected a list of "good" / "bad", one per channel, found {str(value)[:40]!r}')
    if len(items) != m:
        raise DimensionError(field, f"expected {m} states (one per channel) but found {len(items)}")
    wrong = [s for s in items if s not in _STATES]
    if wrong:
        raise InputError(field, f'expected "good" or "bad", found {wrong[0][:20]!r}')
    arr = np.array([_STATES[s] for s in items])
    arr.setflags(write=False)
    return arr


class GilbertElliott:
    """m independent two-state Markov (Gilbert–Elliott) packet-loss channels.

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
    >>> ch = GilbertElliott(p=[0.1], r=[0.4])
    >>> ch.stationary.tolist(), ch.correlation.tolist()
    ([0.8], [0.5])
    >>> ch.delivery_schedule(3)[:, 0].tolist()
    [0.8, 0.8, 0.8]
    """

    __slots__ = ("p", "r", "h_good", "h_bad", "belief", "state_given")

    p: np.ndarray
    r: np.ndarray
    h_good: np.ndarray
    h_bad: np.ndarray
    belief: np.ndarray | None
    state_given: bool

    def __init__(self, *, p: Any, r: Any, h_good: Any = 1.0, h_bad: Any = 0.0, state: Any = None,
                 belief: Any = None, prefix: str = "") -> None:
        p_ = _rates(p, prefix + "p", None)
        m = p_.size
        r_ = _rates(r, prefix + "r", m)
        hg, hb = _rates(h_good, prefix + "h_good", m), _rates(h_bad, prefix + "h_bad", m)
        if state is not None and belief is not None:
            raise InputError(prefix + "state/belief", "expected at most one of the two, found both")
        b = _states(state, prefix + "state", m) if state is not None else (
            None if belief is None else _rates(belief, prefix + "belief", m))
        if b is None and np.any(p_ + r_ == 0):
            i = int(np.argmax(p_ + r_ == 0))
            raise InputError(prefix + "p", f"channel {i} has p + r = 0: the chain never moves, so it has no unique "
                                           "stationary distribution; give state or belief")
        for key, value in (("p", p_), ("r", r_), ("h_good", hg), ("h_bad", hb), ("belief", b),
                           ("state_given", state is not None)):
            object.__setattr__(self, key, value)

    @classmethod
    def from_table(cls, table: Mapping[str, Any], prefix: str = "channel.") -> GilbertElliott:
        """Build from the TOML ``[channel]`` table (keys model, p, r, h_good, h_bad, state, belief).

        Examples
        --------
        >>> ch = GilbertElliott.from_table({"model": "gilbert-elliott", "p": [0.1], "r": [0.4], "state": ["bad"]})
        >>> ch.initial_belief.tolist(), GilbertElliott.from_table(ch.to_dict()).to_dict() == ch.to_dict()
        ([0.0], True)
        """
        if not isinstance(table, Mapping):
            raise InputError(prefix.rstrip("."), f"expected a table, found {type(table).__name__}")
        unknown = [k for k in table if k not in _KEYS]
        if unknown:
            raise InputError(prefix + str(unknown[0]), f"unknown key; expected one of {', '.join(_KEYS)}")
        if table.get("model") != MODEL:
            found = "nothing" if "model" not in table else repr(table["model"])[:40]
            raise InputError(prefix + "model", f'expected "{MODEL}" (the Markov channel model), found {found}')
        for key in ("p", "r"):
            if key not in table:
                raise InputError(prefix + key, "missing field (one per channel)")
        kwargs = {k: table[k] for k in _KEYS[1:] if k in table}
        return cls(**kwargs, prefix=prefix)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("GilbertElliott is immutable: build a new one")

    def __copy__(self) -> GilbertElliott:
        return self          # immutable, its arrays read-only

    def __deepcopy__(self, memo: dict) -> GilbertElliott:
        return self

    def __reduce__(self) -> tuple:
        """Pickling rebuilds the channel from its TOML table through the validating constructor. O(m)."""
        return GilbertElliott.from_table, (self.to_dict(),)

    def __repr__(self) -> str:
        """The parameters that differ from the defaults: h_good, h_bad only when not the Gilbert (1, 0), the state
        or belief only when given (``GilbertElliott(m=1, p=[0.1], r=[0.4], state=['bad'])``)."""
        extra = "" if np.all(self.h_good == 1) and np.all(self.h_bad == 0) else (
            f", h_good={self.h_good.tolist()}, h_bad={self.h_bad.tolist()}")
        if self.belief is not None:
            extra += (f", state={['good' if b == 1 else 'bad' for b in self.belief]}" if self.state_given
                      else f", belief={self.belief.tolist()}")
        return f"GilbertElliott(m={self.m}, p={self.p.tolist()}, r={self.r.tolist()}{extra})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GilbertElliott):
            return NotImplemented
        same = [np.array_equal(getattr(self, k), getattr(other, k)) for k in ("p", "r", "h_good", "h_bad")]
        beliefs = (self.belief is None and other.belief is None) or (
            self.belief is not None and other.belief is not None and np.array_equal(self.belief, other.belief))
        return all(same) and beliefs

    __hash__ = None  # type: ignore[assignment]

    @property
    def m(self) -> int:
        """Number of channels."""
        return self.p.size

    @property
    def correlation(self) -> np.ndarray:
        """lambda_i = 1 - p_i - r_i: the chain's second eigenvalue (0 memoryless, > 0 bursty)."""
        return 1.0 - self.p - self.r

    @property
    def correlated(self) -> bool:
        """Whether deliveries may be correlated across steps (some lambda_i != 0). O(m)."""
        return bool(np.any(self.correlation))

    @property
    def stationary(self) -> np.ndarray:
        """pi_good = r / (p + r) per channel (the initial belief where p + r = 0 and one is given)."""
        total = self.p + self.r
        fallback = self.belief if self.belief is not None else np.zeros(self.m)
        return np.where(total > 0, self.r / np.where(total > 0, total, 1.0), fallback)

    @property
    def initial_belief(self) -> np.ndarray:
        """P(good) at the first planned step: the given belief or state, else the stationary one."""
        return self.belief if self.belief is not None else self.stationary

    @property
    def mean_rate(self) -> np.ndarray:
        """The long-run delivery rate h_bad + (h_good - h_bad) pi_good."""
        return self.h_bad + (self.h_good - self.h_bad) * self.stationary

    def beliefs(self, horizon: int, belief: np.ndarray | None = None) -> np.ndarray:
        """P(S_{i,t} = good) for t = 0..horizon-1 from ``belief`` (default the initial one), (N, m).
        b_{t+1} = r + lambda b_t (constant from the stationary distribution). Time O(N m).

        Raises
        ------
        InputError
            ``horizon`` not an integer >= 1 or beyond MAX_ENTRIES numbers; ``belief`` not m probabilities.
        """
        self.check_horizon(horizon, self.m)
        if belief is not None:
            belief = _rates(belief, "belief", self.m)
        if belief is None and self.belief is None:      # stationary: exactly constant (no drift by rounding)
            return np.repeat(self.stationary[None], horizon, axis=0)
        b = np.array(self.initial_belief if belief is None else belief, dtype=float)
        out = np.empty((horizon, self.m))
        for t in range(horizon):
            out[t] = b
            b = self.r + self.correlation * b
        return out

    @staticmethod
    def check_horizon(horizon: Any, per_step: int) -> None:
        """``horizon`` an integer >= 1 whose arrays (``per_step`` numbers a step) fit in MAX_ENTRIES."""
        if isinstance(horizon, bool) or not isinstance(horizon, int | np.integer) or horizon < 1:
            raise InputError("horizon", f"expected an integer >= 1, found {horizon!r}")
        if horizon * max(per_step, 1) > MAX_ENTRIES:
            raise InputError("horizon", f"expected at most {MAX_ENTRIES} numbers ({MAX_ENTRIES // max(per_step, 1)} "
                                        f"steps), found {horizon} steps")

    def propagate(self, belief: np.ndarray) -> np.ndarray:
        """One step of the prior, ``b_{t+1} = r + lambda b_t``; ``belief`` (..., m). O(m) per belief."""
        return self.r + self.correlation * belief

    def with_belief(self, belief: Any) -> GilbertElliott:
        """The same chains with another initial P(good), (m,) (clipped to [0, 1]). O(m)."""
        return GilbertElliott(p=self.p, r=self.r, h_good=self.h_good, h_bad=self.h_bad,
                              belief=np.clip(belief, 0.0, 1.0))

    def delivery_schedule(self, horizon: int, belief: np.ndarray | None = None) -> np.ndarray:
        """Predicted mu_{i,t} = h_bad + (h_good - h_bad) b_{i,t}, (N, m), clipped to [0, 1]. Time O(N m).

        Examples
        --------
        >>> ch = GilbertElliott(p=[0.1], r=[0.3], h_good=[0.9], h_bad=[0.1], belief=[1.0])
        >>> bool(np.allclose(ch.delivery_schedule(2)[:, 0], [0.9, 0.1 + 0.8 * 0.9]))     # h_bad + (h_good - h_bad) b_t
        True
        """
        mu = self.h_bad + (self.h_good - self.h_bad) * self.beliefs(horizon, belief)
        return np.clip(mu, 0.0, 1.0)

    def to_dict(self) -> dict[str, Any]:
        """The TOML ``[channel]`` table (``from_table`` reads it back).

        Examples
        --------
        >>> GilbertElliott(p=[0.1], r=[0.3], state=["good"]).to_dict()
        {'model': 'gilbert-elliott', 'p': [0.1], 'r': [0.3], 'h_good': [1.0], 'h_bad': [0.0], 'state': ['good']}
        """
        out: dict[str, Any] = {"model": MODEL, "p": self.p.tolist(), "r": self.r.tolist(),
                               "h_good": self.h_good.tolist(), "h_bad": self.h_bad.tolist()}
        if self.belief is not None and self.state_given:
            out["state"] = ["good" if b == 1.0 else "bad" for b in self.belief]
        elif self.belief is not None:
            out["belief"] = self.belief.tolist()
        return out

