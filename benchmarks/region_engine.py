"""The stabilisable-set engine against a baseline commit, side by side in one run: CPU time (time.process_time,
OPENBLAS_NUM_THREADS=1) and the answers of each case, each version in its own subprocess, interleaved rounds,
best of the rounds. Cases: ``packetloss-cvx region`` on every shipped example (the CLI's run, its JSON data), the
plants and channels of tests/closedloop/test_region.py (least radii, memberships, critical points), and a few of
tests/closedloop/test_markov_region.py's (Gilbert-Elliott chains: memberships under both conventions, a rate map, a
critical mean rate); the plants come from tests/plants.py of this checkout for both versions. Rounds alternate which
version runs first.

    OPENBLAS_NUM_THREADS=1 python benchmarks/region_engine.py [--baseline /work/wt/base-region] [--rounds 3]
    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/region_engine.py --one-mode

Prints per case: baseline and this CPU seconds, their ratio, the largest relative difference of the numbers
(lambdas, radii, margins, critical points) and whether every verdict is the same.
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
        for seed in range(6):
            rng = np.random.default_rng(seed)
            n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
            A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
            ch = GilbertElliott(p=rng.uniform(0.05, 0.6, m), r=rng.uniform(0.05, 0.9, m))
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


def one_mode() -> None:
    """The chain strategy (chain_radius.homogeneous_coupled_riccati: regularised power and policy iteration, no
    balancing) run on Bernoulli channels as one-mode chains, against the Bernoulli strategy (region.homogeneous_riccati:
    batched power iteration, Kronecker policy iteration, graded balancing) at the same points: the largest relative
    difference of the least radius per family and the CPU ratio. Why the two iterations are kept apart."""
    import numpy as np

    from packetloss_cvx import load_example
    from packetloss_cvx.closedloop.chain_radius import homogeneous_coupled_riccati
    from packetloss_cvx.closedloop.region import homogeneous_riccati
    from packetloss_cvx.model.channel import MarkovChannel

    def channel(mu):
        return MarkovChannel(transition=[[[1.0]]] * len(mu), delivery=[[float(x)] for x in mu])

    two = load_example("two_actuator")
    axis = np.linspace(0.05, 1.0, 6)
    cases = [("two_actuator 6x6", np.asarray(two.A, float), np.asarray(two.B, float), np.array([a, b]))
             for a in axis for b in axis]
    cases += [("Jordan chains (graded P)", a0 * np.eye(4) + np.eye(4, k=1), np.eye(4)[:, 3:], np.array([mu]))
              for a0, mu in ((1.0, 0.0124), (1.001, 0.002), (1.3, 0.5))]
    for seed in range(10):
        rng = np.random.default_rng(seed)
        n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
        cases.append(("random plants", rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.uniform(size=m)))
    cases += [("decoupled plants", np.diag(a), np.eye(len(a)), np.full(len(a), mu))
              for a in ((2.0, 1.5), (3.0, 1.2, 0.5)) for mu in (0.3, 0.6, 0.9)]
    worst: dict[str, float] = {}
    cpu = [0.0, 0.0]
    for name, A, B, mu in cases:
        t0 = time.process_time()
        lam_b = homogeneous_riccati(A, B, mu)[0]
        t1 = time.process_time()
        lam_c = homogeneous_coupled_riccati(A, B, channel(mu))[0]
        cpu[0] += t1 - t0
        cpu[1] += time.process_time() - t1
        worst[name] = max(worst.get(name, 0.0), 0.0 if lam_b == lam_c else abs(lam_b - lam_c) / abs(lam_b))
    print("one-mode chains through the chain strategy against the Bernoulli strategy (least radius):")
    for name, rel in worst.items():
        print(f"    {name:<26} max rel diff {rel:.1e}")
    print(f"    CPU: Bernoulli strategy {cpu[0]:.3f} s, chain strategy {cpu[1]:.3f} s ({cpu[1] / cpu[0]:.1f}x)")


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
    args = parser.parse_args()
    if args.worker is not None:
        worker(args.worker)
        return
    if args.one_mode:
        one_mode()
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
