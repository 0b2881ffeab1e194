"""The stabilisable-set engine against a baseline commit, side by side in one run: CPU time (time.process_time,
OPENBLAS_NUM_THREADS=1) and the answers of each case, each version in its own subprocess, interleaved rounds,
best of the rounds. Cases: ``packetloss-cvx region`` on every shipped example (the CLI's run, its JSON data), the
plants and channels of tests/closedloop/test_region.py (least radii, memberships, critical points), and a few of
tests/closedloop/test_markov_region.py's (Gilbert-Elliott chains: memberships under both conventions, a rate map, a
critical mean rate); the plants come from tests/plants.py of this checkout for both versions. Rounds alternate which
version runs first.

    OPENBLAS_NUM_THREADS=1 python benchmarks/region_engine.py [--baseline /work/wt/base-region] [--rounds 3]
    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/region_engine.py --one-mode [--rounds 3]
    python benchmarks/region_engine.py --kernels

Prints per case: baseline and this CPU seconds, their ratio, the largest relative difference of the numbers
(lambdas, radii, margins, critical points) and whether every verdict is the same. With ``--one-mode``: the chain
strategy run on Bernoulli channels as one-mode chains against the Bernoulli strategy, in this checkout only (a
Markdown table, `one_mode`); with ``--kernels``: how far each strategy's least radius moves across OpenBLAS kernels
(`kernel_spread`).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent


def _flat(value, numbers: list, words: list) -> None:
    """Every number and every string of a JSON-like value, in order."""
    if isinstance(value, dict):
        for key in sorted(value):
            if key != "files":
                _flat(value[key], numbers, words)
    elif isinstance(value, (list, tuple)):
        for v in value:
            _flat(v, numbers, words)
    elif isinstance(value, bool) or value is None:
        words.append(repr(value))
    elif isinstance(value, (int, float)):
        numbers.append(float(value))
    elif isinstance(value, str):
        words.append(value)
    else:                           # numpy scalars and arrays
        import numpy as np
        arr = np.asarray(value)
        if arr.dtype.kind in "fiu":
            numbers.extend(float(v) for v in arr.ravel())
        else:
            words.extend(str(v) for v in arr.ravel())


def _plants():
    """tests/plants.py of this checkout (the plants the region tests use), loaded by path: the same cases for the
    baseline's worker, whose own tests may differ."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("region_engine_plants", HERE / "tests" / "plants.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def seeded_chains():
    """The chain-membership cases' plants: (seed, A, B, channel) for six seeded random plants (n <= 3, m <= 2) behind
    Gilbert-Elliott channels (also region_schedule_probe.py's)."""
    import numpy as np

    from packetloss_cvx.model.channel import GilbertElliott

    for seed in range(6):
        rng = np.random.default_rng(seed)
        n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
        A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
        yield seed, A, B, GilbertElliott(p=rng.uniform(0.05, 0.6, m), r=rng.uniform(0.05, 0.9, m))


