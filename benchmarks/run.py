"""Side-by-side benchmarks: every ratio is measured in one run on one machine.

    python benchmarks/run.py [--quick] [--json] [--only 8,9] [--baseline ../previous-checkout]

Medians over repeats (wall clock, ``time.perf_counter``); peak memory with
``tracemalloc`` (NumPy reports its buffers to it). Absolute times drift between
runs on a shared machine; the ratios are what to read.
"""

from __future__ import annotations

import argparse
import inspect
import json
import platform
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from markov_tail import markov_tail  # noqa: E402  (benchmarks/markov_tail.py, section 21)
from slow_plant import slow_plant  # noqa: E402  (benchmarks/slow_plant.py, section 20)
from structure import systems_and_structure  # noqa: E402  (benchmarks/structure.py, section 17)

import packetloss_cvx as pl  # noqa: E402
from packetloss_cvx.model.random_systems import random_system  # noqa: E402

PROTOCOL = "udp"  # the protocol with more work (the variance weights)


def bench_system(N: int, n: int = 4, m: int = 2) -> pl.System:
    """A fixed stable random plant (rho(A) = 0.95), diagonal weights, stationary channel, no noise
    (with noise the dense path also forms Lambda' Omega Lambda, (N n)^3 more work)."""
    return random_system(
        np.random.default_rng(2026), n=n, m=m, horizon=N, spectral_radius=0.95, full_weights=False,
        time_varying=False, non_stationary=False, noise=False, edge_mu=False,
    )


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def peak_memory(fn) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def closed_forms(horizons, rows):
    print("\n1. closed form: recursion vs dense (n = 4, m = 2, UDP-like)")
    print(f"{'N':>6} {'dense s':>10} {'recursion s':>12} {'ratio':>8} {'rel cost diff':>14}")
    for N in horizons:
        s = bench_system(N)
        reps = 1 if N >= 2000 else 3
        dense = median_time(lambda s=s: pl.closed_form(s, PROTOCOL, "dense"), reps)
        rec = median_time(lambda s=s: pl.closed_form(s, PROTOCOL, "recursion"), max(reps, 5))
        a, b = pl.closed_form(s, PROTOCOL, "recursion").cost, pl.closed_form(s, PROTOCOL, "dense").cost
        diff = abs(a - b) / abs(b)
        print(f"{N:>6} {dense:>10.4f} {rec:>12.4f} {dense / rec:>7.1f}x {diff:>14.1e}")
        rows.append({"bench": "closed_form", "N": N, "dense_s": dense, "recursion_s": rec,
                     "ratio": dense / rec, "rel_cost_diff": diff})


def crossover(rows):
    print("\n2. crossover of method='auto' (n = 4, m = 2): dense / recursion time")
    print(f"{'N':>6} {'N*m':>6} {'dense s':>10} {'recursion s':>12} {'ratio':>8}")
    for N in (2, 5, 10, 15, 20, 30, 40, 80):
        s = bench_system(N)
        dense = median_time(lambda s=s: pl.closed_form(s, PROTOCOL, "dense"), 21)
        rec = median_time(lambda s=s: pl.closed_form(s, PROTOCOL, "recursion"), 21)
        print(f"{N:>6} {2 * N:>6} {dense:>10.5f} {rec:>12.5f} {dense / rec:>7.2f}x")
        rows.append({"bench": "crossover", "N": N, "dense_s": dense, "recursion_s": rec, "ratio": dense / rec})


def qps(horizons, big, rows):
    print("\n3. QP compile + solve: sparse vs condensed (cvxpy + Clarabel, n = 4, m = 2)")
    print(f"{'N':>6} {'condensed s':>12} {'sparse s':>10} {'ratio':>8}")

    def run(s, form):
        return pl.solve_qp(s, PROTOCOL, form, with_gain=False, cross_check=False)

    for N in horizons:
        s = bench_system(N)
        reps = 1 if N >= 1000 else 3
        cond = median_time(lambda s=s: run(s, "condensed"), reps)
        sparse = median_time(lambda s=s: run(s, "sparse"), 3)
        print(f"{N:>6} {cond:>12.3f} {sparse:>10.3f} {cond / sparse:>7.1f}x")
        rows.append({"bench": "qp", "N": N, "condensed_s": cond, "sparse_s": sparse, "ratio": cond / sparse})
    s = bench_system(big)
    t = median_time(lambda: run(s, "sparse"), 1)
    print(f"   sparse QP at N = {big}: {t:.1f} s")
    rows.append({"bench": "qp_big", "N": big, "sparse_s": t})
    print("   crossover of formulation='auto' (condensed / sparse time):")
    for N in (5, 10, 20, 40, 80):
        small = bench_system(N)
        cond = median_time(lambda s=small: run(s, "condensed"), 7)
        sparse = median_time(lambda s=small: run(s, "sparse"), 7)
        print(f"{N:>6} {cond:>12.4f} {sparse:>10.4f} {cond / sparse:>7.2f}x")
        rows.append({"bench": "qp_crossover", "N": N, "condensed_s": cond, "sparse_s": sparse,
                     "ratio": cond / sparse})


def sweep(points, rows):
    N = 100
    print(f"\n4. {points}-point mu sweep, sparse QP at N = {N}: re-solve via Parameters vs rebuild")
    s = bench_system(N)
    grid = [np.array([g, 1.0 - 0.5 * g]) for g in np.linspace(0.05, 0.95, points)]

    def reuse():
        qp = pl.ExpectedCostQP(s, PROTOCOL, "sparse")
        return [qp.solve(mu=mu, with_gain=False, cross_check=False).cost for mu in grid]

    def rebuild():
        return [pl.solve_qp(s.with_mu(mu), PROTOCOL, "sparse", with_gain=False, cross_check=False).cost
                for mu in grid]

    t_reuse = median_time(reuse, 3)
    t_rebuild = median_time(rebuild, 3)
    same = np.allclose(reuse(), rebuild(), rtol=1e-9)
    print(f"   rebuild {t_rebuild:.2f} s, re-solve {t_reuse:.2f} s, ratio {t_rebuild / t_reuse:.1f}x "
          f"(same costs: {same})")
    rows.append({"bench": "mu_sweep", "points": points, "rebuild_s": t_rebuild, "reuse_s": t_reuse,
                 "ratio": t_rebuild / t_reuse, "same_costs": bool(same)})


def verification_cost(N, rows):
    print(f"\n5. what solver-backed verification costs: sparse QP vs recursion at N = {N}")
    s = bench_system(N)
    qp = median_time(lambda: pl.solve_qp(s, PROTOCOL, "sparse", with_gain=False, cross_check=False), 3)
    rec = median_time(lambda: pl.closed_form(s, PROTOCOL, "recursion"), 5)
    print(f"   sparse QP {qp:.3f} s, recursion {rec:.4f} s, ratio {qp / rec:.0f}x")
    rows.append({"bench": "qp_vs_recursion", "N": N, "qp_s": qp, "recursion_s": rec, "ratio": qp / rec})


