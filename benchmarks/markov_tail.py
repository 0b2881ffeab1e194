"""Section 21 of benchmarks/run.py: the exact Markov cost over long horizons, this tree against a baseline tree, side
by side, each point in a fresh process (one BLAS thread), and every number compared.

    OPENBLAS_NUM_THREADS=1 python benchmarks/markov_tail.py [--baseline DIR] [--quick] [--json]

``DIR`` is a checkout of the baseline (for example ``git archive <commit> | tar -x -C DIR``); without it, this tree's
times alone. For each example
(pendulum_bursty as shipped, its twin with A scaled to rho(A) = 0.99, a stable plant under Gilbert–Elliott
channels started away from their stationary law with process noise, a 3-state chain) and horizon N = 500 .. 32000,
both trees run, in fresh processes, ``exact_closed_form`` (udp: the augmented recursion; tcp) and ``exact_cost`` of
a fixed random plan (udp), best of 3 CPU times (time.process_time) after a warm-up on a short horizon. Printed: each
tree's time of the exact UDP-like minimum, their ratio, and the largest relative difference over the costs, plans
and gains of both protocols and the cost of the random plan (``error`` where a tree raises; the error's type must
then agree).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ("pendulum_bursty", "twin", "ge_noise", "three_state")

CHILD = r"""
import json, sys, time
import numpy as np
import packetloss_cvx as pl
from packetloss_cvx.errors import NumericalError, ResourceError
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel

def build(name, N):
    base = pl.load_example("pendulum_bursty")
    if name in ("pendulum_bursty", "twin"):
        A = base.A if name == "pendulum_bursty" else base.A / max(abs(np.linalg.eigvals(base.A))) * 0.99
        return pl.System(A=A, B=base.B, horizon=N, state_weight=np.diag(base.state_weights[0]),
                         input_weight=base.input_weights[0], x0=base.x0, channel=base.channel)
    rng = np.random.default_rng(7)
    if name == "ge_noise":
        A = rng.standard_normal((3, 3)); A *= 0.9 / max(abs(np.linalg.eigvals(A)))
        return pl.System(A=A, B=rng.standard_normal((3, 2)), horizon=N, state_weight=[1.0, 2.0, 0.5],
                         input_weight=[0.3, 0.7], x0=[1.0, -0.5, 0.2], noise_cov=np.diag([0.1, 0.05, 0.2]),
                         channel=GilbertElliott(p=[0.1, 0.3], r=[0.4, 0.2], state=["bad", "good"]))
    A = rng.standard_normal((2, 2)); A *= 0.95 / max(abs(np.linalg.eigvals(A)))
    chain = MarkovChannel(transition=[[[0.8, 0.2, 0.0], [0.1, 0.6, 0.3], [0.3, 0.0, 0.7]]], delivery=[[1.0, 0.4, 0.0]],
                          state=[2])
    return pl.System(A=A, B=[[1.0], [0.5]], horizon=N, state_weight=[1.0, 1.0], input_weight=[0.5], x0=[1.0, 1.0],
                     noise_cov=np.eye(2) * 0.01, channel=chain)

def run(s, plan):
    out = {}
    for protocol in ("udp", "tcp"):
        try:
            sol = exact_closed_form(s, protocol)
            out[protocol] = {"cost": sol.cost, "inputs": sol.inputs.tolist(), "gain": sol.gain.tolist()}
        except (NumericalError, ResourceError) as err:
            out[protocol] = type(err).__name__
    try:
        out["plan"] = exact_cost(s, plan)
    except (NumericalError, ResourceError) as err:
        out["plan"] = type(err).__name__
    return out

name, N = sys.argv[1], int(sys.argv[2])
build(name, 300)
run(build(name, 300), np.zeros((300, build(name, 300).m)))
best = None
for _ in range(3):
    s = build(name, N)
    t = time.process_time()
    try:
        exact_closed_form(s, "udp", method="recursion")
    except (NumericalError, ResourceError):
        pass
    best = min(best or 1e9, time.process_time() - t)
s = build(name, N)
plan = np.random.default_rng(3).standard_normal((N, s.m)) * 0.97 ** np.arange(N)[:, None]
out = run(s, plan)
out["seconds"] = best
print(json.dumps(out))
"""


def child(tree: Path, name: str, N: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", CHILD, name, str(N)], env=env, capture_output=True, text=True,
                          check=True, cwd=tree)
    return json.loads(done.stdout)


def difference(a, b) -> float:
    """The largest relative difference of two nested results (inf where their shapes or error types differ)."""
    import numpy as np

    if isinstance(a, str) or isinstance(b, str):
        return 0.0 if a == b else float("inf")
    if isinstance(a, dict) or isinstance(b, dict):
        return max(difference(a[k], b[k]) for k in a) if isinstance(a, dict) and isinstance(b, dict) else float("inf")
    x, y = np.asarray(a, float), np.asarray(b, float)
    if x.shape != y.shape:
        return float("inf")
    scale = np.max(np.abs(y)) if y.size else 0.0
    return float(np.max(np.abs(x - y)) / scale) if scale > 0 else float(np.max(np.abs(x - y), initial=0.0))


def markov_tail(baseline: str | None, rows: list, quick: bool = False) -> None:
    """Section 21: see the module docstring. ``quick``: N = 500 and 8000 only."""
    horizons = (500, 8000) if quick else (500, 2000, 8000, 32000)
    trees = {"this": ROOT, **({"baseline": Path(baseline).resolve()} if baseline else {})}
    print(f"\n21. the exact Markov minimum (udp, augmented recursion) over long horizons: CPU ms, best of 3, fresh "
          f"processes, one BLAS thread{'; this tree against ' + str(trees['baseline']) if baseline else ''}")
    print(f"   {'example':>16} {'N':>6} {'base ms':>9} {'this ms':>9} {'ratio':>6} {'max rel diff':>12}")
    for name in EXAMPLES:
        for N in horizons:
            this = child(ROOT, name, N)
            row = {"bench": "markov_tail", "example": name, "N": N, "this_s": this["seconds"]}
            shown = f"{'-':>9} {1e3 * this['seconds']:9.1f} {'-':>6} {'-':>12}"
            if baseline:
                base = child(trees["baseline"], name, N)
                diff = max(difference(this[k], base[k]) for k in ("udp", "tcp", "plan"))
                ratio = base["seconds"] / this["seconds"]
                row.update(baseline_s=base["seconds"], ratio=ratio, max_relative_difference=diff)
                shown = f"{1e3 * base['seconds']:9.1f} {1e3 * this['seconds']:9.1f} {ratio:6.1f} {diff:12.1e}"
            print(f"   {name:>16} {N:>6} {shown}" + ("" if isinstance(this["udp"], dict) else f"  ({this['udp']})"))
            rows.append(row)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--baseline", help="a checkout of the baseline tree (default: this tree's times alone)")
    parser.add_argument("--quick", action="store_true", help="N = 500 and 8000 only")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows: list[dict] = []
    markov_tail(args.baseline, rows, args.quick)
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
