"""What a loop attains at an allocation's mu: the attainable cost and the mean-square verdict of the best linear law.

The paper's TCP-like cost J*_tcp is a first-moment value that no causal law attains (docs/claims.md); an
allocation designed on it (``J*_tcp(mu*) <= alpha``) may leave the loop costing several times alpha, or with no
linear law that holds it mean-square stable. Every allocation result therefore carries, at its mu*:

* ``attainable_cost``: the least expected cost a causal law of the protocol reaches over the horizon, on the
  paper's cost (``x0'Q x0 + sum_t E[x_{t+1}'Omega_{t+1} x_{t+1} + (V_t u_t)'Psi_t (V_t u_t)]`` plus the noise).
  TCP-like: the finite-horizon dynamic programme with acknowledgements (`tcp_attainable_cost`: the
  modified Riccati recursion backwards from ``P_N = Omega_N``; Schenato et al. 2007); behind a Markov chain, the
  same programme over the beliefs the acknowledgements reach (closedloop.chain_dp.chain_attainable: exact, or
  beyond its budget None with both bounds in the note), with the chain at mu* along the allocation's family
  (`.chains`: burstiness held on Gilbert channels, deliveries scaled on the others). UDP-like: the exact expected
  cost of the optimal plan applied open loop, which the paper's J*_udp already is (behind a chain, the exact
  expected cost under the chain that the allocation was designed on);
* ``stabilisable``: True / False / None: is mu* in the stabilisable set S, i.e. does some linear law u = -K x
  hold the loop mean-square stable ([`membership`][packetloss_cvx.closedloop.region.membership], each verdict a
  certificate checked in numpy; None with the reason where no form decides or where it is not computed). Behind a
  Markov chain (`chain_stabilisable`), over the chain at mu* along the allocation's family, by the chain region
  engine (closedloop.markov_region.chain_least_radius) with both certificates re-checked in exact arithmetic
  (closedloop.certificates): where the acknowledgements reveal the chain state (every state delivers always or
  never, a Gilbert channel) the class decided is the mode-dependent linear laws ``u = -K_a x`` on the state the
  last acknowledgement revealed, which TCP-like controllers implement; where they do not, False still decides
  (the certificate bounds every causal law whose input is chosen before its step's deliveries, linear or not, on
  acknowledgements or on the state), True only for a law that ignores the chain state (one gain ``u = -K x``,
  tried at the mode gains of the least radius), and otherwise None with the reason (the laws on acknowledgement
  histories are not decided). A UDP-like allocation's loop gets no acknowledgements: the state-free class always.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..budgets import limit
from ..closedloop.certificates import chain_law_proved_stable, chain_outside_proved
from ..closedloop.chain_dp import chain_attainable, chain_dp
from ..closedloop.law_stability import STABILITY_MAX_N
from ..closedloop.markov_region import chain_least_radius
from ..closedloop.mjls import mean_square_radius
from ..closedloop.modes import mode_stage_costs
from ..closedloop.region import membership
from ..closedloop.riccati import dp_backward
from ..closedloop.stability import is_mean_square_stable
from ..errors import InputError, NumericalError, ResourceError
from ..model.system import System
from ..tolerances import SELF_CHECK_RTOL
from .chains import chain_family

__all__ = ["ATTAINABLE_MAX_N", "CHEAP_FORMS", "LMI_MAX_N", "AttainableEvaluator", "Attainment",
           "ChainAttainableEvaluator", "attainment",
           "chain_cost", "chain_stabilisable", "forward_cost", "revealing", "stabilisable",
           "tcp_attainable_cost"]

#: the verdict is computed up to this state dimension (as ``solve`` and ``closed_form``): beyond, the homogeneous
#: Riccati eigenpair and the DP solution take seconds to minutes, and the verdict is None with that reason
ATTAINABLE_MAX_N = STABILITY_MAX_N

#: the forms asked first, cross-checked (each certificate checked in numpy; a few ms at n = 4); the LMI form (two
#: Clarabel SDPs, about 20 ms at n = 4, ten times the allocation itself) only where neither decides, up to this n
CHEAP_FORMS = ("riccati", "dp")
LMI_MAX_N = 12


class Attainment(NamedTuple):
    """``cost``: the attainable cost at mu (None: not computed, ``cost_note`` says why); ``stabilisable``:
    True / False / None (``stability_note`` says why None, or what a False rests on)."""

    cost: float | None
    cost_note: str
    stabilisable: bool | None
    stability_note: str


def _dp(system: System, schedule: np.ndarray) -> tuple[np.ndarray, float]:
    """The finite-horizon DP's gains (N, m, n) and its cost (`tcp_attainable_cost`). O(N (n^3 + m^3))."""
    # the paper's weights: Omega_0 = Q at t = 0, Omega_t = state_weights[t - 1] after it (Omega_N the terminal one)
    Omega = np.concatenate([system.initial_weight[None], system.state_weights])
    gains, P, noise = dp_backward(system.A, system.B, schedule, Omega, system.input_weights, system.noise_cov)
    cost = float(system.x0 @ P @ system.x0) + noise
    if not np.isfinite(cost):
        raise NumericalError("finite-horizon DP: the cost-to-go overflows (an unstable plant over a long horizon)")
    return gains, cost