def self_check(horizons, rows):
    print("\n7. what the self-check costs: closed_form (Riccati + forward pass of its plan) vs the bare Riccati")
    print(f"{'N':>6} {'bare s':>10} {'checked s':>10} {'ratio':>8}")
    from packetloss_cvx.lq.recursion import backward_pass, mean_trajectory

    def bare(s):
        K, P0, noise = backward_pass(s, PROTOCOL)
        return mean_trajectory(s, K)

    for N in horizons:
        s = bench_system(N)
        a = median_time(lambda s=s: bare(s), 7)
        b = median_time(lambda s=s: pl.closed_form(s, PROTOCOL, "recursion"), 7)
        print(f"{N:>6} {a:>10.4f} {b:>10.4f} {b / a:>7.2f}x")
        rows.append({"bench": "self_check", "N": N, "bare_s": a, "checked_s": b, "ratio": b / a})


def memory(N, rows):
    print(f"\n6. peak memory at N = {N} (tracemalloc)")
    s = bench_system(N)
    rec = peak_memory(lambda: pl.closed_form(s, PROTOCOL, "recursion"))
    dense = peak_memory(lambda: pl.closed_form(s, PROTOCOL, "dense"))
    print(f"   dense {dense / 2**20:.1f} MiB, recursion {rec / 2**20:.2f} MiB, ratio {dense / rec:.0f}x")
    rows.append({"bench": "memory", "N": N, "dense_bytes": dense, "recursion_bytes": rec, "ratio": dense / rec})


