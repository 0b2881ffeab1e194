"""Numbers do not move: every cost and gain of the Theorem-1 paths, computed by two checkouts.

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=CHECKOUT python benchmarks/kernel_agreement.py dump OUT.pkl
    python benchmarks/kernel_agreement.py compare BASE.pkl NEW.pkl

``dump`` evaluates, on seeded random systems (``model.random_systems.random_system``: non-stationary mu
schedules, mu with zeros and ones, time-varying weights, unstable A, noise, Q; plus long stationary
horizons for the stationary tail and Gilbert-Elliott chains with fractional h for the MJLS), the
closed forms (dense / recursion / auto, both protocols: cost, plan, gain), CostEvaluator
(costs, solve, line), expected_cost, cost_difference, dp_riccati, dp_finite_horizon and
coupled_riccati; on the slowly converging plant (:func:`slow_plant`, rho(A) = 1.06) and long uniform horizons
of unstable plants also every gain of backward_pass and expected_cost of the closed form's plan (the plan rolled
forward again, open loop). An error is recorded by its type. ``compare`` prints the worst relative difference per
quantity (max |a - b| / max |b| per array) and whether the same calls raised the same errors.
Written before the kernel was merged (issue 19), run against the baseline and the branch.
"""

from __future__ import annotations

import pickle
import sys

import numpy as np

SYSTEMS = 300
LONG = 24
CHAINS = 60


def _call(fn):
    try:
        return fn()
    except Exception as exc:  # noqa: BLE001 - the type is the answer
        return ("error", type(exc).__name__)


def _systems():
    from packetloss_cvx import System
    from packetloss_cvx.model.random_systems import random_system

    rng = np.random.default_rng(19)
    out = []
    for k in range(SYSTEMS):
        s = random_system(rng)
        if k % 5 == 0:                    # mu with exact zeros (and ones)
            mu = s.mu_schedule.copy()
            mu[..., 0] = 0.0
            if s.m > 1:
                mu[..., -1] = 1.0
            s = s.with_mu(mu if s.mu_schedule.shape[0] > 1 and k % 10 == 0 else mu[0])
        out.append(("random", s))
    for k in range(LONG):                 # long stationary horizons (the stationary tail)
        n, m = int(rng.integers(1, 5)), int(rng.integers(1, 4))
        N = int(rng.choice([200, 600, 2000]))
        s = random_system(rng, n=n, m=m, horizon=N, spectral_radius=float(rng.uniform(0.5, 1.05)),
                          time_varying=False, non_stationary=k % 6 == 5, edge_mu=k % 4 == 3)
        if k % 3 == 0:
            s = s.with_mu(np.ones(m))
        out.append(("long", s))
    for k in range(4):                    # the case: n = 4, m = 2, mu = 1, N = 10^4
        s = random_system(np.random.default_rng(k), n=4, m=2, horizon=10_000, spectral_radius=0.95,
                          time_varying=False, non_stationary=False, noise=k % 2 == 1, edge_mu=False)
        out.append(("long", s.with_mu([1.0, 1.0]) if k < 2 else s))
    for N in (300, 2_000, 10_000):        # the slowly converging plant (rho(A) = 1.06), and its variants
        for mu in ([1.0, 1.0], [0.9, 0.6], [1.0, 0.0]):
            out.append(("slow", slow_plant(N).with_mu(mu)))
    for k in range(8):                    # long uniform horizons of unstable plants (rho(A) up to 1.1)
        n, m = int(rng.integers(2, 5)), int(rng.integers(1, 3))
        s = random_system(rng, n=n, m=m, horizon=int(rng.choice([500, 3000])),
                          spectral_radius=float(rng.uniform(1.0, 1.1)), time_varying=False, non_stationary=False,
                          edge_mu=False)
        out.append(("slow", s.with_mu(np.ones(m)) if k % 2 else s))
    _ = System
    return out


