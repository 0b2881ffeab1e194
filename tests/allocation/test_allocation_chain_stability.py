"""The mean-square verdict of an allocation behind a Markov chain (allocation.attainable.chain_stabilisable): the
chain moved to mu* along the allocation's family, decided over mode-dependent laws where the acknowledgements reveal
the state and over state-free laws (False: over every law) where they hide it.

Independent references, written here: the scalar rule by hand (deadbeat when delivered is optimal for every law
on a scalar plant, so the loop is stabilisable iff the radius of x' = a x on the losses is below 1: ``a^2 (1 - r)``
behind a Gilbert channel, ``a^2 rho(T' diag(1 - d))`` behind any two-state chain); and the least mode-dependent
radius by the power iteration of the homogeneous coupled Riccati map with every delivery vector enumerated and each
step's least-squares gain solved by numpy and the map evaluated at it (not the package's moment formulas).
"""

import itertools

import numpy as np
import pytest

from packetloss_cvx import System, allocate
from packetloss_cvx.allocation.attainable import attainment, chain_stabilisable, revealing
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel


def least_radius_enumerated(A, B, Ts, ds, iterations=600):
    """The least coupled mean-square radius over laws u = -K_a x on the last joint state a, deliveries following
    the state b the chains move to: power iteration of ``R(P)_a = min_K sum_b T_ab sum_v P(v | b) (A - B V K)' P_b
    (A - B V K)`` with the joint states and delivery vectors enumerated."""
    states = list(itertools.product(*[range(len(d)) for d in ds]))
    T = np.ones((1, 1))
    for Ti in Ts:
        T = np.kron(T, np.asarray(Ti, dtype=float))
    n, m = B.shape
    patterns = [np.array(v, dtype=float) for v in itertools.product((0.0, 1.0), repeat=m)]

    def prob(v, b):
        h = np.array([ds[i][states[b][i]] for i in range(m)])
        return float(np.prod(np.where(v == 1.0, h, 1.0 - h)))

    P = np.array([np.eye(n) for _ in states])
    ratio = np.nan
    for _ in range(iterations):
        R = np.zeros_like(P)
        for a in range(len(states)):
            terms = [(T[a, b] * prob(v, b), B * v, P[b]) for b in range(len(states)) for v in patterns]
            G = sum(w * BV.T @ Pb @ BV for w, BV, Pb in terms)
            F = sum(w * BV.T @ Pb @ A for w, BV, Pb in terms)
            K = np.linalg.lstsq(G, F, rcond=1e-12)[0]            # the least-squares gain of this step
            R[a] = sum(w * (A - BV @ K).T @ Pb @ (A - BV @ K) for w, BV, Pb in terms)   # PSD by construction
        total = sum(np.trace(X) for X in R)
        ratio = total / sum(np.trace(X) for X in P)
        P = R / total
    return ratio


def gilbert(lam, mu):
    """A Gilbert channel (h_good = 1, h_bad = 0) with burstiness lam = 1 - p - r and mean rate r / (p + r) = mu."""
    lam, mu = np.asarray(lam, dtype=float), np.asarray(mu, dtype=float)
    return GilbertElliott(p=(1 - mu) * (1 - lam), r=mu * (1 - lam))