def startup(rows, repeats: int = 7, baseline: str | None = None):
    """Start-up of the command line against `python -c "import numpy"` (subprocesses, medians of
    interleaved rounds); with ``baseline``, the closed-form commands run by that checkout too."""
    import os
    import subprocess

    print(f"\n13. command-line start-up (median of {repeats} runs, wall clock, s)")
    cases = [("python -c 'import numpy'", ["-c", "import numpy"]),
             ("python -c 'import cvxpy'", ["-c", "import cvxpy"])]
    cases += [(f"packetloss-cvx {' '.join(a)}", ["-m", "packetloss_cvx", *a]) for a in (
        ["--help"], ["--version"], ["solve", "--help"], ["audit", "--help"], ["allocate", "--help"],
        ["solve"], ["solve", "no-such-file.toml"], ["solve", "two_actuator", "--mu", "2"],
        ["allocate", "two_actuator", "--protocol", "udp", "--alpha", "8", "--beta", "1"],
        ["solve", "two_actuator", "--no-qp"], ["simulate", "two_actuator", "--samples", "200"],
        ["sweep", "two_actuator", "--mu-grid", "3", "--json"])]
    root = str(Path(__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": root, "OPENBLAS_NUM_THREADS": "1"}
    where = {label: (env, root) for label, _ in cases}     # `-m` puts the working folder first on sys.path
    if baseline:    # the closed-form commands as the baseline checkout runs them (cvxpy imported eagerly there)
        old = str(Path(baseline).resolve())
        for label, argv in list(cases[-3:]):
            cases.append((f"baseline {label.removeprefix('packetloss-cvx ')}", argv))
            where[cases[-1][0]] = ({**env, "PYTHONPATH": old}, old)

    times: dict[str, list[float]] = {label: [] for label, _ in cases}
    for _ in range(repeats):        # interleaved rounds: a busy spell on the shared machine hits every case
        for label, argv in cases:
            start = time.perf_counter()
            subprocess.run([sys.executable, *argv], env=where[label][0], cwd=where[label][1], capture_output=True,
                           check=False)
            times[label].append(time.perf_counter() - start)
    base = statistics.median(times[cases[0][0]])
    print(f"{'command':<78} {'s':>7} {'/ numpy':>8}")
    for label, _ in cases:
        t = statistics.median(times[label])
        print(f"{label:<78} {t:7.3f} {t / base:7.2f}x")
        rows.append({"bench": "startup", "command": label, "seconds": t, "ratio_to_numpy": t / base})
def per_run_loop(system: pl.System, K: np.ndarray, steps: int, samples: int, seed: int) -> np.ndarray:
    """The reference a vectorised simulation replaces: one Python loop per run, one per step."""
    rng = np.random.default_rng(seed)
    Omega, psi, mu = system.state_weights[0], system.input_weights[0], system.mu
    out = np.empty(samples)
    for s in range(samples):
        x, total = system.x0.copy(), 0.0
        for _ in range(steps):
            applied = (rng.random(system.m) < mu) * -(K @ x)
            total += x @ Omega @ x + applied ** 2 @ psi
            x = system.A @ x + system.B @ applied
        out[s] = total / steps
    return out


def minimal_loop(system: pl.System, gains: np.ndarray, steps: int, samples: int, rng, runs_last: bool = False):
    """The same laws as a minimal vectorised numpy loop: the simulator's draws (sample_delivery_paths, then
    sample_noise_paths from the same generator), one array operation per step over runs and laws, and only
    each run's mean stage cost (no norms, no kept states). Runs first with the issue's stage cost
    ``((X @ Omega) * X).sum(-1)``, or runs last (``X`` (L, n, runs)) as the simulator holds them."""
    from packetloss_cvx.montecarlo.channels import sample_delivery_paths, sample_noise_paths

    V = sample_delivery_paths(system, steps, samples, rng)
    W = sample_noise_paths(system, steps, samples, rng)
    Omega, psi, A, B = system.state_weights[0], system.input_weights[0], system.A, system.B
    total = 0.0
    if runs_last:
        V, W = V.transpose(0, 2, 1), None if W is None else W.transpose(0, 2, 1)
        X = np.broadcast_to(system.x0[:, None], (len(gains), system.n, samples)).copy()
        for t in range(steps):
            applied = V[t] * -(gains @ X)
            total = total + ((Omega @ X) * X).sum(1) + psi @ (applied * applied)
            X = A @ X + B @ applied
            if W is not None:
                X += W[t]
        return total / steps
    X = np.broadcast_to(system.x0, (len(gains), samples, system.n)).copy()
    KT = np.transpose(gains, (0, 2, 1))
    for t in range(steps):
        applied = V[t] * -(X @ KT)
        total = total + ((X @ Omega) * X).sum(-1) + applied ** 2 @ psi
        X = X @ A.T + applied @ B.T
        if W is not None:
            X += W[t]
    return total / steps


def cpu_medians(fns: dict, repeats: int) -> dict:
    """Median CPU seconds (time.process_time) of each callable, the runs interleaved (one of each per round)."""
    times: dict = {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            start = time.process_time()
            fn()
            times[k].append(time.process_time() - start)
    return {k: statistics.median(v) for k, v in times.items()}


def closed_loop(samples: int, steps: int, n_big: int, rows: list) -> None:
    """Closed loop: vectorised simulation vs a per-run loop; the mean-square radius at n_big, operator
    (ARPACK) vs the n^2 x n^2 Kronecker matrix."""
    from packetloss_cvx.closedloop.moments import closed_loop as exact_loop
    from packetloss_cvx.closedloop.stability import mean_square_radius
    from packetloss_cvx.montecarlo.simulate import closed_loop_block
    print("\n14. closed loop: the simulator vs a minimal vectorised loop and a per-run loop; mean-square radius, "
          "operator vs Kronecker")

    from threadpoolctl import threadpool_limits

    from packetloss_cvx.montecarlo.simulate import BLOCK, law_gains

    s = bench_system(10)
    K = pl.closed_form(s, "tcp").gain
    # the simulator's block against a minimal vectorised loop of the same laws: CPU time, one BLAS thread
    noisy = pl.System(A=s.A, B=s.B, horizon=s.horizon, state_weights=s.state_weights, input_weights=s.input_weights,
                      mu_schedule=s.mu_schedule, x0=s.x0, noise_cov=0.1 * np.eye(s.n))
    print(f"closed-loop block of {BLOCK} runs x {steps} steps, laws tcp, udp, dp, n = {s.n}, m = {s.m}; "
          "CPU ms, one BLAS thread, medians of interleaved runs (target: simulator within 1.2x the minimal loop)")
    for label, system in (("no noise", s), ("noise 0.1 I", noisy)):
        gains = np.stack(list(law_gains(system, ("tcp", "udp", "dp")).values()))
        same = max(float(np.max(np.abs(closed_loop_block(system, gains, steps, BLOCK, np.random.default_rng(k))[0]
                                       - minimal_loop(system, gains, steps, BLOCK, np.random.default_rng(k), last))
                                / minimal_loop(system, gains, steps, BLOCK, np.random.default_rng(k), last)))
                   for k in range(2) for last in (False, True))
        with threadpool_limits(1, user_api="blas"):
            cpu = cpu_medians({
                "simulator": lambda: closed_loop_block(system, gains, steps, BLOCK, np.random.default_rng(1)),
                "minimal, runs first": lambda: minimal_loop(system, gains, steps, BLOCK, np.random.default_rng(1)),
                "minimal, runs last": lambda: minimal_loop(system, gains, steps, BLOCK, np.random.default_rng(1), True),
            }, 3 if samples < 2000 else 7)
        ratios = {k: cpu["simulator"] / v for k, v in cpu.items() if k != "simulator"}
        print(f"  {label:<12} simulator {cpu['simulator'] * 1e3:6.1f}  minimal runs first "
              f"{cpu['minimal, runs first'] * 1e3:6.1f} ({ratios['minimal, runs first']:.2f}x)  minimal runs last "
              f"{cpu['minimal, runs last'] * 1e3:6.1f} ({ratios['minimal, runs last']:.2f}x)  "
              f"run means agree to {same:.1e}")
        rows.append({"bench": "closed_loop_vs_minimal", "case": label, "runs": BLOCK, "steps": steps, "laws": 3,
                     "simulator_cpu_s": cpu["simulator"], "minimal_runs_first_cpu_s": cpu["minimal, runs first"],
                     "minimal_runs_last_cpu_s": cpu["minimal, runs last"], "ratio_runs_first": ratios[
                         "minimal, runs first"], "ratio_runs_last": ratios["minimal, runs last"], "agree": same})
    vec = median_time(lambda: closed_loop_block(s, K[None], steps, samples, np.random.default_rng(0)), 3)
    loop = median_time(lambda: per_run_loop(s, K, steps, samples, 0), 1)
    print(f"closed-loop simulation, {samples} runs x {steps} steps, n = {s.n}, m = {s.m}: vectorised {vec:.3f} s, "
          f"per-run loop {loop:.2f} s, {loop / vec:.0f}x (target >= 30x)")
    rows.append({"bench": "closed_loop_simulation", "samples": samples, "steps": steps, "vectorised_s": vec,
                 "per_run_s": loop, "ratio": loop / vec})
    rng = np.random.default_rng(7)
    A = rng.normal(size=(n_big, n_big)) / np.sqrt(n_big)
    B = rng.normal(size=(n_big, 3))
    Kb = rng.normal(size=(3, n_big)) * 0.2
    mu = np.array([0.9, 0.6, 0.3])
    values = {}
    krylov = median_time(lambda: values.setdefault("krylov", mean_square_radius(A, B, Kb, mu, "krylov")), 3)
    kron = median_time(lambda: values.setdefault("kronecker", mean_square_radius(A, B, Kb, mu, "kronecker")), 1)
    agree = abs(values["krylov"] - values["kronecker"]) / values["kronecker"]
    print(f"mean-square radius at n = {n_big}: operator (ARPACK) {krylov:.3f} s, Kronecker {kron:.2f} s, "
          f"{kron / krylov:.0f}x; relative difference {agree:.1e}")
    rows.append({"bench": "mean_square_radius", "n": n_big, "operator_s": krylov, "kronecker_s": kron,
                 "ratio": kron / krylov, "relative_difference": agree})
    exact = median_time(lambda: exact_loop(s, K), 3)
    print(f"exact closed-loop cost (radius, two moment solves), n = {s.n}: {exact * 1e3:.2f} ms")
    rows.append({"bench": "exact_closed_loop", "n": s.n, "seconds": exact})
# ---------------------------------------------------------------- issue 14: speed where users wait

def allocation_system(seed: int) -> pl.System:
    """Three channels behind a near-identity B (comparable channels: hundreds of boxes), N = 40."""
    rng = np.random.default_rng(seed)
    n = m = 3
    A = rng.normal(size=(n, n))
    A *= 1.02 / max(abs(np.linalg.eigvals(A)))
    B = np.eye(n) + 0.3 * rng.normal(size=(n, m))
    return pl.System(A=A, B=B, horizon=40, state_weight=np.ones(n), input_weight=rng.uniform(0.5, 1.5, m),
                     mu=[0.5] * m, x0=rng.normal(size=n))


def allocation_alpha(system: pl.System) -> float:
    """The cost bound 0.3 of the way from J*_udp(mu = 1) to J*_udp(mu = 0)."""
    full = pl.closed_form(system.with_mu([1.0] * system.m), "udp").cost
    none = pl.closed_form(system.with_mu([0.0] * system.m), "udp").cost
    return full + 0.3 * (none - full)


class _ClosedFormEverywhere:
    """The allocation as it was: every J*(mu) through closed_form(system.with_mu(mu), "auto")."""

    def __init__(self, system, protocol):
        self.system, self.protocol = system, protocol

    def cost(self, mu, x0=None, checked=True):      # closed_form checks every value anyway
        return pl.closed_form(self.system.with_mu(np.clip(mu, 0.0, 1.0)), self.protocol, "auto").cost

    def solve(self, mus):
        from types import SimpleNamespace

        sols = [pl.closed_form(self.system.with_mu(mu), self.protocol, "auto") for mu in mus]
        return SimpleNamespace(costs=np.array([s.cost for s in sols]), inputs=np.array([s.inputs for s in sols]))

    def line(self, mu, i, checked=True):
        base = np.array(mu, dtype=float)

        def at(value):
            point = base.copy()
            point[i] = value
            return self.cost(point)
        return at


#: The baseline's run of one allocation case: this file's allocation_system and allocation_alpha (their
#: source, so both checkouts solve the same case), then the timed allocate.
BASELINE_ALLOCATION = """
import json, sys, time
import numpy as np
import packetloss_cvx as pl
from packetloss_cvx.allocation import allocate      # imported before the clock starts (4560768 has no pl.allocate)
{functions}
s = allocation_system(int(sys.argv[1]))
alpha = allocation_alpha(s)
start = time.process_time()
a = allocate(s, "udp", alpha, [1.0, 1.0, 1.0])
print(json.dumps({{"time": time.process_time() - start, "mu": a.mu.tolist(), "lower_bound": a.lower_bound,
                  "boxes": a.boxes, "status": a.status}}))
"""


def _baseline_allocation(baseline: str, seed: int) -> dict:
    """The same allocation (allocation_system(seed), the same alpha and beta) run by the baseline
    checkout in a fresh process, one BLAS thread."""
    import os
    import subprocess

    env = {**os.environ, "PYTHONPATH": str(Path(baseline).resolve()), "OPENBLAS_NUM_THREADS": "1"}
    code = BASELINE_ALLOCATION.format(functions="\n".join(inspect.getsource(f) for f in (allocation_system,
                                                                                       allocation_alpha)))
    out = subprocess.run([sys.executable, "-c", code, str(seed)], env=env, check=True,
                         capture_output=True, text=True, cwd=baseline).stdout
    return json.loads(out.strip().splitlines()[-1])


def allocation(seeds, rows, baseline=None):
    import packetloss_cvx.allocation.tcp as tcp_module
    import packetloss_cvx.allocation.udp as udp_module

    print("\n8. UDP-like allocation, m = 3, N = 40: J*(mu) by closed_form per call (before; today's closed_form, "
          "whose structure is now shared by with_mu copies) vs the cached evaluator" +
          ("; with --baseline, the same allocation run by that checkout" if baseline else "") +
          " (CPU seconds, time.process_time; run with OPENBLAS_NUM_THREADS=1). 'same': the same mu to 1e-9, bound and "
          "boxes; 'cert': the same status, and each answer's communication cost within the other's certified bounds")
    print(f"{'seed':>5} {'boxes':>6} {'before s':>9} {'after s':>8} {'ratio':>7}  same mu, bound, boxes"
          + (f" {'| baseline s':>12} {'ratio':>7}  same" if baseline else ""))
    cached = udp_module.cost_function

    def old(system, protocol):
        ev = _ClosedFormEverywhere(system, protocol)
        return ev.cost, ev

    for seed in seeds:
        s = allocation_system(seed)
        alpha = allocation_alpha(s)
        runs = {}
        for name, fn in (("after", cached), ("before", old)):
            udp_module.cost_function = tcp_module.cost_function = fn
            try:
                start = time.process_time()
                runs[name] = (pl.allocate(s, "udp", alpha, [1.0, 1.0, 1.0]), time.process_time() - start)
            finally:
                udp_module.cost_function = tcp_module.cost_function = cached
        (a, ta), (b, tb) = runs["after"], runs["before"]
        same = bool(np.allclose(a.mu, b.mu, rtol=0, atol=1e-9) and abs(a.lower_bound - b.lower_bound) <= 1e-12
                    and a.boxes == b.boxes and a.status == b.status)
        line = f"{seed:>5} {a.boxes:>6} {tb:>9.2f} {ta:>8.2f} {tb / ta:>6.1f}x  {same!s:>21}"
        row = {"bench": "allocation_udp_m3_N40", "seed": seed, "boxes": a.boxes, "before_s": tb,
               "after_s": ta, "ratio": tb / ta, "same": same}
        if baseline:
            base = _baseline_allocation(baseline, seed)
            same_base = bool(np.allclose(a.mu, base["mu"], rtol=0, atol=1e-9) and base["boxes"] == a.boxes
                             and abs(a.lower_bound - base["lower_bound"]) <= 1e-9 * max(1.0, abs(a.lower_bound))
                             and base["status"] == a.status)
            ours, theirs = a.communication_cost, float(np.sum(base["mu"]))           # beta = 1
            cert = bool(base["status"] == a.status and a.lower_bound <= theirs + 1e-12
                        and base["lower_bound"] <= ours + 1e-12)
            line += f" {base['time']:>12.2f} {base['time'] / ta:>6.1f}x  {same_base} cert {cert}"
            row.update(baseline_s=base["time"], baseline_ratio=base["time"] / ta, same_as_baseline=same_base,
                       within_certificates=cert)
        print(line)
        rows.append(row)


#: One process's TCP-like allocations (section 18): per case, six calls on one system (alpha 5-50 % of the
#: way from J*_tcp(1) to J*_tcp(0), seeded prices) and six least costs (min_cost under a budget
#: sum(mu) <= 0.1-0.6 m), CPU time of each call, and the answers.
TCP_ALLOCATION_RUN = """
import json, sys, time
import numpy as np
import packetloss_cvx as pl
from packetloss_cvx.allocation import min_cost
{functions}
cases = [("seed 1", allocation_system(1)), ("seed 2", allocation_system(2)), ("seed 3", allocation_system(3)),
         ("two_actuator", pl.load_example("two_actuator")), ("pendulum", pl.load_example("pendulum"))]
pl.allocate(pl.load_example("two_actuator").with_x0([1.0, 0.0]), "tcp", 6.0, [1.0, 1.0])    # imports, first compile
out = {{}}
for name, s in cases:
    full, none = (pl.closed_form(s.with_mu([v] * s.m), "tcp").cost for v in (1.0, 0.0))
    rng = np.random.default_rng(0)
    calls = [(full + f * (none - full), rng.uniform(0.5, 1.5, s.m)) for f in (0.3, 0.1, 0.5, 0.2, 0.4, 0.05)]
    times, answers = [], []
    for alpha, beta in calls:
        start = time.process_time()
        a = pl.allocate(s, "tcp", alpha, beta)
        times.append(time.process_time() - start)
        answers.append([a.mu.tolist(), a.lower_bound, a.status, float(beta @ a.mu)])
    least_times, least = [], []
    for f in (0.3, 0.1, 0.5, 0.2, 0.4, 0.6):
        start = time.process_time()
        c = min_cost(s, "tcp", constraints=[([[1.0] * s.m], [f * s.m])])
        least_times.append(time.process_time() - start)
        least.append([c.mu.tolist(), c.lower_bound, c.status, c.cost])
    out[name] = {{"times": times, "answers": answers, "min_cost_times": least_times, "min_cost_answers": least}}
print(json.dumps(out))
"""


def tcp_allocation(baseline, rows, rounds: int = 5):
    """TCP-like allocation and min_cost, m = 3, N = 40 (seeds 1-3) and the paper's examples: this checkout
    against ``baseline``, each in fresh processes with one BLAS thread, rounds interleaved; CPU time per
    call (``time.process_time``), the first call of a system (its SOCP compiled) and the median of the
    five calls after it (re-solved). The ratio of those medians per round: its median and range over the
    rounds. Same answers: status, mu to 1e-7, the largest relative difference of the proved lower bounds
    (both LPs' multipliers are exact to their tolerances only), and whether each answer lies inside the
    other checkout's certified bounds (value >= the other's lower bound, to 1e-12 relative)."""
    import os
    import subprocess

    if not baseline:
        print("\n18. TCP-like allocation: needs --baseline (a checkout to compare with)")
        return
    print(f"\n18. TCP-like allocation and min_cost, CPU ms per call (first call of a system | median of the next "
          f"five), {rounds} interleaved rounds, baseline {baseline}")
    code = TCP_ALLOCATION_RUN.format(functions="\n".join(inspect.getsource(f) for f in (allocation_system,)))
    runs: dict[str, list[dict]] = {"after": [], "before": []}
    for _ in range(rounds):
        for name, checkout in (("before", Path(baseline).resolve()), ("after", Path(__file__).resolve().parent.parent)):
            env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
            out = subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True, text=True,
                                 cwd=checkout).stdout
            runs[name].append(json.loads(out.strip().splitlines()[-1]))
    print(f"{'call':<9} {'case':<14} {'before first':>12} {'after first':>12} {'before next':>12} {'after next':>11} "
          f"{'ratio next (range)':>22}  same status, mu  inside bounds  max rel diff lower bound")
    for call, times, answers in (("allocate", "times", "answers"), ("min_cost", "min_cost_times", "min_cost_answers")):
        for case in runs["after"][0]:
            first = {k: statistics.median(r[case][times][0] for r in v) * 1e3 for k, v in runs.items()}
            rest = {k: statistics.median(t for r in v for t in r[case][times][1:]) * 1e3 for k, v in runs.items()}
            ratios = [statistics.median(b[case][times][1:]) / statistics.median(a[case][times][1:])
                      for b, a in zip(runs["before"], runs["after"], strict=True)]
            pairs = list(zip(runs["after"][0][case][answers], runs["before"][0][case][answers], strict=True))
            same = all(x[2] == y[2] and np.allclose(x[0], y[0], rtol=0, atol=1e-7) for x, y in pairs)
            bound = max(abs(x[1] - y[1]) / max(abs(y[1]), 1e-12) for x, y in pairs)
            inside = all(x[2] == y[2] and x[3] >= y[1] * (1 - 1e-12) and y[3] >= x[1] * (1 - 1e-12)
                         for x, y in pairs)
            ratio = statistics.median(ratios)
            print(f"{call:<9} {case:<14} {first['before']:>12.1f} {first['after']:>12.1f} {rest['before']:>12.1f} "
                  f"{rest['after']:>11.1f} {ratio:>6.2f}x ({min(ratios):.2f}-{max(ratios):.2f})  {same!s:>15}  "
                  f"{inside!s:>13}  {bound:>10.1e}")
            rows.append({"bench": "tcp_allocation", "call": call, "case": case, "before_first_ms": first["before"],
                         "after_first_ms": first["after"], "before_next_ms": rest["before"],
                         "after_next_ms": rest["after"], "ratio_next": ratio, "ratio_next_range": [min(ratios),
                         max(ratios)], "same": same, "inside_certified_bounds": inside,
                         "lower_bound_max_rel_diff": bound})


def evaluator(points, rows):
    from packetloss_cvx.lq.evaluator import CostEvaluator

    print(f"\n9. batched evaluator: {points} channels, loop of closed_form vs CostEvaluator (UDP-like)")
    print(f"{'system':>14} {'loop s':>8} {'batch s':>8} {'ratio':>7} {'one point: cf ms':>17} {'ev ms':>6} "
          f"{'ratio':>6} {'max rel diff':>13}")
    for label, s in (("two_actuator", pl.load_example("two_actuator")), ("m3 N40", allocation_system(1))):
        mus = np.random.default_rng(0).uniform(0.0, 1.0, (points, s.m))
        ev = CostEvaluator(s, PROTOCOL)
        loop = median_time(lambda s=s, mus=mus: [pl.closed_form(s.with_mu(mu), PROTOCOL).cost for mu in mus], 1)
        batch = median_time(lambda ev=ev, mus=mus: ev.costs(mus), 3)
        ref = np.array([pl.closed_form(s.with_mu(mu), PROTOCOL).cost for mu in mus])
        diff = float(np.max(np.abs(ev.costs(mus) - ref) / ref))
        one_cf = median_time(lambda s=s, mu=mus[0]: pl.closed_form(s.with_mu(mu), PROTOCOL), 51)
        one_ev = median_time(lambda ev=ev, mu=mus[0]: ev.cost(mu), 51)
        print(f"{label:>14} {loop:>8.3f} {batch:>8.4f} {loop / batch:>6.0f}x {one_cf * 1e3:>17.3f} "
              f"{one_ev * 1e3:>6.3f} {one_cf / one_ev:>5.1f}x {diff:>13.1e}")
        rows.append({"bench": "evaluator", "system": label, "points": points, "loop_s": loop, "batch_s": batch,
                     "ratio": loop / batch, "one_closed_form_s": one_cf, "one_evaluator_s": one_ev,
                     "max_rel_diff": diff})


QP_MEMORY = """
import time, tracemalloc
import numpy as np
import packetloss_cvx as pl
from packetloss_cvx.model.random_systems import random_system
def bench_system(N):
    return random_system(np.random.default_rng(2026), n=4, m=2, horizon=N, spectral_radius=0.95, full_weights=False,
                         time_varying=False, non_stationary=False, noise=False, edge_mu=False)
assert pl.__file__.startswith({checkout!r}), pl.__file__
pl.solve_qp(bench_system(10), "udp", "sparse", with_gain=False, cross_check=False)
s = bench_system({N})
tracemalloc.start()
start = time.perf_counter()
qp = pl.ExpectedCostQP(s, "udp", "sparse")
a = qp.solve(with_gain=False, cross_check=False)
first = time.perf_counter() - start
peak = tracemalloc.get_traced_memory()[1]
tracemalloc.reset_peak()
start = time.perf_counter()
b = qp.solve(mu=[0.7, 0.3], with_gain=False, cross_check=False)
again = time.perf_counter() - start
print(first, peak, again, tracemalloc.get_traced_memory()[1], repr(a.cost), repr(b.cost))
"""


def _qp_memory_run(N: int, checkout: Path) -> list[float]:
    """Peak memory and times of one sparse QP, in a fresh process with ``checkout`` on the path."""
    import os
    import subprocess

    env = {**os.environ, "PYTHONPATH": str(checkout.resolve()), "OPENBLAS_NUM_THREADS": "1"}
    code = QP_MEMORY.format(checkout=str(checkout.resolve()), N=N)
    out = subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True, text=True,
                         cwd=checkout)            # -c puts the working directory first on the path
    return [float(v) for v in out.stdout.split()]


def qp_memory(horizons, baseline, rows):
    print("\n10. sparse QP: peak memory (tracemalloc, a fresh process per N) and times, n = 4, m = 2, UDP-like;")
    print("    Z = Vbar U form (this checkout) beside the multiply(v, U) form (--baseline)")
    print(f"{'N':>6} {'compile+solve s':>16} {'peak MiB':>9} {'re-solve s':>11} {'re-solve MiB':>13} "
          f"{'| before: s':>12} {'MiB':>7} {'re-solve s':>11} {'same cost':>10}")
    here = Path(__file__).resolve().parent.parent
    for N in horizons:
        first, peak, again, peak2, cost, cost2 = _qp_memory_run(N, here)
        row = {"bench": "qp_memory", "N": N, "first_s": first, "peak_bytes": peak, "resolve_s": again,
               "resolve_peak_bytes": peak2}
        line = f"{N:>6} {first:>16.2f} {peak / 2**20:>9.1f} {again:>11.2f} {peak2 / 2**20:>13.1f}"
        if baseline:
            b_first, b_peak, b_again, _, b_cost, b_cost2 = _qp_memory_run(N, Path(baseline))
            same = abs(cost - b_cost) <= 1e-9 * b_cost and abs(cost2 - b_cost2) <= 1e-9 * b_cost2
            line += f" {b_first:>12.2f} {b_peak / 2**20:>7.0f} {b_again:>11.2f} {same!s:>10}"
            row.update(before_first_s=b_first, before_peak_bytes=b_peak, before_resolve_s=b_again, same=same)
        print(line)
        rows.append(row)


def blas_threads(rows):
    import os

    from threadpoolctl import threadpool_limits

    from packetloss_cvx import threads

    cores = os.cpu_count() or 1
    print(f"\n11. BLAS threads: the library's policy (1 thread) vs {cores} threads (BLAS default on this machine)")
    print(f"{'call':>28} {'threaded ms':>12} {'policy ms':>10} {'ratio':>7}")
    cases = (("closed_form dense N=40", lambda: pl.closed_form(bench_system(40), PROTOCOL, "dense")),
             ("closed_form dense N=80", lambda: pl.closed_form(bench_system(80), PROTOCOL, "dense")),
             ("closed_form recursion N=400", lambda: pl.closed_form(bench_system(400), PROTOCOL, "recursion")))
    for label, fn in cases:
        try:
            threads.set_blas_threads(None)
            with threadpool_limits(limits=cores, user_api="blas"):
                threaded = median_time(fn, 21)
        finally:
            threads.set_blas_threads(1)
        policy = median_time(fn, 21)
        print(f"{label:>28} {threaded * 1e3:>12.2f} {policy * 1e3:>10.2f} {threaded / policy:>6.1f}x")
        rows.append({"bench": "blas_threads", "call": label, "threaded_s": threaded, "policy_s": policy,
                     "ratio": threaded / policy})


def audit_time(baseline, rows):
    import subprocess

    from packetloss_cvx.claims import audit

    print("\n12. audit --random 200 --seed 1 (in process; with --baseline, the same command from that checkout)")
    start = time.perf_counter()
    audit(random=200, seed=1)
    ours = time.perf_counter() - start
    line = f"   this checkout {ours:.1f} s"
    row = {"bench": "audit", "after_s": ours}
    if baseline:
        code = ("import time; from packetloss_cvx.claims import audit; t = time.perf_counter(); "
                "audit(random=200, seed=1); print(time.perf_counter() - t)")
        env = {**__import__("os").environ, "PYTHONPATH": str(Path(baseline).resolve())}
        before = float(subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True,
                                      text=True, cwd=baseline).stdout.split()[-1])
        line += f", baseline {before:.1f} s, ratio {before / ours:.2f}x"
        row.update(before_s=before, ratio=before / ours)
    print(line)
    rows.append(row)
    # CPU seconds per claim, each checkout in a fresh process (the seeded cases built outside the timing)
    ours_cpu = _claim_cpu(Path(__file__).resolve().parent.parent)
    before_cpu = _claim_cpu(Path(baseline)) if baseline else {}
    print(f"   CPU s per claim{'':>20} {'this':>7}" + (f" {'baseline':>9} {'ratio':>6}" if baseline else ""))
    for claim in list(dict.fromkeys([*before_cpu, *ours_cpu])):
        a, b = ours_cpu.get(claim), before_cpu.get(claim)
        print(f"   {claim:>32} {a if a is not None else float('nan'):7.2f}"
              + (f" {b if b is not None else float('nan'):9.2f} {b / a if a and b else float('nan'):5.2f}x"
                 if baseline else ""))
    shared = [c for c in ours_cpu if c in before_cpu]
    total = sum(ours_cpu.values())
    line = f"   {'total':>32} {total:7.2f}"
    if baseline:
        line += (f" {sum(before_cpu.values()):9.2f} {sum(before_cpu.values()) / total:5.2f}x; on the baseline's "
                 f"claims only: {sum(ours_cpu[c] for c in shared):.2f} s, "
                 f"{sum(before_cpu[c] for c in shared) / sum(ours_cpu[c] for c in shared):.2f}x")
    print(line)
    rows.append({"bench": "audit_cpu", "after": ours_cpu, "before": before_cpu})