def forward_cost(system: System, schedule: np.ndarray, gains: np.ndarray) -> float:
    """The exact expected cost of u_t = -K_t x_t on the paper's cost by the forward second moments
    ``S_{t+1} = E[(A - B V K_t) S_t (A - B V K_t)'] + Sigma_W`` (the mode engine's `mode_stage_costs` at one mode,
    a weight per step): a sum of non-negative terms, free of the backward recursion's cancellation. O(N (n^3 + n^2 m)).

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> forward_cost(s, s.mu_schedule, np.array([[[0.5]]]))     # E[(1 - v/2)^2 + v/4] = 0.5 (1/4 + 1/4) + 0.5
    0.75
    """
    Omega = np.concatenate([system.initial_weight[None], system.state_weights])     # Omega[t] on x_t, Q at t = 0
    stage, terminal = mode_stage_costs(system.A, system.B, Omega, system.input_weights, system.noise_cov, system.x0,
                                       np.asarray(gains, dtype=float), np.asarray(schedule, dtype=float),
                                       per_step=True)
    cost = float(np.sum(stage)) + terminal
    if not np.isfinite(cost):
        raise NumericalError("finite-horizon DP: the forward second moments overflow")
    return cost


class _LineSearch:
    """``line(mu, i, checked)``: the cost as a function of mu_i alone, the others held at ``mu`` (what the
    monotone searches of `.udp` walk), for an evaluator with ``cost(mu, checked)``."""

    def cost(self, mu: np.ndarray, checked: bool = True) -> float:
        raise NotImplementedError

    def line(self, mu: np.ndarray, i: int, checked: bool = True):
        base = np.array(mu, dtype=float)

        def at(value: float) -> float:
            point = base.copy()
            point[i] = value
            return self.cost(point, checked)

        return at


class AttainableEvaluator(_LineSearch):
    """The TCP-like attainable cost as the monotone searches of `.udp` ask it: ``cost(mu, checked)`` (checked:
    the DP's cost against `forward_cost` of its own gains, within SELF_CHECK_RTOL, the forward one returned;
    else NumericalError) and ``line(mu, i, checked)``. Non-increasing in each mu_i (docs/mathematics.md, "Design on the
    attainable cost"). Bernoulli channels, full state. Each call O(N (n^3 + m^3))."""

    def __init__(self, system: System) -> None:
        self.system = system

    def cost(self, mu: np.ndarray, checked: bool = True) -> float:
        schedule = np.broadcast_to(np.asarray(mu, dtype=float), (self.system.horizon, self.system.m))
        gains, value = _dp(self.system, schedule)
        if not checked:
            return value
        forward = forward_cost(self.system, schedule, gains)
        if abs(value - forward) > SELF_CHECK_RTOL * forward:
            raise NumericalError(f"finite-horizon DP: its cost {value:.12g} disagrees with the forward cost of its own "
                                 f"law {forward:.12g} beyond SELF_CHECK_RTOL (the weights' scales lose digits)")
        return forward


