"""The optimal linear law per actuator strategy (TCP-like): the coupled Riccati equation over the strategy's modes.

Under a TCP-like protocol the controller knows, before it sends its packet at step k, every earlier delivery:
the channel state (behind a chain, as `.mjls`'s ``delivery="current"``), the input each actuator holds and, for a
buffer, the age of the plan each actuator plays on a loss. Its *information mode* s is

- ``zero``: the channel state c (the state z = x);
- ``hold``: c, with the held inputs as state (``z = (x, w)``, w the inputs applied at k - 1, 0 before the first);
- ``buffer:L``: ``(c, beta)``, ``beta_i`` in 1..L the age actuator i's last plan would have on a loss now (L: no
  entry left, the actuator applies zero; L at the start). The packet carries actuator i's whole plan
  ``U_i`` (L inputs, the decision ``u = (U_1, .., U_m)``, mL entries) and the state holds the plan's unplayed
  entries ``b_i`` (L - 1 per actuator: ``z = (x, b_1, .., b_m)``), zeroed once exhausted;
- ``buffer:L:hold``: as buffer:L, but a loss with no entry left (age L) plays the plan's last entry again, the
  input applied last (0 before the first packet): the memory ``b_i`` is kept, never zeroed. Hold is the case
  L = 1 with the applied input as the memory; one construction (`design_modes`) builds all four.

Given s, the deliveries d in {0, 1}^m of step k are independent with ``P(d_i = 1) = h_{c,i}`` and the step is
linear: ``z+ = A_sd z + B_sd u``, the applied input ``a = F_sd z + G_sd u``, the next information mode drawn from
``R_sd`` (the channel's transition, the ages' deterministic update). A quadratic cost-to-go ``z'P_s z`` gives,
with ``E_sd = sum_t R_sd(t) P_t`` and stage cost ``x'Omega x + a'Psi a``,

.. math:: P_s = H^{zz}_s - {H^{uz}_s}' K_s,\\quad K_s = (H^{uu}_s)^{-1} H^{uz}_s, \\qquad
   H_s = \\sum_d p_{sd} \\Big([F\\ G]_{sd}' \\Psi [F\\ G]_{sd} + [A\\ B]_{sd}' E_{sd} [A\\ B]_{sd}\\Big)
   + \\Omega\\oplus 0,

the law ``u = -K_s z``. For ``zero`` this is the channel's coupled Riccati equation (`.riccati.mode_riccati`; the
modified Riccati equation for Bernoulli links): the expectation over d written out instead of in closed form.
The linear law is optimal over all causal laws (LQ over a jump linear system with the mode's past known); the
equation is solved by the one solver, `.riccati.solve_bellman`, with the engine (`.modes`) for the radius and the
cost-to-go of a law: its closed loop is the engine's jump system over the modes (s, d), deterministic given the
mode, ``z+ = (A_sd - B_sd K_s) z``, applied input ``(F_sd - G_sd K_s) z``.

An input that reaches neither the plant nor the actuator's memory in any delivery pattern of positive probability
(its Hessian row exactly zero: a buffer's plan entries behind a link that never loses, or never delivers) gets the
gain 0; it changes nothing.

Without acknowledgements (UDP-like) the controller sees the state and its own packets only (`check_protocol`). On
Bernoulli links zero needs nothing more (past deliveries do not enter the future given x), and hold needs the
input applied last, which the state's history tells exactly when there is no process noise and B has full column
rank (``a_k-1 = B^+ (x_k - A x_k-1)``): there the TCP-like law is implementable and so the UDP-like optimum.
Elsewhere (a buffer's ages, hold with noise, any chain's state) the optimal law is nonlinear in general (the dual
effect) and the best linear one an output-feedback design without a Riccati equation: refused with
`UnobservedModeError` (docs/mathematics.md, "The actuator's strategy on a loss").
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..budgets import check, limit
from ..errors import InputError, NumericalError, UnobservedModeError
from ..linalg import frobenius
from ..model.channel import MarkovChannel
from ..model.system import System, check_system
from ..tolerances import MOMENT_RESIDUAL_RTOL, RICCATI_MAX_ITER
from .actuator import MAX_BUFFER_MODES, Actuator, JumpLoop, parse_actuator
from .mjls import mode_chain, mode_start
from .moments import check_steps, mode_cost_to_go, stationary_channel
from .riccati import Bellman, solve_bellman
from .stability import check_law

__all__ = ["PROTOCOLS", "ActuatorDesign", "DesignModes", "actuator_dp", "actuator_dp_finite", "check_protocol",
           "design_modes", "engine_rows"]

#: The controller's information: TCP-like (acknowledged deliveries) or UDP-like (not).
PROTOCOLS = ("tcp", "udp")


@dataclass(frozen=True)
class DesignModes:
    """A strategy's jump linear system as the TCP-like controller sees it (module docstring): S information modes,
    D = 2^m delivery patterns ``patterns`` (D, m), ``p`` (S, D) P(pattern | mode), per (s, d) the step ``A`` (S, D,
    N, N), ``B`` (S, D, N, r), the applied input ``F`` (S, D, m, N) and ``G`` (S, D, m, r), the next mode's law ``R``
    (S, D, S); ``start`` P(mode at 0), ``embed`` (N, n) the plant's state in z, ``labels`` a name per mode;
    ``state`` (S,) each mode's channel state, ``moves`` (S, D, S) the ages' update (``R_sd(t) = moves_sdt
    T_c(s)c(t)``) and ``h`` (M_c, m) the channel's delivery probabilities, for the exact certificates."""

    actuator: Actuator
    patterns: np.ndarray
    p: np.ndarray
    A: np.ndarray
    B: np.ndarray
    F: np.ndarray
    G: np.ndarray
    R: np.ndarray
    start: np.ndarray
    embed: np.ndarray
    labels: tuple[str, ...]
    state: np.ndarray
    moves: np.ndarray
    h: np.ndarray

    @property
    def modes(self) -> int:
        return self.p.shape[0]

    def step(self, P: np.ndarray, Omega: np.ndarray, psi: np.ndarray,
             least_squares: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``(K, P_prev)``: the greedy gains (S, r, N) for the cost-to-go P (S, N, N) and the Bellman right-hand side
        (module docstring), symmetrised. ``least_squares``: the Hessians' minimum-norm least-squares solution (the
        homogeneous map, no weights, whose Hessian may be singular: closedloop.actuator_region).
        O(S D (S N^2 + (N + r)^3)).

        Raises
        ------
        NumericalError
            A Hessian H^uu_s is singular beyond its exactly-zero rows.
        """
        E = np.tensordot(self.R, P, axes=(2, 0))
        AB = np.concatenate([self.A, self.B], axis=-1)                   # (S, D, N, N + r)
        FG = np.concatenate([self.F, self.G], axis=-1)                   # (S, D, m, N + r)
        weight = self.p[:, :, None, None]
        H = np.sum(weight * ((FG.mT * psi) @ FG + AB.mT @ E @ AB), axis=1)
        N = self.A.shape[-1]
        H[:, :N, :N] += Omega
        H = 0.5 * (H + H.mT)
        Huu, Huz = H[:, N:, N:].copy(), H[:, N:, :N].copy()
        idle = np.einsum("sii->si", Huu) == 0.0                         # exactly unreached inputs: gain 0
        Huu[idle[:, :, None] & np.eye(Huu.shape[-1], dtype=bool)] = 1.0
        Huz[idle] = 0.0
        try:
            K = np.stack([np.linalg.lstsq(a, b, rcond=None)[0] for a, b in zip(Huu, Huz, strict=True)]) \
                if least_squares else np.linalg.solve(Huu, Huz)
        except np.linalg.LinAlgError:
            raise NumericalError(f"{self.actuator}'s Riccati step: an input Hessian is singular") from None
        P_prev = H[:, :N, :N] - Huz.mT @ K
        return K, 0.5 * (P_prev + P_prev.mT)

    def loop(self, K: np.ndarray) -> JumpLoop:
        """The closed loop of ``u = -K_s z`` (K (S, r, N)) as the engine's jump system over the modes (s, d), s
        major: deterministic given the mode (``A_sd - B_sd K_s``, applied input ``(F_sd - G_sd K_s) z`` as the
        engine's held input, no random delivery left), the chain ``T_(sd)(te) = R_sd(t) p_te``. O(S D (N^2 r + S D)).
        """
        S, D, N, _ = self.A.shape
        m = self.F.shape[2]
        closed = (self.A - self.B @ K[:, None]).reshape(S * D, N, N)
        applied = (self.F - self.G @ K[:, None]).reshape(S * D, m, N)
        T = (self.R[:, :, :, None] * self.p[None, None]).reshape(S * D, S * D)
        start = (self.start[:, None] * self.p).reshape(S * D)
        zero = np.zeros((S * D, m))
        return JumpLoop(self.actuator, closed, np.zeros((N, m)), np.zeros((S * D, m, N)), zero, T, start, applied,
                        self.embed)

    def cost_to_go(self, K: np.ndarray, Omega: np.ndarray, psi: np.ndarray) -> np.ndarray:
        """The law's exact cost-to-go per information mode, ``P_s = sum_d p_sd Pi_sd``, Pi the engine's coupled
        Lyapunov solution over the modes (s, d) (`.moments.mode_cost_to_go`). Needs a mean-square stable law."""
        loop = self.loop(K)
        S, D = self.p.shape
        W = Omega + (loop.held.mT * psi) @ loop.held                      # x'Omega x + a'Psi a per (s, d)
        m = loop.B.shape[1]
        Pi = mode_cost_to_go(loop.A, loop.B, loop.K, loop.h, loop.T, W, np.zeros(m))
        return np.einsum("sd,sdij->sij", self.p, Pi.reshape(S, D, *Pi.shape[1:]))


def _memory(strategy: Actuator) -> tuple[int, bool, int]:
    """``(L, holding, width)``: the packet's entries per actuator (1 for zero and hold), whether a loss with no entry
    left plays the last applied input, and the actuator's memory in z per actuator: the plan's L - 1 entries after
    the first, or (hold) the input applied. O(1)."""
    L = strategy.length if strategy.kind == "buffer" else 1
    holding = strategy.kind == "hold" or strategy.exhausted == "hold"
    return L, holding, max(L - 1, 1) if holding else L - 1


def design_modes(A: npt.ArrayLike, B: npt.ArrayLike, channel: npt.ArrayLike | MarkovChannel,
                 actuator: str | Actuator = "zero") -> DesignModes:
    """The strategy's `DesignModes` behind ``channel`` (Bernoulli mu (m,), or a Gilbert–Elliott or k-state chain).
    Modes: ``M_c`` for zero and hold, ``M_c L^m`` for buffer:L and buffer:L:hold (refused beyond
    `MAX_BUFFER_MODES`). Time O(S D N (N + r)).

    Raises
    ------
    InputError
        Field ``actuator``: an unknown strategy, L < 1, or too many buffer modes.

    Examples
    --------
    >>> d = design_modes([[2.0]], [[1.0]], [0.5], "hold")        # z = (x, w); lost: x+ = 2x + w, w+ = w
    >>> d.patterns.tolist(), d.A[0, 0].tolist(), d.F[0, 0].tolist(), d.B[0, 1].tolist()
    ([[0.0], [1.0]], [[2.0, 1.0], [0.0, 1.0]], [[0.0, 1.0]], [[1.0], [1.0]])
    >>> d = design_modes([[2.0]], [[1.0]], [0.5], "buffer:2:hold")  # z = (x, b); exhausted, lost: plays b, keeps it
    >>> d.labels[1], d.A[1, 0].tolist(), d.F[1, 0].tolist()
    ('c0 ages (2,)', [[2.0, 1.0], [0.0, 1.0]], [[0.0, 1.0]])
    """
    strategy = parse_actuator(actuator)
    if isinstance(channel, MarkovChannel):
        A_, B_ = check_law(A, B, np.zeros((np.shape(B)[1], np.shape(A)[0])), np.ones(np.shape(B)[1]))[:2]
        _, Tc, hc = mode_chain(channel)
        start_c = mode_start(channel)
    else:
        A_, B_, _, mu = check_law(A, B, np.zeros((np.shape(B)[1], np.shape(A)[0])), channel)
        Tc, hc, start_c = np.ones((1, 1)), mu[None], np.ones(1)
    n, m = B_.shape
    Mc = Tc.shape[0]
    L, holding, width = _memory(strategy)
    skip = L - width                                   # the packet's entries not kept: the one applied on delivery
    ages = list(itertools.product(range(1, L + 1), repeat=m))
    S = Mc * len(ages)
    if S > MAX_BUFFER_MODES:
        raise InputError("actuator", f"{strategy} behind {Mc} channel state(s) and {m} actuator(s) has "
                                     f"{Mc} * {L}^{m} = {S} information modes; expected at most {MAX_BUFFER_MODES}: "
                                     "use a shorter buffer")
    patterns = np.array(list(itertools.product((0, 1), repeat=m)), dtype=float).reshape(-1, m)
    D = len(patterns)
    N, r = n + m * width, m * L
    check("memory_bytes", 8.0 * S * D * (N + r) * (N + r) * 3, "actuator",
          f"{strategy}'s {S * D} mode steps of {N + r}^2 entries", instead="use a shorter buffer")
    shape = (S, D)
    A_all, B_all = np.zeros((*shape, N, N)), np.zeros((*shape, N, r))
    F_all, G_all = np.zeros((*shape, m, N)), np.zeros((*shape, m, r))
    R, p, moves = np.zeros((*shape, S)), np.zeros(shape), np.zeros((*shape, S), dtype=bool)
    index = {(c, beta): c * len(ages) + j for c in range(Mc) for j, beta in enumerate(ages)}
    for (c, beta), s in index.items():
        for k, d in enumerate(patterns.astype(bool)):
            p[s, k] = np.prod(np.where(d, hc[c], 1.0 - hc[c]))
            A_all[s, k, :n, :n] = A_
            for i in range(m):
                mem = slice(n + i * width, n + (i + 1) * width)
                if d[i]:                                   # delivered: apply the packet's first entry, keep the rest
                    G_all[s, k, i, i * L] = 1.0            # (hold: the entry applied, as the held input)
                    B_all[s, k, :n, i * L] = B_[:, i]
                    B_all[s, k, mem, i * L + skip:(i + 1) * L] = np.eye(width)
                    continue
                played = beta[i] if beta[i] < L else (L - 1 if holding else None)
                if played is not None:                     # lost: play entry beta_i, or hold the last one
                    F_all[s, k, i, n + i * width + played - skip] = 1.0
                    A_all[s, k, :n, n + i * width + played - skip] = B_[:, i]
                if holding or beta[i] + 1 < L:             # keep the memory while an entry is left to play
                    A_all[s, k, mem, mem] = np.eye(width)
            nxt = tuple(np.where(d, 1, np.minimum(np.array(beta) + 1, L)).tolist())
            for c2 in range(Mc):
                R[s, k, index[(c2, nxt)]] += Tc[c, c2]
                moves[s, k, index[(c2, nxt)]] = True
    start = np.zeros(S)
    for c in range(Mc):
        start[index[(c, (L,) * m)]] = start_c[c]
    labels = tuple(f"c{c}" + (f" ages {beta}" if L > 1 else "") for (c, beta) in index)
    embed = np.vstack([np.eye(n), np.zeros((N - n, n))])
    state = np.array([c for (c, _) in index], dtype=int)
    return DesignModes(strategy, patterns, p, A_all, B_all, F_all, G_all, R, start, embed, labels, state, moves, hc)


@dataclass(frozen=True)
class ActuatorDesign:
    """The optimal TCP-like linear law of a strategy: gains ``K`` (S, r, N) per information mode (u = -K_s z),
    cost-to-go ``P`` (S, N, N), the engine's mean-square ``radius`` of its loop, ``cost`` the average stage cost
    under noise (``sum_(s,d) pi_sd tr(E_sd Sigma_z)``, pi the stationary law of the modes), ``initial`` the total
    noise-free cost from x0 (``sum_s start_s z0' P_s z0``), and the solver's ``iterations`` and ``residual``."""

    modes: DesignModes
    K: np.ndarray
    P: np.ndarray
    radius: float
    cost: float
    initial: float
    iterations: int
    residual: float

    def to_dict(self) -> dict[str, object]:
        return {"actuator": str(self.modes.actuator), "radius": self.radius, "average_stage_cost": self.cost,
                "initial_cost": self.initial, "iterations": self.iterations, "residual": self.residual,
                "modes": self.modes.modes}


def check_protocol(system: System, actuator: str | Actuator, protocol: str = "tcp",
                   mu: npt.ArrayLike | None = None) -> Actuator:
    """The strategy, once it is checked that ``protocol``'s controller can run the TCP-like optimal law of
    ``actuator`` on ``system`` (its chain, or Bernoulli ``mu``), so that law is its optimum too. TCP-like: always.
    UDP-like (the state and its own packets known, no acknowledgement), on Bernoulli links only: zero (the past
    deliveries do not enter the future given x), and hold without process noise and with B of full column rank
    (the input applied last is ``B^+ (x_k - A x_k-1)``, the whole mode). O(n m^2).

    Raises
    ------
    InputError
        Field ``protocol``: neither "tcp" nor "udp".
    UnobservedModeError
        Field ``protocol``: a UDP-like request the controller's information does not determine, saying why and what
        to use instead (docs/mathematics.md, "The actuator's strategy on a loss").

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> str(check_protocol(s, "hold", "udp"))          # no noise: x_k - 2 x_k-1 is the input applied
    'hold'
    >>> try:
    ...     check_protocol(s, "buffer:2", "udp")
    ... except UnobservedModeError as err:
    ...     print(err.field, "|", err.detail[:72])
    protocol | buffer:2's optimal law without acknowledgements is not computed: the age
    """
    system = check_system(system)
    strategy = parse_actuator(actuator, system.horizon)
    if protocol not in PROTOCOLS:
        raise InputError("protocol", f"expected tcp or udp, found {protocol!r}")
    if protocol == "tcp":
        return strategy
    chain = system.channel is not None and mu is None
    noisy = bool(np.any(system.noise_cov != 0.0))
    full_rank = np.linalg.matrix_rank(system.B) == system.m
    if chain:
        why = ("the channel state behind the chain is hidden (the state reveals a delivery only where the input "
               "applied differs from what a loss applies), and the optimal law depends on a belief over it that the "
               "law itself shapes")
    elif strategy.kind == "zero" or (strategy.kind == "hold" and not noisy and full_rank):
        return strategy
    elif strategy.kind == "hold":
        why = ("the input each actuator holds is hidden: " + ("with process noise" if noisy else
               "with B of rank below its columns") + " the state's history tells it only as a Gaussian mixture over "
               "the delivery histories")
    else:
        why = ("the age of the plan each actuator plays is hidden (the state tells a delivery only where the "
               "packet's first entry differs from the entry the old plan plays, which the law does not control)")
    raise UnobservedModeError(
        "protocol", f"{strategy}'s optimal law without acknowledgements is not computed: {why}, so the optimal law "
        "is nonlinear in general (the input chosen now changes what the next state reveals: the dual effect) and the "
        "best law linear in the observations is an output-feedback design of a jump linear system whose mode is not "
        "observed, with no Riccati equation; use protocol tcp (acknowledgements), or evaluate a given law's exact "
        "cost and radius (closedloop.actuator.actuator_costs, actuator_radius; solve --actuator)")


def _system_modes(system: System, actuator: str | Actuator, mu: npt.ArrayLike | None) -> DesignModes:
    system = check_system(system)
    strategy = parse_actuator(actuator, system.horizon)
    channel = system.channel if system.channel is not None and mu is None else (
        stationary_channel(system) if mu is None else mu)
    return design_modes(system.A, system.B, channel, strategy)


def _weights(system: System, modes: DesignModes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    E = modes.embed
    return E @ system.state_weights[0] @ E.T, np.asarray(system.input_weights[0], dtype=float), \
        E @ system.noise_cov @ E.T


def actuator_dp(system: System, actuator: str | Actuator = "zero", mu: npt.ArrayLike | None = None,
                max_iter: int | None = None,
                proves: Callable[[DesignModes, np.ndarray], bool] | None = None,
                protocol: str = "tcp") -> ActuatorDesign:
    """The stationary optimal TCP-like linear law of ``actuator`` on ``system`` (stage weights Omega_1 and Psi_0,
    noise Sigma_W; its chain, or ``mu``, default the stationary Bernoulli channel): the stabilising solution of the
    coupled Riccati equation over the strategy's modes (module docstring), by `.riccati.solve_bellman`. ``zero`` is
    `.riccati.dp_riccati` (Bernoulli) and `.mjls.coupled_riccati` (a chain). ``protocol="udp"``: the same law where
    a UDP-like controller can run it, its optimum there (`check_protocol`). Time O(iterations S D (S N^2 +
    (N + r)^3)) plus the engine's coupled Lyapunov solve per policy step.

    Raises
    ------
    InputError
        Field ``actuator``: an unknown strategy, L < 1 or beyond the horizon, or too many modes.
    UnobservedModeError
        Field ``protocol``: a UDP-like request whose optimal law is not computed (`check_protocol`).
    NumericalError
        No verdict: no convergence, a limit that is not stabilising, or a residual above MOMENT_RESIDUAL_RTOL (a
        diverging iteration is a proof only through ``proves(modes, P)``, closedloop.actuator_region's exact check
        that P's direction bounds every law's radius by 1: then the reason starts "coupled Riccati equations
        (...): no stabilising solution").

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> d = actuator_dp(s, "hold")          # every packet arrives: the DARE on x, P = 2 + sqrt(5), the held input free
    >>> bool(np.allclose(d.P[0], [[2 + 5 ** 0.5, 0.0], [0.0, 0.0]]))
    True
    """
    system = check_system(system)
    check_protocol(system, actuator, protocol, mu)
    modes = _system_modes(system, actuator, mu)
    Omega, psi, Sigma = _weights(system, modes)
    S, N, r = modes.modes, modes.A.shape[-1], modes.B.shape[-1]
    _check_rows(modes, system.horizon)

    def radius(K: np.ndarray) -> float:
        return modes.loop(K).radius()

    top = float(np.abs(system.B).max(initial=0.0))
    scale = max(frobenius(Omega), float(np.max(psi, initial=0.0)),
                float(np.max(psi, initial=0.0)) / max(top * top, np.finfo(float).tiny))
    problem = Bellman(step=lambda P: modes.step(P, Omega, psi), radius=radius,
                      cost_to_go=lambda K: modes.cost_to_go(K, Omega, psi),
                      start=np.repeat(Omega[None], S, axis=0), scale=scale, gain_shape=(S, r, N), definite=False)
    K, P, iterations, residual, rad = solve_bellman(
        problem, proves=(lambda P: False) if proves is None else (lambda P: proves(modes, P)),
        max_iter=RICCATI_MAX_ITER if max_iter is None else max_iter,
        label=f"coupled Riccati equations ({modes.actuator})", where="")
    loop = modes.loop(K)
    pi = _stationary(loop.T)
    E = np.einsum("sdt,tij->sdij", modes.R, P).reshape(-1, N, N)
    cost = float(np.einsum("a,aij,ij->", pi, E, Sigma))
    z0 = modes.embed @ system.x0
    initial = float(np.einsum("s,i,sij,j->", modes.start, z0, P, z0))
    return ActuatorDesign(modes, K, P, rad, cost, initial, iterations, residual)


def engine_rows(modes: DesignModes) -> int:
    """Rows of the engine's second-moment operator for a law of the strategy: ``S D N^2`` (the modes (s, d))."""
    return modes.modes * len(modes.patterns) * modes.A.shape[-1] ** 2


def _check_rows(modes: DesignModes, horizon: int) -> None:
    """Refuse a strategy whose law's radius (ARPACK over `engine_rows`, twice a policy step) is over the
    ``actuator_rows`` budget, naming the longest buffer within it. O(L)."""
    rows = engine_rows(modes)
    if rows <= limit("actuator_rows"):
        return
    m, n = modes.patterns.shape[1], modes.embed.shape[1]
    Mc, D = modes.h.shape[0], len(modes.patterns)
    fits = [L for L in range(1, horizon + 1) if Mc * L ** m * D * (n + m * (L - 1)) ** 2 <= limit("actuator_rows")]
    check("actuator_rows", rows, "actuator", f"{modes.actuator}'s optimal law, its loop's second-moment operator "
          f"of {modes.modes} * {D} modes * {modes.A.shape[-1]}^2 = {rows} rows",
          instead=f"use buffer:{fits[-1]} or shorter" if fits else "use zero or hold")


def _stationary(T: np.ndarray) -> np.ndarray:
    """A stationary law of the row-stochastic T (the eigenvector of eigenvalue 1, normalised). O(M^3)."""
    w, V = np.linalg.eig(T.T)
    if np.count_nonzero(np.abs(w - 1.0) < 1e-9) != 1:
        raise NumericalError("the modes' chain has no unique stationary law (a reducible channel): the average "
                             "cost depends on where it starts")
    v = np.real(V[:, int(np.argmin(np.abs(w - 1.0)))])
    v = np.abs(v) / np.abs(v).sum()
    if frobenius(v @ T - v) > MOMENT_RESIDUAL_RTOL:
        raise NumericalError("the modes' stationary law: no unique eigenvector of eigenvalue 1")
    return v


def actuator_dp_finite(system: System, steps: int, actuator: str | Actuator = "zero",
                       mu: npt.ArrayLike | None = None, protocol: str = "tcp") -> tuple[np.ndarray, float]:
    """The finite-horizon TCP-like optimum of ``actuator`` over ``steps`` steps with terminal cost x_T'Omega x_T:
    ``(gains, cost)``, ``gains[t]`` (S, r, N) the law at step t per information mode, and the optimal expected
    cost from x0 with noise, ``sum_s start_s z0'P_0,s z0 + sum_t sum_(s,d) P(s_t = s) p_sd tr(E_t+1,sd Sigma_z)``.
    ``protocol="udp"``: as `actuator_dp`. Time O(steps S D (S N^2 + (N + r)^3)).

    Raises
    ------
    NumericalError
        The cost-to-go overflows.
    UnobservedModeError
        Field ``protocol``: a UDP-like request whose optimal law is not computed (`check_protocol`).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> gains, cost = actuator_dp_finite(s, 1, "buffer:2")   # one DARE step: K = 1/2, cost 1 + 1/4 + 1/4
    >>> float(gains[0, 0, 0, 0]), cost
    (0.5, 1.5)
    """
    system = check_system(system)
    check_protocol(system, actuator, protocol, mu)
    modes = _system_modes(system, actuator, mu)
    Omega, psi, Sigma = _weights(system, modes)
    S, N, r = modes.modes, modes.A.shape[-1], modes.B.shape[-1]
    _check_rows(modes, system.horizon)
    check_steps(steps, S * N * N)
    P = np.repeat(Omega[None], S, axis=0)
    gains, noise = np.empty((steps, S, r, N)), np.empty((steps, S))
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps - 1, -1, -1):
            E = np.einsum("sdt,tij->sdij", modes.R, P)
            noise[t] = np.einsum("sd,sdij,ij->s", modes.p, E, Sigma)      # the noise entering x_t+1, per mode at t
            gains[t], P = modes.step(P, Omega, psi)
    pi, total = modes.start.copy(), 0.0
    for t in range(steps):
        total += float(pi @ noise[t])
        pi = np.einsum("s,sd,sdt->t", pi, modes.p, modes.R)
    z0 = modes.embed @ system.x0
    cost = float(np.einsum("s,i,sij,j->", modes.start, z0, P, z0)) + total
    if not (np.isfinite(cost) and np.all(np.isfinite(gains))):
        raise NumericalError(f"finite-horizon DP ({modes.actuator}): the cost-to-go overflows")
    return gains, cost