def slow_plant(N: int):
    """The paper's pendulum A with two inputs, weights diag(5, 1, 1, 1) and (2, 1), x0 = (0.1, 0, 0.1, 0), mu = 1:
    its Riccati pass converges slowly (the closed loop contracts by about 0.99 per step)."""
    from packetloss_cvx import System

    A = [[1.001, 0.005, 0.000, 0.000], [0.35, 1.001, -0.135, 0.000], [-0.001, 0.000, 1.001, 0.005],
         [-0.375, -0.001, 0.590, 1.001]]
    B = [[0.001, 0.2], [0.540, 0.0], [-0.002, 0.1], [-1.066, 0.3]]
    return System(A=A, B=B, horizon=N, state_weight=[5.0, 1.0, 1.0, 1.0], input_weight=[2.0, 1.0], mu=[1.0, 1.0],
                  x0=[0.1, 0.0, 0.1, 0.0])


def _chains():
    from packetloss_cvx import System
    from packetloss_cvx.model.channel import GilbertElliott

    rng = np.random.default_rng(7)
    out = []
    for k in range(CHAINS):
        n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
        A = rng.normal(size=(n, n))
        A *= rng.uniform(0.5, 1.1) / max(abs(np.linalg.eigvals(A)))
        hg = rng.uniform(0.5, 1.0, m) if k % 2 else np.ones(m)
        hb = rng.uniform(0.0, 0.5, m) if k % 2 else np.zeros(m)
        if k % 10 == 9:
            hb = hg.copy()                # equal h: the memoryless reduction
        ch = GilbertElliott(p=rng.uniform(0.01, 0.4, m), r=rng.uniform(0.1, 0.9, m), h_good=hg, h_bad=hb)
        out.append(System(A=A, B=rng.normal(size=(n, m)), horizon=5, state_weight=rng.uniform(0.2, 2, n),
                          input_weight=rng.uniform(0.2, 2, m), x0=rng.normal(size=n), channel=ch))
    return out


def dump(path: str) -> None:
    import packetloss_cvx as pl
    from packetloss_cvx.closedloop.mjls import coupled_riccati, jump_law_stage_costs
    from packetloss_cvx.closedloop.riccati import dp_finite_horizon, dp_riccati
    from packetloss_cvx.lq.difference import cost_difference
    from packetloss_cvx.lq.evaluator import CostEvaluator
    from packetloss_cvx.lq.recursion import backward_pass

    res: dict = {}
    rng = np.random.default_rng(3)
    for k, (kind, s) in enumerate(_systems()):
        for p in ("tcp", "udp"):
            methods = ("dense", "recursion", "auto") if kind == "random" else ("recursion", "auto")
            if kind == "slow":            # every gain of the backward pass, and the plan rolled forward again
                out = _call(lambda s=s, p=p: backward_pass(s, p))
                res[(k, p, "backward_pass")] = out if isinstance(out[0], str) else (out[0], out[1])
                sol = _call(lambda s=s, p=p: pl.closed_form(s, p, "recursion"))
                res[(k, p, "expected_cost_of_plan")] = sol if isinstance(sol, tuple) else _call(
                    lambda s=s, p=p, sol=sol: pl.expected_cost(s, sol.inputs, p))
            for method in methods:
                sol = _call(lambda s=s, p=p, method=method: pl.closed_form(s, p, method))
                res[(k, p, method, "closed_form")] = sol if isinstance(sol, tuple) else (
                    sol.cost, np.array(sol.inputs), np.array(sol.gain))
            U = rng.normal(size=(s.horizon, s.m))
            res[(k, p, "expected_cost")] = _call(lambda s=s, p=p, U=U: pl.expected_cost(s, U, p))
            if kind in ("long", "slow"):
                continue
            res[(k, p, "expected_cost_dense")] = _call(lambda s=s, p=p, U=U: pl.expected_cost(s, U, p, "dense"))
            mus = rng.uniform(0, 1, (4, s.m))
            mus[0, 0] = 0.0
            mus[1] = 1.0
            sched = rng.uniform(0, 1, (3, s.horizon, s.m))
            for method in ("auto", "recursion", "dense"):
                ev = _call(lambda s=s, p=p, method=method: CostEvaluator(s, p, method))
                if isinstance(ev, tuple):
                    res[(k, p, method, "evaluator")] = ev
                    continue
                res[(k, p, method, "ev.costs")] = _call(lambda ev=ev, mus=mus: ev.costs(mus))
                res[(k, p, method, "ev.costs_sched")] = _call(lambda ev=ev, sched=sched: ev.costs(sched))
                sol = _call(lambda ev=ev, mus=mus: ev.solve(mus))
                res[(k, p, method, "ev.solve")] = sol if isinstance(sol, tuple) else (
                    np.array(sol.costs), np.array(sol.inputs), np.array(sol.gains))
                res[(k, p, method, "ev.cost")] = _call(lambda ev=ev, mus=mus: [ev.cost(mu) for mu in mus])
                line = _call(lambda ev=ev, mu=mus[2]: ev.line(mu, 0))
                res[(k, p, method, "ev.line")] = line if isinstance(line, tuple) else _call(
                    lambda line=line: [line(v) for v in (0.0, 0.3, 0.77, 1.0)])
        if kind == "random":
            res[(k, "cost_difference")] = _call(lambda s=s: cost_difference(s))
            res[(k, "cost_difference_mu")] = _call(lambda s=s: cost_difference(s, 0.4))
            mu0 = s.mu_schedule[0]
            dp = _call(lambda s=s, mu0=mu0: dp_riccati(s, mu0))
            res[(k, "dp_riccati")] = dp if isinstance(dp, tuple) else (np.array(dp.gain), np.array(dp.cost_to_go))
            fh = _call(lambda s=s, mu0=mu0: dp_finite_horizon(s, 6, mu0))
            res[(k, "dp_finite_horizon")] = fh if isinstance(fh[0], str) else (
                np.array(fh[0]), np.array(fh[1]), fh[2])
    for k, s in enumerate(_chains()):
        r = _call(lambda s=s: coupled_riccati(s))
        res[("chain", k, "coupled_riccati")] = r if isinstance(r, tuple) else (
            np.array(r.gains), np.array(r.cost_matrices), r.spectral_radius)
        if not isinstance(r, tuple):
            res[("chain", k, "jump_costs")] = _call(lambda s=s, r=r: jump_law_stage_costs(s, r.gains, 8))
    with open(path, "wb") as f:
        pickle.dump(res, f)
    print(f"{len(res)} quantities written to {path}")