class ChainAttainableEvaluator(_LineSearch):
    """The TCP-like attainable cost behind chains as the monotone searches of `.udp` ask it: ``cost(mu, checked)``,
    the chain DP's cost with each channel's chain at mean rate mu_i along its family (`.chains.ChainFamily`:
    burstiness held on Gilbert channels, deliveries scaled on the others; rates above a family's top evaluated at
    the top), self-checked against the forward cost of its own law (closedloop.chain_dp.chain_attainable; ``checked``
    accepted, nothing skipped), and ``line``. Non-increasing in each mu_i along both families (docs/mathematics.md,
    "Design on the attainable cost behind a chain"). The exact DP must fit the ``chain_dp_nodes`` budget: checked
    once at construction (`chain_dp` at an interior rate, where the fewest outcomes identify a state). Per point
    O(`chain_attainable`).

    Raises
    ------
    BudgetError
        At construction: the DP behind the chain does not fit the ``chain_dp_nodes`` budget (a hidden state over
        a long horizon).
    ResourceError
        A point of the search where only bounds are computed (the structure of its chain differs from the one
        checked).

    Examples
    --------
    One step of x' = x + v u behind a Gilbert channel: the law knows only the stationary mean, 1 - mu / 2.

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.4]))
    >>> round(ChainAttainableEvaluator(s).cost(np.array([0.5])), 12)
    0.75
    """

    def __init__(self, system: System) -> None:
        self.system = system
        self.family = chain_family(system)
        chain_dp(system.with_channel(self.family.channel_at(0.5 * self.family.top)))       # the budget, or refused

    def cost(self, mu: np.ndarray, checked: bool = True) -> float:
        found = chain_attainable(self.system.with_channel(self.family.channel_at(np.asarray(mu, dtype=float))))
        if found.cost is None:
            raise ResourceError(f"design on the attainable cost behind the chain at mu = "
                                f"{np.round(mu, 6).tolist()}: {found.note}", float("nan"), limit("chain_dp_nodes"))
        return float(found.cost)


def tcp_attainable_cost(system: System, mu: np.ndarray | None = None) -> float:
    """The least expected cost of any TCP-like (acknowledged) causal law over the horizon, on the paper's cost.

    .. math:: P_N = \\Omega_N,\\quad P_t = \\Omega_t + A'P_{t+1}A - A'P_{t+1}BM K_t,\\quad
       J = x_0'P_0 x_0 + \\sum_{t=0}^{N-1} \\mathrm{tr}(P_{t+1}\\Sigma_W)

    with ``Omega_0 = Q`` (the initial weight), ``K_t`` the modified Riccati gain at ``mu_t`` and ``Psi_t``
    (`modified_riccati_step`, by `dp_backward`). Time-varying weights and channels as the system
    gives them. O(N (n^3 + m^3)).

    Raises
    ------
    NumericalError
        The cost-to-go overflows.

    Examples
    --------
    One step of x' = x + v u: E[(x + v u)^2 + v u^2] = 1 + mu (2 u + 2 u^2), least at u = -1/2: 1 - mu/2.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> tcp_attainable_cost(s)
    0.75
    """
    N = system.horizon
    schedule = system.mu_schedule if mu is None else np.broadcast_to(np.asarray(mu, dtype=float), (N, system.m))
    return _dp(system, schedule)[1]


def stabilisable(system: System, mu: np.ndarray, acknowledged: bool = True) -> tuple[bool | None, str]:
    """Is there a linear law u = -K x that holds the loop mean-square stable at ``mu`` (Bernoulli losses, full
    state)? ``(verdict, note)``: True or False each on a certificate checked in numpy (the "riccati" and "dp"
    forms of [`membership`][packetloss_cvx.closedloop.region.membership], cross-checked; "lmi" where neither decides,
    up to
    `LMI_MAX_N`),
    None with the reason where none decides (within about 1e-9 of the boundary) or where it is not computed; behind a
    Markov chain `chain_stabilisable`. With lossy sensor links only False is a verdict (a law on an estimate does
    no better than one on the state). O(iterations (n^3 + m^3)), O(n^6) for the certificates.

    Examples
    --------
    x' = 2 x + v u: some law holds the loop iff 4 (1 - mu) < 1, i.e. mu > 3/4.

    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> stabilisable(s, np.array([0.7]))[0], stabilisable(s, np.array([0.8]))[0]
    (False, True)
    """
    if system.channel is not None:
        return chain_stabilisable(system, mu, acknowledged)
    if system.n > ATTAINABLE_MAX_N:
        return None, f"not computed for n = {system.n} > {ATTAINABLE_MAX_N} (it can take minutes)"
    try:
        found = membership(system, mu, forms=CHEAP_FORMS)
        if found.verdict == "undecided" and system.n <= LMI_MAX_N:
            found = membership(system, mu, forms=("lmi",))
    except NumericalError as err:      # a numerical failure is not a verdict
        return None, f"undecided: {err}"
    if found.verdict == "undecided":
        return None, f"undecided: {found.reason or 'no form could check a certificate'}"
    if found.verdict == "unstable":
        return False, ("no linear law holds the loop mean-square stable (certificate T(P) >= 0, every law's "
                       f"radius >= {1.0 + found.certificate_margin:.6g})")
    if system.sensor is not None:
        return None, ("the full-state loop is stabilisable; the lossy sensor links are not part of this verdict "
                      "(packetloss-cvx region FILE --sensor-grid K)")
    return True, f"a linear law has mean-square radius {found.radius:.6g} < 1 (certified)"