def shared_qps(repeats, rows):
    """Section 15: the audit's 200 random systems x 2 protocols through ExpectedCostQP (condensed, one
    solve each, no gain, no cross-check), with every problem compiled per object (exact shape,
    ``SHARED_MAX_ENTRIES = 0``) against the problems shared by padded shape (from an empty cache:
    the shared side pays its compiles); interleaved, medians of ``repeats``."""
    from packetloss_cvx.qp import shared as qp_shared

    rng = np.random.default_rng(1)
    systems = [random_system(rng) for _ in range(200)]
    limit = qp_shared.SHARED_MAX_ENTRIES

    def run(shared: bool):
        qp_shared.clear_cache()
        qp_shared.SHARED_MAX_ENTRIES = limit if shared else 0
        try:
            return [pl.ExpectedCostQP(s, p, "condensed").solve(with_gain=False, cross_check=False)
                    for s in systems for p in ("tcp", "udp")]
        finally:
            qp_shared.SHARED_MAX_ENTRIES = limit

    print("\n15. compiled QPs shared by shape: the audit's 200 random systems x 2 protocols, condensed, one solve "
          "each")
    times = {True: [], False: []}
    answers = {}
    for _ in range(repeats):
        for shared in (False, True):
            start = time.perf_counter()
            answers[shared] = run(shared)
            times[shared].append(time.perf_counter() - start)
    own, shared = statistics.median(times[False]), statistics.median(times[True])
    buckets = len(qp_shared.cached_shapes())
    du = max(float(np.abs(s.mu_schedule * (a.inputs - b.inputs)).max(initial=0.0))
             / max(float(np.abs(s.mu_schedule * b.inputs).max(initial=0.0)), 1e-300)
             for s, a, b in zip([s for s in systems for _ in "tp"], answers[True], answers[False], strict=True))
    dj = max(abs(a.cost - b.cost) / abs(b.cost) for a, b in zip(answers[True], answers[False], strict=True))
    print(f"   compiled per system: {own:.2f} s ({own / 400 * 1e3:.2f} ms a solve, 400 compiles)")
    print(f"   shared by shape:     {shared:.2f} s ({shared / 400 * 1e3:.2f} ms a solve, {buckets} compiles)")
    print(f"   ratio {own / shared:.2f}x; max rel |Vbar dU| {du:.1e}, max rel dJ {dj:.1e} (shared vs per system)")
    rows.append({"bench": "shared_qps", "per_system_s": own, "shared_s": shared, "ratio": own / shared,
                 "compiles": buckets, "max_rel_input_diff": du, "max_rel_cost_diff": dj})


