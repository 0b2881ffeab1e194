"""Section 17 of benchmarks/run.py: systems and their structure (docs/performance.md,
"Section 17"). Each fast path against the path it replaced, reproduced here, on the audit's 200 random systems
(seed 1), side by side in one run; CPU seconds (``time.process_time``), medians of 3."""

from __future__ import annotations

import statistics
import time

import numpy as np
from scipy.optimize import minimize_scalar

from packetloss_cvx.lq.difference import (
    cost_difference,
    maximise_cost_difference,
    scalar_channel,
    shared_channel_differences,
)
from packetloss_cvx.lq.prediction import prediction
from packetloss_cvx.lq.recursion import recursion_cost, udp_variance_weights
from packetloss_cvx.model.chain import attach_channel
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.model.random_systems import random_system


def _step_by_step_cost(system, inputs, protocol, weights):
    """recursion_cost before: every term one step at a time."""
    A, B, W, mu, psi = system.A, system.B, system.state_weights, system.mu_schedule, system.input_weights
    d, noise = weights
    x = system.x0.copy()
    total = float(x @ system.initial_weight @ x) + noise
    for t in range(system.horizon):
        u = inputs[t]
        mean_u = mu[t] * u
        total += float(np.sum(mean_u * (psi[t] * u)))
        if protocol == "udp":
            lossy = mu[t] < 1.0
            total += float(np.sum((mean_u * ((1.0 - mu[t]) * d[t] * u))[lossy]))
        x = A @ x + B @ (mu[t] * u)
        total += float(x @ W[t] @ x)
    return total


def _stacked_lu_grid(system, nus, pred):
    """maximise_cost_difference's grid before: two stacked LU solves per nu."""
    k = system.horizon * system.m
    v = np.repeat(np.asarray(nus, dtype=float)[:, None], k, axis=1)
    g = pred.Omega_gp @ system.x0
    base = pred.Omega_g[None] * v[:, None, :] + np.diag(pred.Psi)
    lossy = pred.Omega_d * (1.0 - v)
    udp = base.copy()
    udp[:, np.arange(k), np.arange(k)] += lossy
    a = np.linalg.solve(udp, g[None, :, None])[:, :, 0]
    b = np.linalg.solve(base.transpose(0, 2, 1), (v * g)[:, :, None])[:, :, 0]
    return np.array([float(b[i] @ (lossy[i] * a[i])) for i in range(len(v))])


def _lu_maximiser(system, grid, pred):
    """maximise_cost_difference before: LU grid, then Brent on cost_difference."""
    z = np.linspace(-np.log(1e9), np.log(1e9), grid)
    nus = 1 / (1 + np.exp(-z))
    vals = _stacked_lu_grid(system, nus, pred)
    i = int(np.argmax(vals))
    res = minimize_scalar(lambda s: -cost_difference(system, 1 / (1 + np.exp(-s)), pred),
                          bounds=(z[max(i - 1, 0)], z[min(i + 1, grid - 1)]), method="bounded",
                          options={"xatol": 1e-10})
    return (1 / (1 + np.exp(-res.x)), -res.fun) if -res.fun >= vals[i] else (nus[i], vals[i])


def systems_and_structure(rows: list) -> None:
    print("\n17. Systems and structure (the audit's 200 random systems, seed 1; CPU s, medians of 3)")
    rng = np.random.default_rng(1)
    cases = [random_system(rng) for _ in range(200)]
    chains = [GilbertElliott(p=rng.uniform(0.05, 0.5, s.m), r=rng.uniform(0.05, 0.5, s.m)) for s in cases]
    mus = [rng.uniform(0.05, 1.0, s.m) for s in cases]
    inputs = [rng.normal(size=(s.horizon, s.m)) for s in cases]
    bases = [b for b in (scalar_channel(s, 0.5) for s in cases) if b.horizon * b.m <= 100]
    for s in cases:                        # the per-structure store the "after" columns read, filled once
        prediction(s)
        udp_variance_weights(s)
    z = np.linspace(-np.log(1e9), np.log(1e9), 200)
    nus = 1 / (1 + np.exp(-z))

    def cold(fn):
        """fn on freshly validated copies with the new mu (an empty store each repeat; built outside the timing)."""
        def timed() -> float:
            copies = [system_from_dict({**s.to_dict(), "channel": {"mu": mu.tolist()}})
                      for s, mu in zip(cases, mus, strict=True)]
            start = time.process_time()
            for c in copies:
                fn(c)
            return time.process_time() - start
        return timed

    def warm(fn):
        def timed() -> float:
            start = time.process_time()
            fn()
            return time.process_time() - start
        return timed

    benches = [
        ("attach_channel (TOML round trip -> with_channel)", len(cases),
         warm(lambda: [system_from_dict({**s.to_dict(), "channel": c.to_dict()})
                       for s, c in zip(cases, chains, strict=True)]),
         warm(lambda: [attach_channel(s, c) for s, c in zip(cases, chains, strict=True)])),
        ("prediction of a with_mu copy (built -> kept)", len(cases), cold(prediction),
         warm(lambda: [prediction(s.with_mu(mu)) for s, mu in zip(cases, mus, strict=True)])),
        ("udp_variance_weights of a copy (built -> kept)", len(cases), cold(udp_variance_weights),
         warm(lambda: [udp_variance_weights(s.with_mu(mu)) for s, mu in zip(cases, mus, strict=True)])),
        ("recursion_cost (step by step -> all steps at once)", len(cases),
         warm(lambda: [_step_by_step_cost(s, U, "udp", udp_variance_weights(s))
                       for s, U in zip(cases, inputs, strict=True)]),
         warm(lambda: [recursion_cost(s, U, "udp", udp_variance_weights(s))
                       for s, U in zip(cases, inputs, strict=True)])),
        ("J_Delta on a 200-point grid (stacked LU -> eigh)", len(bases),
         warm(lambda: [_stacked_lu_grid(b, nus, prediction(b)) for b in bases]),
         warm(lambda: [shared_channel_differences(b, nus, prediction(b)) for b in bases])),
        ("maximise_cost_difference, grid 200 (LU -> curve)", len(bases),
         warm(lambda: [_lu_maximiser(b, 200, prediction(b)) for b in bases]),
         warm(lambda: [maximise_cost_difference(b, 200, prediction(b)) for b in bases])),
    ]
    print(f"{'':>52} {'before ms':>10} {'after ms':>9} {'ratio':>7}   (per system)")
    for label, count, before_fn, after_fn in benches:
        before = statistics.median(before_fn() for _ in range(3))
        after = statistics.median(after_fn() for _ in range(3))
        print(f"{label:>52} {before / count * 1e3:>10.3f} {after / count * 1e3:>9.3f} {before / after:>6.1f}x")
        rows.append({"bench": "systems_and_structure", "case": label, "before_s": before, "after_s": after,
                     "ratio": before / after})