def revealing(channel) -> bool:
    """Whether the acknowledgements reveal every channel's state: two states, one delivering always and the other
    never (a Gilbert channel), so an acknowledgement names the state of its step. O(m).

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> revealing(GilbertElliott(p=[0.1], r=[0.4])), revealing(GilbertElliott(p=[0.1], r=[0.4], h_bad=[0.5]))
    (True, False)
    """
    return all(d.size == 2 and sorted(d.tolist()) == [0.0, 1.0] for d in channel.delivery)


def chain_stabilisable(system: System, mu: np.ndarray, acknowledged: bool = True) -> tuple[bool | None, str]:
    """Does some law hold the loop mean-square stable behind the system's chain moved to the mean rates ``mu``
    along its family (`.chains.chain_family`)? ``(verdict, note)`` as `stabilisable`, the class of laws decided
    over in the module docstring: the chain region engine's least radius over mode-dependent laws on the last
    state (closedloop.markov_region.chain_least_radius, deliveries following the state the chain moves to, as a
    TCP-like acknowledgement of a Gilbert channel reveals the last one); "stable" counts where its gains' coupled
    radius is proved below ``1 - MEAN_SQUARE_MARGIN`` in exact arithmetic
    (closedloop.certificates.chain_law_proved_stable) and the acknowledgements reveal the state (else only a
    state-free gain so proved counts; ``acknowledged`` False, a UDP-like loop, which gets no acknowledgements: only a
    state-free gain); "unstable" where its certificate proves every law's radius >= 1 exactly
    (closedloop.certificates.chain_outside_proved). Otherwise None with the reason. Two-state chains (the engine's
    scope), n <= `ATTAINABLE_MAX_N`. Time O((2^m n^2)^3) for the radius, the certificates' exact checks
    O(4^m (n + m)^3) integer operations.

    Examples
    --------
    x' = 2 x + v u behind a Gilbert channel with burstiness 0.2: deadbeat when the last packet arrived, x' = 2 x
    after a loss: some law holds the loop iff 4 (1 - r) < 1, r = 0.8 mu at mean rate mu: iff mu > 15/16.

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.04], r=[0.76]))
    >>> chain_stabilisable(s, np.array([0.93]))[0], chain_stabilisable(s, np.array([0.95]))[0]
    (False, True)
    """
    if system.n > ATTAINABLE_MAX_N:
        return None, f"not computed for n = {system.n} > {ATTAINABLE_MAX_N} (it can take minutes)"
    try:
        channel = chain_family(system).channel_at(np.asarray(mu, dtype=float))
    except InputError as err:
        return None, f"not computed behind the chain: {err}"
    if not channel.two_state:
        return None, (f"not computed behind a chain with {list(channel.sizes)} states: the chain region engine "
                      "decides two-state chains")
    A, B = np.asarray(system.A, dtype=float), np.asarray(system.B, dtype=float)
    try:
        found, lam, _ = chain_least_radius(A, B, channel, "next")
        if found.verdict == "unstable":
            if not chain_outside_proved(A, B, channel, found.certificate, 1.0, "next"):
                return None, ("undecided: the chain certificate that no law holds the loop does not survive "
                              "exact arithmetic (near the boundary)")
            return False, ("no law holds the loop mean-square stable behind the chain at mu* (certificate checked "
                           f"exactly: every law's radius >= 1; least mode-dependent radius {lam:.6g})")
        if found.verdict == "undecided":
            return None, f"undecided behind the chain: {found.reason}"
        if acknowledged and revealing(channel):
            if not chain_law_proved_stable(A, B, channel, found.gain, found.radius, "next"):
                return None, (f"undecided: the mode gains' coupled radius {found.radius:.6g} < 1 does not survive "
                              "exact arithmetic")
            verdict, why = True, (f"a law on the chain state the acknowledgements reveal, u = -K_a x, has "
                                  f"mean-square radius {found.radius:.6g} < 1 behind the chain (certified)")
        else:
            hidden = ("the acknowledgements do not reveal the state here" if acknowledged else
                      "a UDP-like loop gets no acknowledgements")
            verdict, why = _state_free(A, B, channel, found.gain, found.radius, hidden)
    except (InputError, NumericalError) as err:        # a budget or a failed routine: not a verdict
        return None, f"undecided behind the chain: {err}"
    if verdict and system.sensor is not None:
        return None, ("the full-state loop behind the chain is stabilisable; the lossy sensor links are not part of "
                      "this verdict")
    return verdict, why