CLAIM_CPU = """
import json, time
import numpy as np
from packetloss_cvx.claims import registry
from packetloss_cvx.claims.context import Context, paper_systems
from packetloss_cvx.model.random_systems import random_system
rng = np.random.default_rng(1)
ctx = Context(paper=paper_systems(), random=[random_system(rng) for _ in range(200)], seed=1)
out = {}
for claim in registry.CLAIMS:
    start = time.process_time()
    registry.run_claim(claim, ctx)
    out[claim] = time.process_time() - start
print(json.dumps(out))
"""


def _claim_cpu(checkout: Path) -> dict:
    """CPU seconds per claim of ``audit(random=200, seed=1)``'s cases, run from ``checkout``."""
    import subprocess

    env = {**__import__("os").environ, "PYTHONPATH": str(Path(checkout).resolve())}
    out = subprocess.run([sys.executable, "-c", CLAIM_CPU], env=env, check=True, capture_output=True, text=True,
                         cwd=checkout).stdout
    return json.loads(out.splitlines()[-1])


EVALUATIONS = """
import json, time
import numpy as np
from packetloss_cvx.allocation import brute_force
from packetloss_cvx.claims.channel_allocation import GRID, alpha_levels
from packetloss_cvx.claims.context import paper_systems
from packetloss_cvx.claims.paper import ALLOCATION_BETAS
from packetloss_cvx.lq.evaluator import CostEvaluator
from packetloss_cvx.threads import blas_limited
s = paper_systems()["two_actuator"]
ev = CostEvaluator(s, "udp", "recursion")
out = {}
for P in (1, 15):
    mus = np.random.default_rng(0).uniform(0.0, 1.0, (P, 2))
    run = blas_limited(lambda: [ev.costs(mus) for _ in range(200)])
    best = np.inf
    for _ in range(7):
        t = time.perf_counter(); run(); best = min(best, (time.perf_counter() - t) / 200)
    out[f"costs_P{P}_s"] = best
calls = [0]
real = CostEvaluator.costs
def counted(self, *args, **kwargs):
    calls[0] += 1
    return real(self, *args, **kwargs)
CostEvaluator.costs = counted
alphas = alpha_levels(s)[0]
t = time.process_time()
cases = [(a, b) for b in ALLOCATION_BETAS for a in alphas]
if hasattr(brute_force, "brute_force_allocations"):     # side by side, as the claim runs them
    answers = brute_force.brute_force_allocations(s, "udp", cases, **GRID)
else:
    answers = [brute_force.brute_force_allocation(s, "udp", a, b, **GRID) for a, b in cases]
out["allocations_cpu_s"] = time.process_time() - t
out["allocation_calls"] = calls[0]
out["answers"] = [list(a) if a else None for a in answers]
print(json.dumps(out))
"""