def _cases():
    """name -> callable returning a JSON-like answer (the worker's cases)."""
    import numpy as np

    from packetloss_cvx import System, load_example
    from packetloss_cvx.cli.parser import build_parser
    from packetloss_cvx.cli.region import run
    from packetloss_cvx.closedloop.critical import critical_point
    from packetloss_cvx.closedloop.region import certificate_margin, homogeneous_riccati, membership
    from packetloss_cvx.model.examples import __file__ as examples_init

    def member(found):
        return [found.verdict, found.radius, found.certificate_margin, list(found.forms)]

    def point(p):
        return [p.t, p.lower, None if p.inside is None else p.inside.verdict,
                None if p.outside is None else p.outside.verdict]

    plants = _plants()
    scalar, decoupled, chain = plants.scalar, plants.decoupled, plants.chain

    def single_input(seed):
        return plants.single_input_plant(np.random.default_rng(seed))[0]

    def arrays(s):
        return np.asarray(s.A, float), np.asarray(s.B, float)

    folder = Path(examples_init).parent
    cases = {}
    for path in sorted(folder.glob("*.toml")):
        def cli(path=path):
            return run(build_parser().parse_args(["region", str(path), "-q"])).data
        cases[f"cli region {path.stem}"] = cli

    def scalar_forms():
        s = scalar()
        return [member(membership(s, [mu], forms=("riccati", "dp"))) for mu in (0.3, 0.74, 0.7499, 0.7501, 0.76,
                                                                                0.95)]

    def scalar_critical():
        return point(critical_point(scalar(), "dp"))

    def decoupled_critical():
        return [point(critical_point(decoupled(a), "dp")) for a in ((2.0, 1.5), (3.0, 1.2, 0.5), (1.1, 4.0))]

    def random_memberships():
        out = []
        for seed in range(6):
            rng = np.random.default_rng(seed)
            n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
            s = System(A=rng.normal(size=(n, n)), B=rng.normal(size=(n, m)), horizon=2, state_weight=[1.0] * n,
                       input_weight=[1.0] * m, mu=[1.0] * m, x0=[1.0] * n)
            out.append(member(membership(s, rng.uniform(size=m), forms=("riccati", "dp"))))
        return out

    def batch_two_actuator():
        two = load_example("two_actuator")
        axis = np.linspace(0.0, 1.0, 9)
        lam, P, K = homogeneous_riccati(*arrays(two), np.array([[a, b] for b in axis for a in axis]))
        return [lam, K]

    def batch_random():
        rng = np.random.default_rng(3)
        out = []
        for _ in range(6):
            n, m = rng.integers(1, 4, size=2)
            lam, _, K = homogeneous_riccati(rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.uniform(size=(12, m)))
            out += [lam, K]
        return out

    def jordan():
        return [homogeneous_riccati(*arrays(chain(a0)), np.array([mu]))[0]
                for a0, mu in ((1.0, 0.0124), (1.001, 0.002), (1.001, 0.0079), (1.001, 0.0186), (1.3, 0.5))]

    def jordan_membership():
        return member(membership(chain(1.0), np.array([0.0124]), forms=("riccati", "dp")))

    def mahler():
        return [point(critical_point(single_input(seed) if seed else chain(1.001), "dp")) for seed in range(5)]

    def unreached():
        out = []
        for A in ([[0.5, 1.0], [0.0, 1.2]], [[0.5, 0.0], [0.0, 1.2]]):
            s = System(A=A, B=[[1.0], [0.0]], horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0], mu=[1.0],
                       x0=[1.0, 1.0])
            out += [member(membership(s, [mu], forms=("riccati",))) for mu in (0.1, 0.5, 1.0)]
        return out

    def nilpotent():
        out = []
        for seed in range(4):
            rng = np.random.default_rng(seed)
            Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
            A, B = Q @ np.triu(2.0 * rng.normal(size=(3, 3)), 1) @ Q.T, rng.normal(size=(3, 1))
            out.append(homogeneous_riccati(A, B, np.array([[0.3], [0.7]]))[0])
        return out

    def deadbeat():
        s = load_example("two_actuator")
        return [member(membership(s, mu, forms=("riccati",))) for mu in ([1.0, 0.22], [1.0, 0.44], [0.33, 1.0],
                                                                            [1.0, 1.0])]

    def margins():
        A, B = np.array([[2.0]]), np.array([[1.0]])
        return [certificate_margin(A, B, np.array([mu]), np.eye(1)) for mu in np.linspace(0.05, 0.95, 19)]

    from packetloss_cvx.closedloop.markov_region import (
        chain_at_rate,
        chain_critical_rate,
        chain_membership,
        chain_rate_map,
    )
    from packetloss_cvx.model.channel import GilbertElliott

    def chain_memberships():
        out = []
        for _, A, B, ch in seeded_chains():
            for delivery in ("next", "current"):
                found = chain_membership(A, B, ch, delivery)
                out.append([found.verdict, found.radius, found.certificate_margin])
        return out

    def chain_map():
        two = load_example("two_actuator")
        return list(chain_rate_map(two.A, two.B, GilbertElliott(p=[0.3, 0.2], r=[0.4, 0.5]), np.linspace(0, 1, 4)))

    def chain_critical():
        a, corr = np.array([1.5, 1.2]), np.array([0.2, 0.6])
        ch = chain_at_rate(GilbertElliott(p=(1 - corr) / 2, r=(1 - corr) / 2), [0.5, 0.5])
        s = System(A=np.diag(a), B=np.eye(2), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
                   x0=[1.0, 1.0], channel=ch)
        return point(chain_critical_rate(s, [1.0, 1.0]))

    cases.update({"scalar memberships": scalar_forms, "scalar critical": scalar_critical,
                  "decoupled critical": decoupled_critical, "random memberships": random_memberships,
                  "batch two_actuator 9x9": batch_two_actuator, "batch random": batch_random,
                  "jordan least radius": jordan, "jordan membership": jordan_membership,
                  "single-input critical (Mahler)": mahler, "unreached mode": unreached,
                  "nilpotent least radius": nilpotent, "deadbeat memberships": deadbeat,
                  "certificate margins": margins, "chain memberships (Markov)": chain_memberships,
                  "chain rate map 4x4 (Markov)": chain_map, "chain critical rate (Markov)": chain_critical})
    return cases