def test_scalar_verdict_behind_a_gilbert_channel_follows_the_hand_rule_at_each_mean_rate():
    """x' = 2 x + v u behind a Gilbert channel whose burstiness 0.2 is held: stabilisable iff 4 (1 - 0.8 mu) < 1,
    i.e. mu > 15/16; the file's own chain (mean rate 0.95) is moved to each mu."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=gilbert([0.2], [0.95]))
    assert revealing(s.channel)
    for mu in (0.3, 0.6, 0.9, 0.93, 0.945, 0.96, 0.99):
        verdict, note = chain_stabilisable(s, np.array([mu]))
        assert verdict is bool(4 * (1 - 0.8 * mu) < 1), (mu, note)
        if verdict:
            assert "reveal" in note
            assert "certified" in note
        else:
            assert "every law's radius >= 1" in note


def test_scalar_verdict_behind_a_hidden_chain_is_the_radius_of_the_deadbeat_law():
    """A two-state chain with deliveries (0.9, 0.3) (the state hidden), its deliveries scaled along the family: the
    verdict is a^2 rho(T' diag(1 - d(mu))) < 1, d(mu) = d mu / mubar, decided by a law that ignores the state."""
    T = np.array([[0.85, 0.15], [0.25, 0.75]])
    d = np.array([0.9, 0.3])
    pi = np.array([0.25, 0.15]) / 0.4                              # stationary: pi T = pi
    mubar = float(pi @ d)
    checked = 0
    for a in (1.2, 1.5, 2.0, 3.0):
        s = System(A=[[a]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                   channel=MarkovChannel(transition=[T], delivery=[d]))
        assert not revealing(s.channel)
        for mu in np.linspace(0.2, mubar / d.max(), 6):
            rho = a * a * max(abs(np.linalg.eigvals(T.T * (1 - d * mu / mubar)[:, None])))
            if abs(rho - 1) < 1e-3:
                continue
            verdict, note = chain_stabilisable(s, np.array([mu]))
            assert verdict is bool(rho < 1), (a, mu, rho, note)
            if verdict:
                assert "ignores the chain state" in note
            checked += 1
    assert checked >= 20


@pytest.mark.parametrize("seed", range(6))
def test_verdicts_behind_gilbert_channels_match_the_enumerated_least_radius(seed):
    """Random 2-state plants behind one or two Gilbert channels (the acknowledgements reveal the state), at the
    file's rates and at other mean rates along the family: True iff the enumerated least radius is below 1."""
    rng = np.random.default_rng(seed)
    m = 1 + seed % 2
    A = rng.normal(size=(2, 2)) * 1.1
    B = rng.normal(size=(2, m))
    lam = rng.uniform(0.0, 0.8, size=m)
    s = System(A=A, B=B, horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0] * m, x0=[1.0, 1.0],
               channel=gilbert(lam, rng.uniform(0.3, 0.95, size=m)))
    decided = 0
    for mu in (s.channel.mean_rate, rng.uniform(0.2, 1.0, size=m), rng.uniform(0.2, 1.0, size=m)):
        ch = gilbert(lam, mu)
        reference = least_radius_enumerated(A, B, [ch.transition[i] for i in range(m)],
                                            [ch.delivery[i] for i in range(m)])
        verdict, note = chain_stabilisable(s, mu)
        if abs(reference - 1) < 0.02:
            continue
        assert verdict is bool(reference < 1), (mu, reference, note)
        decided += 1
    assert decided >= 1


def test_behind_a_hidden_chain_a_loop_only_a_state_law_holds_is_undecided():
    """Two channels with hidden states (deliveries (0.8, 0.3) and (0.95, 0.3)): a law on the joint state would hold
    the loop (enumerated least radius < 1), but the acknowledgements do not reveal it and no state-free gain tried
    is certified: no verdict, the reason given. (A verdict from the mode-dependent law would claim what no TCP-like
    controller can implement.)"""
    A = np.array([[1.14, 2.08], [-0.47, 1.25]])
    B = np.array([[-0.79, -0.89], [-0.62, -0.98]])
    ch = GilbertElliott(p=[0.36, 0.06], r=[0.38, 0.46], h_good=[0.8, 0.95], h_bad=[0.3, 0.3])
    s = System(A=A, B=B, horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0], x0=[1.0, 1.0], channel=ch)
    reference = least_radius_enumerated(A, B, list(ch.transition), list(ch.delivery))
    verdict, note = chain_stabilisable(s, ch.mean_rate)
    assert reference < 1
    assert verdict is None
    assert "do not reveal" in note
    assert "not decided" in note


def test_tcp_allocation_behind_a_chain_carries_the_verdict_at_mu_star():
    """allocate behind a Gilbert channel with burstiness 0.1: the verdict at mu* by the hand rule of the scalar plant
    (x' = 1.5 x: stabilisable iff 2.25 (1 - r) < 1, r = 0.9 mu, i.e. mu > (5/9) / 0.9), both verdicts met."""
    s = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=gilbert([0.1], [0.9]))
    seen = set()
    for alpha in (6.0, 2.9, 1.9):
        a = allocate(s, "tcp", alpha, [1.0])
        mu = float(a.mu[0])
        expected = bool(2.25 * (1 - 0.9 * mu) < 1)
        assert a.stabilisable is expected, (alpha, mu, a.stability_note)
        seen.add(expected)
    assert seen == {True, False}


def test_a_udp_like_loop_is_decided_over_laws_that_ignore_the_chain_state():
    """Two revealing Gilbert channels where a law on the last state holds the loop (enumerated least radius just
    below 1): the TCP-like verdict is True (the acknowledgements reveal the state), the UDP-like one, whose loop gets
    no acknowledgements, None with the reason (no state-free gain tried is certified)."""
    A = np.array([[1.04, -0.16], [-0.44, -1.55]])
    B = np.array([[0.88, 0.4], [0.99, -0.86]])
    ch = GilbertElliott(p=[0.205, 0.14], r=[0.435, 0.31])
    s = System(A=A, B=B, horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0], x0=[1.0, 1.0], channel=ch)
    reference = least_radius_enumerated(A, B, list(ch.transition), list(ch.delivery))
    assert reference < 1 - 1e-4
    assert chain_stabilisable(s, ch.mean_rate)[0] is True
    verdict, note = chain_stabilisable(s, ch.mean_rate, acknowledged=False)
    assert verdict is None
    assert "UDP-like loop gets no acknowledgements" in note
    assert attainment(s, "udp", ch.mean_rate, 1.0).stabilisable is None
    assert attainment(s, "tcp", ch.mean_rate, 1.0).stabilisable is True