def evaluations(baseline, rows):
    """Section 16: the audit's J* evaluations: one batched-recursion call (two_actuator, UDP-like, 1 and 15
    points, BLAS limited once outside) and the 18 brute-force allocations of allocation-udp-perfect-channel
    as the claim runs them (side by side where the checkout can; evaluator calls, CPU seconds, answers),
    each checkout in a fresh process."""
    import subprocess

    def measure(checkout: Path) -> dict | None:
        """The checkout's numbers, or None when it has no CostEvaluator (before 2026-11-21, e.g. d88a42b)."""
        if not (Path(checkout) / "packetloss_cvx" / "evaluator.py").exists():
            return None     # (not an import error: an editable install would fill the gap from this checkout)
        env = {**__import__("os").environ, "PYTHONPATH": str(Path(checkout).resolve())}
        out = subprocess.run([sys.executable, "-c", EVALUATIONS], env=env, check=True, capture_output=True,
                             text=True, cwd=checkout).stdout
        return json.loads(out.splitlines()[-1])

    print("\n16. J* evaluations of the audit (two_actuator, UDP-like, recursion)")
    ours = measure(Path(__file__).resolve().parent.parent)
    before = measure(Path(baseline)) if baseline else {}
    if before is None:
        print(f"   the baseline {baseline} has no CostEvaluator: compare with a checkout of 1002bdf or later")
        baseline, before = None, {}
    print(f"{'':>36} {'this':>9}" + (f" {'baseline':>9} {'ratio':>6}" if baseline else ""))
    for key, label, scale in (("costs_P1_s", "costs(), 1 point (us)", 1e6),
                              ("costs_P15_s", "costs(), 15 points (us)", 1e6),
                              ("allocation_calls", "brute force: evaluator calls", 1),
                              ("allocations_cpu_s", "brute force: 18 allocations (CPU s)", 1)):
        a, b = ours[key] * scale, before.get(key, float("nan")) * scale
        print(f"{label:>36} {a:9.4g}" + (f" {b:9.4g} {b / a:5.2f}x" if baseline else ""))
    if baseline:
        print(f"{'same 18 answers':>36} {ours['answers'] == before['answers']}")
    rows.append({"bench": "evaluations", "after": ours, "before": before})