def worker(repeats: int) -> None:
    """Run every case ``repeats`` times in this process; print one JSON line: name -> (best CPU s, numbers, words)."""
    import packetloss_cvx
    out = {"module": packetloss_cvx.__file__}
    for name, case in _cases().items():
        best, answer = float("inf"), None
        for _ in range(repeats):
            t0 = time.process_time()
            answer = case()
            best = min(best, time.process_time() - t0)
        numbers, words = [], []
        _flat(answer, numbers, words)
        out[name] = (best, numbers, words)
    print(json.dumps(out))


def _one_mode_cases():
    """(family, A, B, mu, hand) of the one-mode comparison; hand the least radius by a formula where one exists (a
    Jordan block of size 4 driven at its last state: Elia's a0^2 (1 - mu)^(1/4); a decoupled plant with B = I:
    max_i a_i^2 (1 - mu)), else None."""
    import numpy as np

    from packetloss_cvx import load_example

    two = load_example("two_actuator")
    axis = np.linspace(0.05, 1.0, 6)
    cases = [("two_actuator 6x6", np.asarray(two.A, float), np.asarray(two.B, float), np.array([a, b]), None)
             for a in axis for b in axis]
    cases += [("Jordan chains (graded P)", a0 * np.eye(4) + np.eye(4, k=1), np.eye(4)[:, 3:], np.array([mu]),
               a0 ** 2 * (1.0 - mu) ** 0.25) for a0, mu in ((1.0, 0.0124), (1.001, 0.002), (1.3, 0.5))]
    for seed in range(10):
        rng = np.random.default_rng(seed)
        n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
        cases.append(("random plants", rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.uniform(size=m), None))
    cases += [("decoupled plants", np.diag(a), np.eye(len(a)), np.full(len(a), mu), max(a) ** 2 * (1.0 - mu))
              for a in ((2.0, 1.5), (3.0, 1.2, 0.5)) for mu in (0.3, 0.6, 0.9)]
    return cases


#: the phases of each strategy, by (module, function) as cProfile names them: the power iteration, the policy
#: iteration (with the chain's unregularised refinement), and the function whose calls count the power steps
_PHASES = {"bernoulli": ("region", "_power", ("_policy_iteration",), "_homogeneous_step"),
           "chain": ("chain_radius", "_power", ("_policy", "_refine"), "_apply")}


def _phases(profile, strategy: str) -> tuple[float, float, int]:
    """(power CPU s, policy CPU s, power steps) of one strategy from a cProfile run (cumulative times: the profiler's
    own cost inflates both alike). A power step is a call of the map from the power iteration (the Bernoulli
    strategy's calls are batched: one a step whether the batch holds one point or many; here each point runs
    alone)."""
    import pstats

    module, power, policy, step = _PHASES[strategy]
    out = [0.0, 0.0, 0]
    for (path, _, name), (_, _, _, cum, callers) in pstats.Stats(profile).stats.items():
        if not path.endswith(f"closedloop/{module}.py"):
            continue
        if name == power:
            out[0] += cum
        elif name in policy:
            out[1] += cum
        if name == step:
            out[2] += sum(c[1] for (where, _, caller), c in callers.items()
                          if caller == power and where.endswith(f"closedloop/{module}.py"))
    return out[0], out[1], out[2]


