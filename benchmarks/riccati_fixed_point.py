"""How close the coupled Riccati answers are to the fixed point, this checkout against a baseline: the equation's
residual at each answer computed exactly (rational arithmetic on the answer's doubles, the expectation over the
deliveries by enumerating the 2^m patterns, none of the package's algebra), and the answers' distance.

    python benchmarks/riccati_fixed_point.py --baseline /path/to/baseline/checkout

Prints per case ||R(P) - P||_F / ||P||_F exactly for the baseline's P and this checkout's, the relative change of P
between the two, and the gains' largest relative distance from the exact minimiser at each P (actuators that can
deliver; the rows of those that cannot are a convention, closedloop.riccati.mode_riccati).
"""

from __future__ import annotations

import argparse
import itertools
from fractions import Fraction
from pathlib import Path

import numpy as np
from mode_engine import ROOT, _load


def _solve(H: list[list[Fraction]], L: list[list[Fraction]]) -> list[list[Fraction]]:
    """H X = L exactly (Gauss–Jordan on Fractions)."""
    k = len(H)
    M = [H[i][:] + L[i][:] for i in range(k)]
    for c in range(k):
        p = next(r for r in range(c, k) if M[r][c] != 0)
        M[c], M[p] = M[p], M[c]
        M[c] = [x / M[c][c] for x in M[c]]
        for r in range(k):
            if r != c and M[r][c] != 0:
                f = M[r][c]
                M[r] = [x - f * y for x, y in zip(M[r], M[c], strict=True)]
    return [row[k:] for row in M]


def exact_bellman(A, B, Omega, psi, T, h, P) -> tuple[list, list]:
    """R(P)_a and the minimising gains on the delivering actuators, exactly, for a P (M, n, n) of doubles."""
    M, n, m = P.shape[0], A.shape[0], B.shape[1]
    F = np.vectorize(Fraction, otypes=[object])
    A_, B_, W_, P_, T_, h_ = F(A), F(B), F(Omega), F(P), F(T), F(h)
    psi_ = F(psi)
    out, gains = [], []
    for a in range(M):
        E = sum(T_[a, b] * P_[b] for b in range(M))
        E = (E + E.T) / 2
        BEB, BEA = B_.T.dot(E).dot(B_), B_.T.dot(E).dot(A_)
        Hs = np.full((m, m), Fraction(0), dtype=object)
        Ls = np.full((m, n), Fraction(0), dtype=object)
        for v in itertools.product([0, 1], repeat=m):
            prob = Fraction(1)
            for i in range(m):
                prob *= h_[a, i] if v[i] else 1 - h_[a, i]
            if prob == 0:
                continue
            for i in range(m):
                if not v[i]:
                    continue
                Ls[i] += prob * BEA[i]
                for j in range(m):
                    if v[j]:
                        Hs[i, j] += prob * (BEB[i, j] + (psi_[i] if i == j else 0))
        on = [i for i in range(m) if h[a, i] > 0]
        K = _solve([[Hs[i, j] for j in on] for i in on], [list(Ls[i]) for i in on]) if on else []
        R = W_ + A_.T.dot(E).dot(A_)
        for r, i in enumerate(on):
            for x in range(n):
                for y in range(n):
                    R[x, y] -= Ls[i, x] * K[r][y]
        out.append(R)
        gains.append((on, K))
    return out, gains


def measure(res, A, B, Omega, psi, T, h) -> tuple[float, float]:
    """(exact relative residual, gains' largest relative distance from the exact minimiser)."""
    P = res.cost_matrices
    R, gains = exact_bellman(A, B, Omega, psi, T, h, P)
    diff = sum(float(x) ** 2 for a in range(len(R)) for x in (R[a] - np.vectorize(Fraction, otypes=[object])(P[a]))
               .ravel())
    size = float(np.linalg.norm(P))
    worst = 0.0
    for a, (on, K) in enumerate(gains):
        for r, i in enumerate(on):
            exact = np.array([float(x) for x in K[r]])
            worst = max(worst, float(np.max(np.abs(res.gains[a, i] - exact)) / np.max(np.abs(exact))))
    return diff ** 0.5 / size, worst


def cases(mod: dict) -> list[tuple[str, object]]:
    files, GE = mod["io"], mod["channel"].GilbertElliott
    System = __import__("sys").modules["packetloss_cvx"].System
    two, pend = files.load_example("two_actuator"), files.load_example("pendulum")
    scalar = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                    channel=GE(p=[0.0], r=[0.5]))
    rng = np.random.default_rng(0)                              # test_markov_mjls's fractional case, seed 0
    A = rng.normal(size=(2, 2))
    A *= 1.05 / max(abs(np.linalg.eigvals(A)))
    hg, hb = rng.uniform(0.55, 0.95, 2), rng.uniform(0.05, 0.5, 2)
    hb[1] = 0.0
    frac = System(A=A, B=rng.normal(size=(2, 2)), horizon=2, state_weight=rng.uniform(0.5, 2, 2),
                  input_weight=rng.uniform(0.5, 2, 2), x0=[1.0, 0.0],
                  channel=GE(p=rng.uniform(0.05, 0.4, 2), r=rng.uniform(0.2, 0.8, 2), h_good=hg, h_bad=hb))
    return [
        ("pendulum_bursty (example)", files.load_example("pendulum_bursty")),
        ("two_actuator GE fractional", two.with_channel(GE(p=[0.1, 0.2], r=[0.4, 0.5], h_good=[0.95, 0.9],
                                                           h_bad=[0.1, 0.2]))),
        ("two_actuator Gilbert", two.with_channel(GE(p=[0.1, 0.2], r=[0.4, 0.5]))),
        ("pendulum Gilbert p=0.1 r=0.6", pend.with_channel(GE(p=[0.1], r=[0.6]))),
        ("scalar p=0 r=0.5 (hand case)", scalar),
        ("fractional seed 0 (test case)", frac),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, required=True)
    args = parser.parse_args()
    results = {}
    for tree, root in (("base", args.baseline.resolve()), ("this", ROOT)):
        mod = _load(root)
        for label, s in cases(mod):
            _, T, h = mod["mjls"].mode_chain(s.channel)
            res = mod["mjls"].coupled_riccati(s)
            results.setdefault(label, {})[tree] = (res, *measure(res, s.A, s.B, s.state_weights[0],
                                                                 s.input_weights[0], T, h), res.iterations)
    print(f"{'case':32s} {'residual base':>14s} {'residual this':>14s} {'P moved':>9s} {'gain err base':>14s} "
          f"{'gain err this':>14s} {'steps base/this':>16s}")
    for label, r in results.items():
        (b, rb, gb, ib), (t, rt, gt, it) = r["base"], r["this"]
        moved = float(np.max(np.abs(t.cost_matrices - b.cost_matrices)) / np.max(np.abs(b.cost_matrices)))
        print(f"{label:32s} {rb:14.2e} {rt:14.2e} {moved:9.2e} {gb:14.2e} {gt:14.2e} {ib:>8d}/{it:<7d}")


if __name__ == "__main__":
    main()