# ---------------------------------------------------------------- issue 19: stationary long horizons

def stationary_tail(horizons, repeats, rows):
    """closed_form(method="recursion") at mu = 1 (n = 4, m = 2, bench_system's plant, rho(A) = 0.95) against
    scipy's solve_discrete_are on the same (A, B), CPU time (time.process_time; run with
    OPENBLAS_NUM_THREADS=1), interleaved, minimum over repeats; a fresh System per run (nothing cached), and
    the full pass (the closure switched off) for the cost agreement and as the before."""
    from scipy.linalg import solve_discrete_are

    import packetloss_cvx.lq.recursion as recursion

    print("\n19. stationary long horizons (issue 19): closed_form(method='recursion'), mu = 1, n = 4, m = 2, vs "
          "scipy solve_discrete_are on the same (A, B); CPU ms, min of interleaved runs")
    print(f"{'N':>6} {'proto':>5} {'dare ms':>8} {'closed ms':>10} {'ratio':>6} {'full ms':>8} {'full/closed':>11}"
          f" {'|dJ|/J vs full':>15}")

    def fresh(N):
        s = bench_system(N)
        return pl.System(A=s.A, B=s.B, horizon=N, state_weight=np.diag(s.state_weights[0]),
                         input_weight=s.input_weights[0], mu=[1.0, 1.0], x0=s.x0)

    def cpu(fn):
        start = time.process_time()
        out = fn()
        return time.process_time() - start, out

    saved = recursion.STATIONARY_RUN
    for N in horizons:
        s0 = fresh(N)
        R = np.diag(s0.input_weights[0])
        for protocol in ("tcp", "udp"):
            times = {"dare": [], "closed": [], "full": []}
            for _ in range(repeats):
                times["dare"].append(cpu(lambda: solve_discrete_are(s0.A, s0.B, s0.state_weights[0], R))[0])
                system = fresh(N)
                t, closed = cpu(lambda system=system: pl.closed_form(system, protocol, "recursion"))
                times["closed"].append(t)
                system = fresh(N)
                recursion.STATIONARY_RUN = 10**9
                try:
                    t, full = cpu(lambda system=system: pl.closed_form(system, protocol, "recursion"))
                finally:
                    recursion.STATIONARY_RUN = saved
                times["full"].append(t)
            d, c, f = (min(times[k]) for k in ("dare", "closed", "full"))
            rel = abs(closed.cost - full.cost) / full.cost
            print(f"{N:>6} {protocol:>5} {d * 1e3:>8.3f} {c * 1e3:>10.3f} {c / d:>5.1f}x {f * 1e3:>8.1f} "
                  f"{f / c:>10.0f}x {rel:>15.1e}")
            rows.append({"bench": "stationary_tail", "N": N, "protocol": protocol, "dare_s": d, "closed_s": c,
                         "full_s": f, "ratio_to_dare": c / d, "cost_rel_vs_full": rel})