def one_mode(repeats: int) -> None:
    """The chain strategy (chain_radius.homogeneous_coupled_riccati: regularised power iteration to checkpoints 30,
    90, 270, ..., a regularised policy iteration and its unregularised refinement at each, stopped where the gains'
    radius meets the Collatz-Wielandt bound of their eigenvector; balanced where P is graded) run on Bernoulli
    channels as one-mode chains, against the Bernoulli strategy (region.homogeneous_riccati: power iteration handed
    to an unregularised Kronecker policy iteration after 30 steps, or after 4 where its steps shrink too slowly;
    balanced where P is graded) at the same points. Per family: CPU of each (best of ``repeats``), their ratio, the
    largest relative difference of the least radius between them and of each from the hand value where there is
    one, and from one profiled run each strategy's power steps a point, their CPU a step and the shares of its time
    in its power and its policy iteration (with the chain's refinement)."""
    import cProfile
    import pstats

    from packetloss_cvx.closedloop.chain_radius import homogeneous_coupled_riccati
    from packetloss_cvx.closedloop.region import homogeneous_riccati
    from packetloss_cvx.model.channel import MarkovChannel

    def channel(mu):
        return MarkovChannel(transition=[[[1.0]]] * len(mu), delivery=[[float(x)] for x in mu])

    strategies = {"bernoulli": lambda A, B, mu: homogeneous_riccati(A, B, mu)[0],
                  "chain": lambda A, B, mu: homogeneous_coupled_riccati(A, B, channel(mu))[0]}
    families: dict[str, list] = {}
    for case in _one_mode_cases():
        families.setdefault(case[0], []).append(case[1:])
    rows = []
    for family, cases in families.items():
        row = {"family": family, "points": len(cases)}
        lams = {}
        for label, solve in strategies.items():
            best = float("inf")
            for _ in range(repeats):
                t0 = time.process_time()
                lams[label] = [solve(A, B, mu) for A, B, mu, _ in cases]
                best = min(best, time.process_time() - t0)
            profile = cProfile.Profile()
            profile.enable()
            for A, B, mu, _ in cases:
                solve(A, B, mu)
            profile.disable()
            power, policy, steps = _phases(profile, label)
            total = sum(v[3] for k, v in pstats.Stats(profile).stats.items()
                        if k[2] in ("homogeneous_riccati", "homogeneous_coupled_riccati"))
            row[label] = (best, power / total, policy / total, steps / len(cases), power / max(steps, 1))
            hands = [(lam, hand) for lam, (*_, hand) in zip(lams[label], cases, strict=True) if hand is not None]
            row[f"{label} hand"] = max((abs(lam - hand) / hand for lam, hand in hands), default=None)
        row["diff"] = max(0.0 if b == c else abs(b - c) / abs(b) for b, c in zip(lams["bernoulli"], lams["chain"],
                                                                                   strict=True))
        rows.append(row)
    print(f"one-mode chains: the chain strategy against the Bernoulli strategy (least radius), CPU best of {repeats}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', '(unset)')}, "
          f"OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE', '(unset)')}")
    print("| family | points | Bernoulli ms | chain ms | ratio | power steps a point (B / chain) | profiled µs a power "
          "step (B / chain) | time in power, policy (B) | time in power, policy (chain) | max rel diff | rel err from "
          "hand (B / chain) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    totals = [0.0, 0.0]
    for row in rows:
        b, c = row["bernoulli"], row["chain"]
        totals[0] += b[0]
        totals[1] += c[0]
        hand = ("-" if row["bernoulli hand"] is None else
                f"{row['bernoulli hand']:.1e} / {row['chain hand']:.1e}")
        print(f"| {row['family']} | {row['points']} | {1e3 * b[0]:.1f} | {1e3 * c[0]:.1f} | {c[0] / b[0]:.2f} | "
              f"{b[3]:.0f} / {c[3]:.0f} | {1e6 * b[4]:.0f} / {1e6 * c[4]:.0f} | "
              f"{100 * b[1]:.0f} %, {100 * b[2]:.0f} % | {100 * c[1]:.0f} %, {100 * c[2]:.0f} % | {row['diff']:.1e} | "
              f"{hand} |")
    print(f"| total | {sum(r['points'] for r in rows)} | {1e3 * totals[0]:.1f} | {1e3 * totals[1]:.1f} | "
          f"{totals[1] / totals[0]:.2f} | | | | | | |")


#: the OpenBLAS kernels `kernel_spread` runs the one-mode cases under
_KERNELS = ("Haswell", "Prescott", "Nehalem", "Sandybridge", "Zen", "SkylakeX")


def one_mode_radii() -> None:
    """Print one JSON line: the least radius of every one-mode case by each strategy (a worker of `kernel_spread`)."""
    from packetloss_cvx.closedloop.chain_radius import homogeneous_coupled_riccati
    from packetloss_cvx.closedloop.region import homogeneous_riccati
    from packetloss_cvx.model.channel import MarkovChannel

    out = []
    for family, A, B, mu, _ in _one_mode_cases():
        chain = MarkovChannel(transition=[[[1.0]]] * len(mu), delivery=[[float(x)] for x in mu])
        out.append([family, homogeneous_riccati(A, B, mu)[0], homogeneous_coupled_riccati(A, B, chain)[0]])
    print(json.dumps(out))


def kernel_spread() -> None:
    """The one-mode cases' least radii under each OpenBLAS kernel of _KERNELS (a subprocess each, this checkout):
    per family and strategy, the largest relative spread of a point's least radius across the kernels, beside the
    largest relative difference of the two strategies under any one kernel. How far a least radius is reproducible
    at all, so how near two iterations can be asked to agree."""
    env = {**os.environ, "PYTHONPATH": str(HERE), "OPENBLAS_NUM_THREADS": "1"}
    runs = {}
    for kernel in _KERNELS:
        done = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--one-mode-radii"], capture_output=True,
                              env={**env, "OPENBLAS_CORETYPE": kernel}, text=True, cwd=HERE)
        if done.returncode:
            raise RuntimeError(f"{kernel}: the worker failed\n{done.stderr[-3000:]}")
        runs[kernel] = json.loads(done.stdout.strip().splitlines()[-1])

    def rel(values: list[float]) -> float:
        top = max(abs(v) for v in values)
        return (max(values) - min(values)) / top if top > 0 else 0.0

    rows: dict[str, list[float]] = {}
    for k, (family, *_) in enumerate(runs[_KERNELS[0]]):
        spread_b = rel([runs[kernel][k][1] for kernel in _KERNELS])
        spread_c = rel([runs[kernel][k][2] for kernel in _KERNELS])
        apart = max(rel(runs[kernel][k][1:]) for kernel in _KERNELS)
        old = rows.get(family, [0.0, 0.0, 0.0])
        rows[family] = [max(old[0], spread_b), max(old[1], spread_c), max(old[2], apart)]
    print(f"least radius across the OpenBLAS kernels {', '.join(_KERNELS)} (largest relative spread of a point)")
    print("| family | Bernoulli strategy across kernels | chain strategy across kernels | the two apart (worst kernel)"
          " |")
    print("|---|---|---|---|")
    for family, (spread_b, spread_c, apart) in rows.items():
        print(f"| {family} | {spread_b:.1e} | {spread_c:.1e} | {apart:.1e} |")


