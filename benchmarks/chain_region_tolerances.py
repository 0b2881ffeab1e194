"""The measurements behind closedloop.chain_radius's tolerances (tolerances.COUPLED_ZERO_RTOL,
COUPLED_POLICY_REGULARISATION, COUPLED_BRACKET_RTOL), on seeded plants and chains; run under each OpenBLAS kernel:

    OPENBLAS_CORETYPE=Prescott python benchmarks/chain_region_tolerances.py [--eps 1e-8 1e-10 1e-12]

- zero test: ``||F|| / (||A|| sqrt(tr P))`` at its least over the first M n + 1 steps of R from I, on 400 random
  controllable plants behind chains that deliver every packet after the first step (least radius 0) and 12
  two_actuator points with a channel at mean rate 1 (the same), against 400 random chains (least radius > 0);
- regularisation: per eps, how many of 313 chains (160 random, pendulum_bursty at 9 mean rates, the 24 "current"
  chains of tests/closedloop/test_markov_region.py, 120 chains at the ends of their mean rates) have lambda pinned to 1e-9 by
  its own certificate and its gains' radius, how many memberships are undecided, and the CPU seconds;
- bracket: the gap (radius - bound) / radius at the first checkpoint over the same chains, quantiles.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import packetloss_cvx.closedloop.chain_radius as cr
import packetloss_cvx.closedloop.markov_region as mr
from packetloss_cvx import load_system
from packetloss_cvx.closedloop.mjls import mean_square_radius, mode_chain
from packetloss_cvx.model.channel import GilbertElliott

EXAMPLES = Path(__file__).resolve().parent.parent / "packetloss_cvx" / "model" / "examples"


def zero_ratio(A, B, ch, delivery):
    _, T, h = mode_chain(ch)
    M, n = len(h), A.shape[0]
    P = np.repeat(np.eye(n)[None] / (n * M), M, axis=0)
    least = np.inf
    for _ in range(M * n + 1):
        L, w = cr.psd_part_factor(P)
        F = cr._riccati_factors(L, A, B, T, h, delivery)
        squares = float(sum(np.sum(f * f) for f in F))
        least = min(least, np.sqrt(squares / (np.linalg.norm(A, 2) ** 2 * w.sum())))
        R = np.stack([f.T @ f for f in F])
        total = np.trace(R, axis1=1, axis2=2).sum()
        if not total > 0:
            return 0.0
        P = R / total
    return least


def zero_test() -> None:
    rng = np.random.default_rng(0)
    dead, live = [], []
    for k in range(400):
        n, m = rng.integers(1, 5), rng.integers(1, 3)
        A, B = rng.normal(size=(n, n)) * rng.uniform(0.5, 3.0), rng.normal(size=(n, m))
        dead.append(zero_ratio(A, B, GilbertElliott(p=[0.0] * m, r=[1.0] * m), ("next", "current")[k % 2]))
    s = load_system(EXAMPLES / "two_actuator.toml")
    base = GilbertElliott(p=[0.5, 0.5], r=[0.5, 0.5])
    for x in np.linspace(0, 1, 6):
        for ch in (mr.chain_at_rate(base, [1.0, x]), mr.chain_at_rate(base, [x, 1.0])):
            dead.append(zero_ratio(s.A, s.B, ch, "next"))
    for k in range(400):
        n, m = rng.integers(1, 5), rng.integers(1, 3)
        A, B = rng.normal(size=(n, n)) * rng.uniform(0.5, 3.0), rng.normal(size=(n, m))
        ch = GilbertElliott(p=rng.uniform(0.02, 0.9, m), r=rng.uniform(0.02, 0.98, m))
        live.append(zero_ratio(A, B, ch, ("next", "current")[k % 2]))
    print(f"zero test: least radius 0 ({len(dead)}): largest ratio {max(dead):.3g}; "
          f"least radius > 0 ({len(live)}): smallest {min(live):.3g}")


def chains() -> list:
    cases = []
    rng = np.random.default_rng(5)
    for k in range(160):
        n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
        A = rng.normal(size=(n, n))
        A *= rng.uniform(0.8, 1.6) / max(abs(np.linalg.eigvals(A)))
        B = rng.normal(size=(n, m))
        ch = GilbertElliott(p=rng.uniform(0.02, 0.8, m), r=rng.uniform(0.02, 0.9, m))
        cases.append((A, B, ch, ("next", "current")[k % 2]))
    s = load_system(EXAMPLES / "pendulum_bursty.toml")
    cases += [(s.A, s.B, mr.chain_at_rate(s.channel, [rate]), "next") for rate in np.linspace(0, 1, 9)]
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        A = np.array([[1.0 + rng.uniform(0, 0.4), rng.uniform(-0.5, 0.5)], [0.0, rng.uniform(0.5, 1.3)]])
        B = rng.normal(size=(2, 2))
        cases += [(A, B, GilbertElliott(p=rng.uniform(0.05, 0.6, 2), r=rng.uniform(0.05, 0.9, 2)), "current")
                  for _ in range(4)]
    rng = np.random.default_rng(9)
    for k in range(120):
        n, m = int(rng.integers(2, 5)), int(rng.integers(1, 3))
        A = rng.normal(size=(n, n))
        A *= rng.uniform(0.9, 1.4) / max(abs(np.linalg.eigvals(A)))
        B = rng.normal(size=(n, m))
        corr = rng.uniform(0.0, 0.9, m)
        rate = rng.choice([0.0, 1.0, 0.5], size=m) if m > 1 else rng.choice([0.0, 1.0], size=1)
        cases.append((A, B, mr.chain_at_rate(GilbertElliott(p=(1 - corr) / 2, r=(1 - corr) / 2), rate),
                      ("next", "current")[k % 2]))
    return cases


def regularisation(eps_values) -> None:
    cases = chains()
    gaps = []
    refine, bound = cr._refine, cr._bound
    log: list = []

    def logged_refine(*args):
        out = refine(*args)
        log.append(out[2])
        return out

    def logged_bound(*args):
        out = bound(*args)
        if len(log) == 1:
            log.append(out)
        return out

    for eps in eps_values:
        cr.COUPLED_POLICY_REGULARISATION = eps
        pinned = undecided = 0
        start = time.process_time()
        for A, B, ch, d in cases:
            lam, P, K = cr.homogeneous_coupled_riccati(A, B, ch, d)
            undecided += mr.chain_membership(A, B, ch, d).verdict == "undecided"
            if lam == 0.0:
                pinned += 1
                continue
            weighed = np.trace(P, axis1=-2, axis2=-1) > 1e-12
            Q = np.where(weighed[:, None, None], P, 0.0)
            below = 1.0 + cr.chain_certificate_margin(A, B, ch, Q / np.trace(Q, axis1=-2, axis2=-1).sum(), d)
            above = mean_square_radius(A, B, ch, K, d)
            pinned += abs(lam - below) <= 1e-9 * lam and abs(lam - above) <= 1e-9 * lam
        print(f"eps {eps:g}: {pinned} of {len(cases)} pinned to 1e-9, {undecided} undecided, "
              f"{time.process_time() - start:.1f} s CPU")
    cr._refine, cr._bound = logged_refine, logged_bound
    for A, B, ch, d in cases:
        log.clear()
        cr.homogeneous_coupled_riccati(A, B, ch, d)
        if len(log) == 2 and log[0] > 0:
            gaps.append((log[0] - log[1]) / log[0])
    cr._refine, cr._bound = refine, bound
    print("bracket gap at the first checkpoint, quantiles 0.5, 0.9, 0.99, 1:",
          [f"{q:.2g}" for q in np.quantile(gaps, [0.5, 0.9, 0.99, 1.0])])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--eps", type=float, nargs="*", default=[1e-10])
    args = parser.parse_args()
    zero_test()
    regularisation(args.eps)


if __name__ == "__main__":
    main()