#: One process's stationary long horizon (section 19 with a baseline): closed_form(method="recursion") at mu = 1
#: on a fresh System per call, against scipy's solve_discrete_are on the same (A, B) repeated back to back (the
#: second call timed: a warm DARE), alternating, CPU time; the medians.
STATIONARY_RUN_CODE = """
import json, statistics, sys, time
import numpy as np
from scipy.linalg import solve_discrete_are
import packetloss_cvx as pl
data = json.loads(sys.argv[1])
A, B, q, r, x0 = (np.array(data[k]) for k in ("A", "B", "q", "r", "x0"))
Q, R = np.diag(q), np.diag(r)
def fresh():
    return pl.System(A=A, B=B, horizon=data["N"], state_weight=Q, input_weight=r, mu=[1.0] * B.shape[1], x0=x0)
pl.closed_form(fresh(), data["protocol"], "recursion")
dare, closed = [], []
for _ in range(data["repeats"]):
    solve_discrete_are(A, B, Q, R)
    start = time.process_time()
    solve_discrete_are(A, B, Q, R)
    dare.append(time.process_time() - start)
    system = fresh()
    start = time.process_time()
    pl.closed_form(system, data["protocol"], "recursion")
    closed.append(time.process_time() - start)
print(json.dumps({"dare": statistics.median(dare), "closed": statistics.median(closed)}))
"""


def stationary_rounds(baseline, N, rounds, rows, repeats=21, protocol="tcp"):
    """Section 19 against a baseline checkout: per round, one fresh process per checkout (interleaved, one BLAS
    thread) times closed_form at N against a warm DARE (:data:`STATIONARY_RUN_CODE`); the per-round ratio of the
    medians, its median and range over the rounds."""
    import os
    import subprocess

    s = bench_system(N)
    data = {"A": s.A.tolist(), "B": s.B.tolist(), "q": np.diag(s.state_weights[0]).tolist(),
            "r": s.input_weights[0].tolist(), "x0": s.x0.tolist(), "N": N, "protocol": protocol}
    checkouts = {"baseline": Path(baseline).resolve(), "this": Path(__file__).resolve().parent.parent}
    out: dict[str, list[dict]] = {k: [] for k in checkouts}
    for _ in range(rounds):
        for name, checkout in checkouts.items():
            env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
            arg = json.dumps({**data, "repeats": repeats if name == "this" else 3})
            text = subprocess.run([sys.executable, "-c", STATIONARY_RUN_CODE, arg], env=env, check=True,
                                  capture_output=True, text=True, cwd=checkout).stdout
            out[name].append(json.loads(text.strip().splitlines()[-1]))
    print(f"\n   N = {N}, {protocol}, {rounds} interleaved rounds, fresh processes; ratio = median closed_form / "
          f"median warm DARE of the same process")
    print(f"   {'checkout':<40} {'warm dare ms':>12} {'closed_form ms':>15} {'ratio median (range)':>22}")
    for name, checkout in checkouts.items():
        ratios = [r["closed"] / r["dare"] for r in out[name]]
        dare = statistics.median(r["dare"] for r in out[name]) * 1e3
        closed = statistics.median(r["closed"] for r in out[name]) * 1e3
        print(f"   {str(checkout):<40} {dare:>12.3f} {closed:>15.3f} {statistics.median(ratios):>9.2f}x "
              f"({min(ratios):.2f}-{max(ratios):.2f})")
        rows.append({"bench": "stationary_rounds", "checkout": str(checkout), "N": N, "protocol": protocol,
                     "warm_dare_ms": dare, "closed_ms": closed, "ratio_median": statistics.median(ratios),
                     "ratio_range": [min(ratios), max(ratios)]})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes (a minute or two)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON at the end")
    parser.add_argument("--startup", action="store_true", help="only the command line's start-up section")
    parser.add_argument("--only", help="comma-separated section numbers to run (default: all)")
    parser.add_argument("--baseline",
                        help="a checkout of the previous version (sections 8, 10, 12, 13, 16, 18-21: before/after)")
    args = parser.parse_args()
    if args.startup:
        rows: list[dict] = []
        startup(rows, baseline=args.baseline)
        print(json.dumps(rows) if args.json else "")
        return
    import clarabel
    import cvxpy

    print(f"python {platform.python_version()}, numpy {np.__version__}, cvxpy {cvxpy.__version__}, "
          f"clarabel {clarabel.__version__}, {platform.machine()}, {time.strftime('%Y-%m-%d')}")
    rows: list[dict] = []
    quick = args.quick
    sections = {
        1: lambda: closed_forms((100, 400, 1000) if quick else (100, 1000, 4000), rows),
        2: lambda: crossover(rows),
        3: lambda: qps((100, 400) if quick else (100, 400, 1000), 1000 if quick else 5000, rows),
        4: lambda: sweep(20 if quick else 50, rows),
        5: lambda: verification_cost(400 if quick else 1000, rows),
        6: lambda: memory(1000 if quick else 4000, rows),
        7: lambda: self_check((100, 1000) if quick else (100, 1000, 10000), rows),
        8: lambda: allocation((1,) if quick else (1, 2, 3), rows, args.baseline),
        9: lambda: evaluator(200 if quick else 1000, rows),
        10: lambda: qp_memory((500, 1000, 2000) if quick else (500, 1000, 2000, 4000, 8000), args.baseline, rows),
        11: lambda: blas_threads(rows),
        12: lambda: audit_time(args.baseline, rows),
        13: lambda: startup(rows, baseline=args.baseline),
        14: lambda: closed_loop(500 if quick else 2000, 100, 30 if quick else 50, rows),
        15: lambda: shared_qps(1 if quick else 3, rows),
        16: lambda: evaluations(args.baseline, rows),
        17: lambda: systems_and_structure(rows),
        18: lambda: tcp_allocation(args.baseline, rows, 2 if quick else 5),
        19: lambda: (stationary_tail((1000, 10_000) if quick else (1000, 10_000, 100_000), 5 if quick else 15, rows),
                     args.baseline and stationary_rounds(args.baseline, 10_000, 2 if quick else 5, rows)),
        20: lambda: slow_plant(args.baseline, rows, 2 if quick else 5),
        21: lambda: markov_tail(args.baseline, rows, quick),
    }
    chosen = sorted(sections) if not args.only else [int(k) for k in args.only.split(",")]
    for key in chosen:
        sections[key]()
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