def _leaves(value):
    if isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], str):
        return [value]
    if isinstance(value, (tuple, list)):
        return [leaf for v in value for leaf in _leaves(v)]
    return [np.asarray(value, dtype=float)]


def compare(base_path: str, new_path: str) -> None:
    with open(base_path, "rb") as f:
        base = pickle.load(f)
    with open(new_path, "rb") as f:
        new = pickle.load(f)
    worst: dict = {}
    errors_differ = []
    for key, b in base.items():
        a = new.get(key, ("error", "missing"))
        name = key[-1]
        la, lb = _leaves(a), _leaves(b)
        if len(la) != len(lb) or any(isinstance(x, tuple) != isinstance(y, tuple) for x, y in zip(la, lb, strict=True)):
            errors_differ.append((key, a if isinstance(a, tuple) and isinstance(a[0], str) else "value",
                                  b if isinstance(b, tuple) and isinstance(b[0], str) else "value"))
            continue
        for x, y in zip(la, lb, strict=True):
            if isinstance(x, tuple):
                if x != y:
                    errors_differ.append((key, x, y))
                continue
            if x.shape != y.shape:
                errors_differ.append((key, x.shape, y.shape))
                continue
            if not x.size:
                continue
            scale = float(np.max(np.abs(y)))
            diff = float(np.max(np.abs(x - y))) if np.all(np.isfinite(x) == np.isfinite(y)) else np.inf
            rel = diff / scale if scale > 0 else diff
            count, top, where = worst.get(name, (0, 0.0, None))
            worst[name] = (count + 1, max(top, rel), key if rel >= top else where)
    print(f"{'quantity':<22} {'arrays':>7} {'worst relative':>15}  at")
    for name, (count, top, where) in sorted(worst.items()):
        print(f"{name:<22} {count:>7} {top:>15.2e}  {where}")
    overall = max(top for _, top, _ in worst.values())
    print(f"overall worst relative difference: {overall:.2e} over {sum(c for c, _, _ in worst.values())} arrays")
    print(f"calls whose outcome (value or error type) differs: {len(errors_differ)}")
    for item in errors_differ[:20]:
        print("  ", item)


if __name__ == "__main__":
    if sys.argv[1] == "dump":
        dump(sys.argv[2])
    else:
        compare(sys.argv[2], sys.argv[3])