def _state_free(A: np.ndarray, B: np.ndarray, channel, gains: np.ndarray, radius: float, hidden: str
                ) -> tuple[bool | None, str]:
    """`chain_stabilisable` where the acknowledgements hide the chain state: True where one of the mode gains,
    used in every state, has a coupled radius proved below 1 - MEAN_SQUARE_MARGIN exactly; else None."""
    tried = []
    for K in np.unique(np.asarray(gains, dtype=float), axis=0):
        value = mean_square_radius(A, B, channel, K, "next")
        tried.append(value)
        if is_mean_square_stable(value) and chain_law_proved_stable(A, B, channel, np.broadcast_to(K, gains.shape),
                                                                     value, "next"):
            return True, (f"a law that ignores the chain state, u = -K x, has mean-square radius {value:.6g} < 1 "
                          "behind the chain (certified)")
    return None, (f"a law on the chain state would hold the loop (least radius {radius:.6g}), but {hidden}, and no "
                  f"state-free gain tried is certified (radii {', '.join(f'{v:.6g}' for v in tried)}); laws on the "
                  "acknowledgement history are not decided")


def chain_cost(system: System, mu: np.ndarray) -> tuple[float | None, str]:
    """The TCP-like attainable cost behind the system's chain moved to the mean rates ``mu`` along its family
    (`.chains.chain_family`) and its note: ``(cost, note)``; the cost None where only bounds are computed (both in
    the note), the family refuses the chain, or a numerical failure (the reason in the note). O(`chain_attainable`).

    >>> from packetloss_cvx import load_example
    >>> cost, note = chain_cost(load_example("pendulum_bursty"), np.array([0.9]))
    >>> round(cost, 1), note.split(":")[0]
    (10668.7, 'exact')
    """
    if system.sensor is not None:
        return None, ("not computed with lossy sensor links (the DP with acknowledgements assumes the state is "
                      "measured)")
    try:
        moved = system.with_channel(chain_family(system).channel_at(np.asarray(mu, dtype=float)))
        found = chain_attainable(moved)
    except (InputError, NumericalError) as err:         # a budget refusal is an InputError
        return None, f"not computed behind the chain: {err}"
    return found.cost, found.note


def attainment(system: System, protocol: str, mu: np.ndarray, cost: float, chain: bool = False) -> Attainment:
    """The `Attainment` at an allocation's ``mu`` (``system`` at any mu: it is replaced). ``cost`` is the
    allocation's own cost: UDP-like it is the attainable cost already (J*_udp, or behind a chain the exact cost
    under it, ``chain`` True). O(N (n^3 + m^3)) plus `stabilisable`."""
    mu = np.asarray(mu, dtype=float)
    verdict, why = stabilisable(system, mu, acknowledged=protocol != "udp")
    if protocol == "udp":
        return Attainment(float(cost), "exact expected cost of the optimal plan" + (" under the chain" if chain
                                                                                       else " (J*_udp)"),
                          verdict, why)
    if system.channel is not None:
        cost, note = chain_cost(system, mu)
        return Attainment(cost, note, verdict, why)
    if system.sensor is not None:
        return Attainment(None, "not computed with lossy sensor links (the DP with acknowledgements assumes the "
                                "state is measured)", verdict, why)
    try:
        value = tcp_attainable_cost(system.with_mu(mu), mu)
    except NumericalError as err:
        return Attainment(None, str(err), verdict, why)
    return Attainment(value, "finite-horizon DP with acknowledgements", verdict, why)
