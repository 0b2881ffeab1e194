"""What the actuator does when a packet is lost: zero, hold, or play the buffered plan, each a jump linear system.

A linear law ``u_k = -K x_k`` (``-K_c x_k`` per channel state c behind a chain, the state known to the controller as
in `.mjls`'s ``delivery="current"``) is sent to m actuators, actuator i's packet delivered with probability
``h_{c,i}`` (Bernoulli: ``mu_i``), independently given the channel state. On a loss the actuator

- ``zero``: applies nothing (the paper's model; today's loop, `.stability` and `.mjls`);
- ``hold``: applies its last applied input ``w`` (0 before the first packet). With ``z = (x, w)``,
  ``z+ = (Ã - B̃ V K̃) z``, ``Ã = [[A, B], [0, I]]``, ``B̃ = [B; I]``, ``K̃ = [K, I]``: the engine's own form over
  the channel's modes, the applied input ``w - V (K x + w)``. The held input is state: behind a link that never
  delivers (mu_i = 0) it is held for ever, so the radius is at least 1 (a held input other than the empty start's
  0 never decays), although from that start the loop is zero's;
- ``buffer:L``: each packet carries the law's next L planned inputs ``u_{k+j|k} = -K (A - B K)^j x_k``,
  j = 0..L-1 (the nominal prediction, every input delivered); on a loss the actuator plays the next entry of
  the last plan it received, and zero once the plan is exhausted (``buffer:L:hold``: its last applied input, the
  plan's last entry, kept in the memory instead of zeroed). The mode is the channel state c and, per
  actuator, the age ``alpha_i`` of the plan being played (0: delivered now, L: exhausted), so
  ``M_c (L + 1)^m`` modes; the state is ``z = (x, b_1, .., b_m)``, ``b_i`` the L - 1 entries after the first of
  actuator i's last plan, or, where one gain serves every channel state and n < L - 1, the plan's predicted state
  ``p_i`` (n entries: ``p_i <- (A - B K) p_i`` on a loss, the entry played ``-k_i p_i``); either is zeroed once
  exhausted, so that a plan never played again is not counted as state.
  Given the mode the step is deterministic (``x+ = A x + B a``, ``a_i = -k_i x``, ``b_i[alpha_i]`` or 0), the
  deliveries entering through the mode chain: ``P((c, alpha) -> (c', alpha')) = T_cc' prod_i q_i`` with
  ``q_i = h_{c',i}`` for ``alpha'_i = 0`` and ``1 - h_{c',i}`` for ``alpha'_i = min(alpha_i + 1, L)``.
  ``buffer:1`` is ``zero``.

Each is handed to the mode engine (`.modes`: per-mode plant A_a, the applied input ``F_a z - V K_a z``), so the
mean-square radius and the exact finite-horizon costs ``E[x'Omega x + a' Psi a]`` (a the applied input) are the
engine's. The state weight sees x only, the noise enters x only, and the actuator's memory starts empty.

What the controller knows. The costs here are those of the given law ``u = -K x``, which reads the state only
(and the channel state, behind a chain): they are the same under both protocols. Under a TCP-like protocol the
acknowledgements tell the controller, before it computes u_k, which packets arrived, hence the held input and the
age of every buffered plan (the whole mode): a law that depends on them is implementable, and the optimal one per
strategy solves the coupled Riccati equations over these modes. Under a UDP-like protocol it knows neither; it
must keep a belief over the held input and the buffer ages (from the state's history, exact only without noise
and with B of full column rank), and a mode-dependent law is not implementable: which optimal laws it can run is
`.actuator_design.check_protocol`'s decision.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..budgets import check, gib_text, operator_bytes
from ..errors import DimensionError, InputError, NumericalError
from ..model.channel import MarkovChannel
from ..model.system import System, check_system, loop_weights, numeric_array
from .mjls import mode_chain, mode_start
from .modes import mode_matrix, mode_radius, mode_stage_costs
from .moments import check_steps, stationary_channel
from .stability import check_law, is_mean_square_stable

__all__ = ["MAX_BUFFER_MODES", "STRATEGIES", "Actuator", "JumpLoop", "actuator_costs", "actuator_loop",
           "actuator_radius", "compare_actuators", "parse_actuators", "parse_actuator"]

#: The strategies, as ``--actuator`` and ``actuator=`` spell them (``buffer:L``, ``buffer`` alone: L = the horizon).
STRATEGIES = ("zero", "hold", "buffer")
#: The buffer's modes ``M_c (L + 1)^m`` (channel states times the actuators' plan ages) are refused beyond this:
#: its per-mode arrays and the engine's mode chain are dense (1024 modes: an 8 MiB transition matrix).
MAX_BUFFER_MODES = 1024


@dataclass(frozen=True)
class Actuator:
    """A strategy on a loss: ``kind`` one of `STRATEGIES`, ``length`` the buffer's L (1 for zero and hold),
    ``exhausted`` what a buffer plays once its plan is exhausted: "zero" or "hold" (its last applied input)."""

    kind: str
    length: int = 1
    exhausted: str = "zero"

    def __str__(self) -> str:
        if self.kind != "buffer":
            return self.kind
        return f"buffer:{self.length}" + (":hold" if self.exhausted == "hold" else "")


def parse_actuator(spec: str | Actuator, horizon: int | None = None) -> Actuator:
    """The strategy ``spec`` names: "zero", "hold", "buffer:L" with 1 <= L <= ``horizon`` (the plan's length), or
    "buffer" (L = ``horizon``); "buffer:L:hold" holds the last applied input once the plan is exhausted
    ("buffer:L:zero" is "buffer:L"; "buffer:1:hold" is "hold").

    Raises
    ------
    InputError
        Field ``actuator``, one line naming what is allowed.

    Examples
    --------
    >>> parse_actuator("buffer:3", horizon=5), str(parse_actuator("buffer", horizon=5))
    (Actuator(kind='buffer', length=3, exhausted='zero'), 'buffer:5')
    >>> parse_actuator("buffer:0")
    Traceback (most recent call last):
    packetloss_cvx.errors.InputError: actuator: expected zero, hold or buffer:L with an integer 1 <= L, found \
'buffer:0' (buffer:L:hold holds the last input once the plan is exhausted; buffer:L:zero, the default, applies zero)
    >>> str(parse_actuator("buffer:3:hold")), str(parse_actuator("buffer:3:zero")), str(parse_actuator("buffer:1:hold"))
    ('buffer:3:hold', 'buffer:3', 'hold')
    """
    if isinstance(spec, Actuator):
        spec = str(spec)
    bound = "" if horizon is None else f" <= {horizon} (the horizon)"
    allowed = (f"expected zero, hold or buffer:L with an integer 1 <= L{bound}, found {spec!r} (buffer:L:hold holds "
               "the last input once the plan is exhausted; buffer:L:zero, the default, applies zero)")
    if not isinstance(spec, str):
        raise InputError("actuator", allowed)
    kind, _, length = spec.strip().partition(":")
    length, _, exhausted = length.partition(":")
    if kind in ("zero", "hold") and not length and not exhausted:
        return Actuator(kind)
    if kind != "buffer" or (not length and horizon is None) or exhausted not in ("", "zero", "hold"):
        raise InputError("actuator", allowed)
    if not length:
        length = str(horizon)
    if not length.strip().isdigit() or int(length) < 1 or (horizon is not None and int(length) > horizon):
        raise InputError("actuator", allowed)
    if exhausted == "hold" and int(length) == 1:     # nothing buffered beyond the delivered input: hold itself
        return Actuator("hold")
    return Actuator("buffer", int(length), exhausted or "zero")


@dataclass(frozen=True)
class JumpLoop:
    """A strategy's loop in the mode engine's arrays (`.modes`): state ``z = embed x`` plus the actuator's
    memory (N entries), ``A`` (N, N) or per mode (M, N, N), ``B`` (N, m), gains ``K`` (m, N) or (M, m, N),
    deliveries ``h`` (m,) or (M, m), chain ``T`` (None: one mode) and ``start`` P(mode at 0), ``held`` the input
    applied whatever the delivery (None: nothing on a loss), ``embed`` (N, n)."""

    actuator: Actuator
    A: np.ndarray
    B: np.ndarray
    K: np.ndarray
    h: np.ndarray
    T: np.ndarray | None
    start: np.ndarray | None
    held: np.ndarray | None
    embed: np.ndarray

    @property
    def modes(self) -> int:
        return 1 if self.T is None else self.T.shape[0]

    def radius(self, method: str = "auto") -> float:
        """The engine's mean-square radius of this loop (`.modes.mode_radius`); the dense matrix refused
        beyond the ``operator_rows`` budget. Time O((M N^2)^3) dense, Krylov beyond."""
        dim = self.modes * self.A.shape[-1] ** 2

        def matrix() -> np.ndarray:
            size = gib_text(operator_bytes(dim))
            check("operator_rows", dim, "actuator", f"the {self.actuator} loop's second-moment operator, dense "
                  f"with {self.modes} modes * {self.A.shape[-1]}^2 = {dim} rows (about {size})",
                  instead="use method='krylov', a shorter buffer or fewer actuators")
            return mode_matrix(self.A, self.B, self.K, self.h, self.T)

        return mode_radius(self.A, self.B, self.K, self.h, self.T, "current", method, matrix,
                           label=f"mean-square radius ({self.actuator})")

    def stage_costs(self, Omega: np.ndarray, psi: np.ndarray, Sigma: np.ndarray, x0: np.ndarray,
                    steps: int) -> tuple[np.ndarray, float]:
        """Exact ``E[x_t' Omega x_t + a_t' Psi a_t]``, t < steps, and ``E[x_T' Omega x_T]`` from x0 (memory empty),
        noise Sigma on x (`.modes.mode_stage_costs`, the law broadcast over the steps: formed once)."""
        E = self.embed
        Omega_z, Sigma_z, z0 = E @ Omega @ E.T, E @ Sigma @ E.T, E @ x0
        K_all = np.broadcast_to(self.K, (steps, *self.K.shape))
        h_all = self.h if self.T is not None else np.broadcast_to(self.h, (steps, *self.h.shape))
        return mode_stage_costs(self.A, self.B, Omega_z, psi, Sigma_z, z0, K_all, h_all, self.T, self.start,
                                "current", held=self.held)


Channel = npt.ArrayLike | MarkovChannel


def actuator_loop(A: npt.ArrayLike, B: npt.ArrayLike, gain: npt.ArrayLike, channel: Channel,
                  actuator: str | Actuator = "zero") -> JumpLoop:
    """The loop of ``u = -K x`` behind ``channel`` (Bernoulli mu (m,), or a Gilbert–Elliott or k-state chain, then
    ``gain`` (m, n) or per state (M_c, m, n)) with the actuator's strategy on a loss, as the mode engine's arrays
    (module docstring). ``zero`` gives exactly the arrays of today's loop. Time O(M (N^2 + n^3 L)) for the buffer.

    Raises
    ------
    InputError
        Field ``actuator``: an unknown strategy, L < 1, or a buffer beyond `MAX_BUFFER_MODES` modes.
    DimensionError
        A gain or mu of the wrong shape.

    Examples
    --------
    >>> loop = actuator_loop([[2.0]], [[1.0]], [[1.0]], [0.5], "hold")      # z = (x, w): one mode, N = 2
    >>> loop.A.tolist(), loop.B.tolist(), loop.K.tolist(), loop.held.tolist()
    ([[2.0, 1.0], [0.0, 1.0]], [[1.0], [1.0]], [[1.0, 1.0]], [[0.0, 1.0]])
    """
    strategy = parse_actuator(actuator)
    if isinstance(channel, MarkovChannel):
        A_, B_ = check_law(A, B, np.zeros((np.shape(B)[1], np.shape(A)[0])), np.ones(np.shape(B)[1]))[:2]
        _, Tc, hc = mode_chain(channel)
        K = _state_gains(gain, Tc.shape[0], *B_.shape[::-1])
        start = mode_start(channel)
    else:
        A_, B_, K, mu = check_law(A, B, gain, channel)
        Tc, hc, start = None, mu, None
    n, m = B_.shape
    if strategy.kind == "zero":
        return JumpLoop(strategy, A_, B_, K, hc, Tc, start, None, np.eye(n))
    if strategy.kind == "hold":
        At = np.block([[A_, B_], [np.zeros((m, n)), np.eye(m)]])
        Bt = np.vstack([B_, np.eye(m)])
        Kt = np.concatenate([K, np.broadcast_to(np.eye(m), (*K.shape[:-1], m))], axis=-1)
        held = np.broadcast_to(np.hstack([np.zeros((m, n)), np.eye(m)]), Kt.shape).copy()
        return JumpLoop(strategy, At, Bt, Kt, hc, Tc, start, held, np.vstack([np.eye(n), np.zeros((m, n))]))
    return _buffer_loop(strategy, A_, B_, K, hc, Tc, start)


def _state_gains(gain: npt.ArrayLike, M: int, m: int, n: int) -> np.ndarray:
    """One (m, n) gain for every channel state, or (M, m, n) gains per state, as (M, m, n)."""
    K = numeric_array(gain, "gain")
    K = np.repeat(K[None], M, axis=0) if K.ndim == 2 else K
    if K.shape != (M, m, n):
        raise DimensionError("gain", f"expected ({m}, {n}) or ({M}, {m}, {n}) per channel state, found {K.shape}")
    return K


def _buffer_loop(strategy: Actuator, A: np.ndarray, B: np.ndarray, K: np.ndarray, hc: np.ndarray,
                 Tc: np.ndarray | None, start_c: np.ndarray | None) -> JumpLoop:
    """The buffer's modes (c, alpha), c major, alpha in {0..L}^m lexicographic, and their deterministic steps."""
    L, (n, m) = strategy.length, B.shape
    hold = strategy.exhausted == "hold"                              # L >= 2 (parse_actuator)
    Mc = 1 if Tc is None else Tc.shape[0]
    Tc = np.ones((1, 1)) if Tc is None else Tc
    hc = hc[None] if hc.ndim == 1 else hc
    Kc = K[None] if K.ndim == 2 else K
    start_c = np.ones(1) if start_c is None else start_c
    M = Mc * (L + 1) ** m
    if M > MAX_BUFFER_MODES:
        raise InputError("actuator", f"buffer:{L} behind {Mc} channel state(s) and {m} actuator(s) has "
                                     f"{Mc} * {L + 1}^{m} = {M} modes; expected at most {MAX_BUFFER_MODES}: use a "
                                     "shorter buffer")
    # the plan's memory per actuator: its predicted state p_i (n entries, one gain for every channel state: entry j
    # is -k_i (A - B K)^j x_k0, so p_i <- (A - B K) p_i and the entry played is -k_i p_i), or else its L - 1 entries
    predicted = n < L - 1 and all(np.array_equal(Kc[0], Kc[c]) for c in range(Mc))
    width = n if predicted else L - 1
    N = n + m * width
    check("memory_bytes", 8.0 * M * (3 * N * N + M), "actuator",
          f"buffer:{L}'s {M} mode matrices of {N}^2 entries (about {gib_text(8.0 * M * 3 * N * N)})",
          instead="use a shorter buffer")
    ages = np.array(list(itertools.product(range(L + 1), repeat=m)), dtype=int).reshape(-1, m)
    slot = [n + i * width for i in range(m)]                         # where actuator i's memory starts in z
    closed = [A - B @ Kc[c] for c in range(Mc)]
    plans = [[np.array([-Kc[c][i] @ np.linalg.matrix_power(closed[c], j) for j in range(1, L)]).reshape(L - 1, n)
              for i in range(m)] for c in range(Mc)]                 # per state: rows -k_i (A - B K)^j, j >= 1
    A_all, K_all = np.zeros((M, N, N)), np.zeros((M, m, N))
    held, h = np.zeros((M, m, N)), np.zeros((M, m))
    for c, (r, alpha) in itertools.product(range(Mc), enumerate(ages)):
        a = c * len(ages) + r
        A_all[a, :n, :n] = A
        K_all[a, :, :n] = Kc[c]
        for i, age in enumerate(alpha):
            rows = slice(slot[i], slot[i] + width)
            if age == 0:                                              # delivered: play -k_i x, keep the plan
                h[a, i] = 1.0
                A_all[a, rows, :n] = np.eye(n) if predicted else plans[c][i]
            elif age < L and predicted:                               # lost: advance the prediction, play it
                row = -Kc[c][i] @ closed[c]
                A_all[a, rows, rows] = closed[c]
                A_all[a, :n, rows] += np.outer(B[:, i], row)
                held[a, i, rows] = row
            elif age < L:                                             # lost: play entry alpha_i, keep the plan
                A_all[a, :n, slot[i] + age - 1] = B[:, i]
                held[a, i, slot[i] + age - 1] = 1.0
                A_all[a, rows, rows] = np.eye(L - 1)
            elif hold and predicted:                                  # exhausted, held: the last entry again
                row = -Kc[c][i]
                A_all[a, rows, rows] = np.eye(n)
                A_all[a, :n, rows] += np.outer(B[:, i], row)
                held[a, i, rows] = row
            elif hold:
                A_all[a, :n, slot[i] + L - 2] = B[:, i]
                held[a, i, slot[i] + L - 2] = 1.0
                A_all[a, rows, rows] = np.eye(L - 1)
    # the age chain: alpha'_i = 0 with P h_{c', i}, min(alpha_i + 1, L) with 1 - h_{c', i}
    delivered = ages == 0                                                              # (R, m)
    follows = ages[None, :, :] == np.minimum(ages + 1, L)[:, None, :]                  # [r, r', i]
    T = np.empty((M, M))
    start = np.empty(M)
    for c2 in range(Mc):
        p = np.where(delivered[None], hc[c2], 0.0) + np.where(follows, 1.0 - hc[c2], 0.0)   # [r, r', i]
        step = np.prod(p, axis=2)
        cols = slice(c2 * len(ages), (c2 + 1) * len(ages))
        for c in range(Mc):
            T[c * len(ages):(c + 1) * len(ages), cols] = Tc[c, c2] * step
        first = np.prod(np.where(delivered, hc[c2], np.where(ages == L, 1.0 - hc[c2], 0.0)), axis=1)
        start[cols] = start_c[c2] * first
    B_aug = np.vstack([B, np.zeros((N - n, m))])
    return JumpLoop(strategy, A_all, B_aug, K_all, h, T, start, held, np.vstack([np.eye(n), np.zeros((N - n, n))]))


def _system_loop(system: System, gain: npt.ArrayLike, actuator: str | Actuator,
                 mu: npt.ArrayLike | None) -> JumpLoop:
    system = check_system(system)
    strategy = parse_actuator(actuator, system.horizon)
    channel = system.channel if system.channel is not None and mu is None else (
        stationary_channel(system) if mu is None else mu)
    return actuator_loop(system.A, system.B, gain, channel, strategy)


def actuator_radius(system: System, gain: npt.ArrayLike, actuator: str | Actuator = "zero",
                    mu: npt.ArrayLike | None = None, method: str = "auto") -> float:
    """Mean-square radius of ``u = -K x`` on ``system``'s plant and channel (its chain, or ``mu``, default the
    stationary Bernoulli channel) with the actuator's strategy on a loss (< 1: mean-square stable). ``zero`` is
    [`.stability.mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius] (Bernoulli) and
    `.mjls.mean_square_radius` (a chain).

    Raises
    ------
    InputError
        Field ``actuator``: an unknown strategy, L < 1 or L beyond the horizon, or too many buffer modes.
    NumericalError, BudgetError
        As `.modes.mode_radius`.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> [round(actuator_radius(s, [[2.0]], a), 12) for a in ("zero", "buffer:1")]  # (2 - 1)^2 + 1/4 * 4
    [2.0, 2.0]
    """
    return _system_loop(system, gain, actuator, mu).radius(method)


def actuator_costs(system: System, gain: npt.ArrayLike, steps: int, actuator: str | Actuator = "zero",
                   mu: npt.ArrayLike | None = None) -> tuple[np.ndarray, float]:
    """Exact expected stage costs ``E[x_t' Omega_1 x_t + a_t' Psi_0 a_t]`` (a_t the applied input), t < steps, and
    ``E[x_T' Omega_1 x_T]`` of ``u = -K x`` from the system's x0 (noise Sigma_W each step) with the actuator's
    strategy on a loss; channel as `actuator_radius`. ``zero`` is
    [`.moments.finite_horizon_costs`][packetloss_cvx.closedloop.moments.finite_horizon_costs]
    (Bernoulli) and `.mjls.jump_law_stage_costs` (a chain). Time O(steps M (M N^2 + N^3)).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> stage, terminal = actuator_costs(s, [[1.0]], 1, "hold")   # x1 = 2 - v: E = 5/2; E[(v u)^2] = 1/2
    >>> stage.tolist(), terminal
    ([1.5], 2.5)
    """
    loop = _system_loop(system, gain, actuator, mu)
    check_steps(steps, loop.modes * loop.A.shape[-1] ** 2)
    return loop.stage_costs(*loop_weights(system), system.noise_cov, system.x0, steps)


def parse_actuators(text: str, horizon: int) -> tuple[Actuator, ...]:
    """A comma-separated list of strategies (`parse_actuator`), or "all": zero, hold and buffer:N (N the
    horizon: the whole plan), each once.

    >>> [str(a) for a in parse_actuators("all", 4)], [str(a) for a in parse_actuators("hold,buffer:2", 4)]
    (['zero', 'hold', 'buffer:4'], ['hold', 'buffer:2'])
    """
    parts = ["zero", "hold", "buffer"] if text.strip() == "all" else text.split(",")
    return tuple(dict.fromkeys(parse_actuator(part.strip(), horizon) for part in parts))


def compare_actuators(system: System, gain: npt.ArrayLike, steps: int | None = None,
                      actuators: str | tuple[Actuator, ...] = "all",
                      mu: npt.ArrayLike | None = None) -> dict[str, dict[str, float | bool | str]]:
    """The strategies side by side for one law: per strategy (its name as key) the mean-square ``radius``,
    ``stable`` (radius below 1 by MEAN_SQUARE_MARGIN) and ``cost``, the exact expected cost of ``steps`` steps from
    x0 (stage costs and the terminal ``x_T' Omega_1 x_T``; default steps: the horizon). A radius that cannot be
    computed is nan with its ``reason``. Time: the strategies' `actuator_radius` and `actuator_costs`.

    Examples
    --------
    >>> s = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.8], x0=[1.0])
    >>> rows = compare_actuators(s, [[0.6]])          # a slow law: holding stabilises it, zeroing does not
    >>> {name: row["stable"] for name, row in rows.items()}
    {'zero': False, 'hold': True, 'buffer:3': True}
    """
    system = check_system(system)
    steps = system.horizon if steps is None else steps
    strategies = parse_actuators(actuators, system.horizon) if isinstance(actuators, str) else actuators
    out: dict[str, dict[str, float | bool | str]] = {}
    for strategy in strategies:
        loop = _system_loop(system, gain, strategy, mu)
        check_steps(steps, loop.modes * loop.A.shape[-1] ** 2)
        try:
            radius, reason = loop.radius(), ""
        except NumericalError as err:
            radius, reason = float("nan"), str(err)
        stage, terminal = loop.stage_costs(*loop_weights(system), system.noise_cov, system.x0, steps)
        out[str(strategy)] = {"radius": radius, "stable": is_mean_square_stable(radius),
                              "cost": float(stage.sum() + terminal), "reason": reason}
    return out