def _run(root: Path, repeats: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(root), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker", str(repeats)], env=env,
                          capture_output=True, text=True, cwd=root)
    if done.returncode:
        raise RuntimeError(f"{root}: the worker failed\n{done.stderr[-3000:]}")
    data = json.loads(done.stdout.strip().splitlines()[-1])
    if not data["module"].startswith(str(root)):
        raise RuntimeError(f"{root}: imported {data['module']}")
    return data


def _rel(a: list[float], b: list[float]) -> float:
    if len(a) != len(b):
        return float("inf")
    worst = 0.0
    for x, y in zip(a, b, strict=True):
        if x == y or (x != x and y != y):
            continue
        worst = max(worst, abs(x - y) / max(abs(x), abs(y), 1e-300))
    return worst


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--baseline", default="/work/wt/base-region")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--worker", type=int, default=None)
    parser.add_argument("--one-mode", action="store_true", help="only the one-mode comparison of the two strategies")
    parser.add_argument("--kernels", action="store_true", help="the one-mode least radii across OpenBLAS kernels")
    parser.add_argument("--one-mode-radii", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        worker(args.worker)
        return
    if args.one_mode_radii:
        one_mode_radii()
        return
    if args.kernels:
        kernel_spread()
        return
    if args.one_mode:
        one_mode(args.rounds)
        return
    roots = {"baseline": Path(args.baseline).resolve(), "this": HERE}
    best: dict[str, dict] = {"baseline": {}, "this": {}}
    for k in range(args.rounds):
        for label, root in (list(roots.items()) if k % 2 == 0 else list(roots.items())[::-1]):
            data = _run(root, args.repeats)
            for name, value in data.items():
                if name == "module":
                    continue
                cpu, numbers, words = value
                old = best[label].get(name)
                best[label][name] = (min(cpu, old[0]) if old else cpu, numbers, words)
    print(f"CPU seconds, best of {args.rounds} rounds x {args.repeats} repeats, OPENBLAS_NUM_THREADS=1, "
          f"OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE', '(unset)')}")
    print(f"{'case':<34} {'baseline':>9} {'this':>9} {'ratio':>6}  {'max rel diff':>12}  verdicts")
    totals = [0.0, 0.0]
    for name, (cpu, numbers, words) in best["baseline"].items():
        new = best["this"][name]
        totals[0] += cpu
        totals[1] += new[0]
        same = "same" if words == new[2] else "DIFFER"
        print(f"{name:<34} {cpu:9.4f} {new[0]:9.4f} {new[0] / cpu:6.3f}  {_rel(numbers, new[1]):12.2e}  {same}")
    print(f"{'total':<34} {totals[0]:9.4f} {totals[1]:9.4f} {totals[1] / totals[0]:6.3f}")


if __name__ == "__main__":
    main()
