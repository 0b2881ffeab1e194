"""The closed-loop mode engine (``markov.modes``) against a baseline checkout: the Bernoulli second-moment paths
(the engine at one mode) and the chains' (the engine at M modes), interleaved round by round in one process.

    OPENBLAS_NUM_THREADS=1 python benchmarks/mode_engine.py --baseline /path/to/baseline/checkout [--rounds 7]

Each round times every case with the baseline's functions and this checkout's, one after the other, the first of
the two alternating from round to round (CPU time,
``time.process_time``, every packetloss_cvx module reloaded from the checkout before its turn); prints the medians in
milliseconds per call, the ratio this / baseline (median and range of the per-round ratios) and the largest
relative change of the answers (elementwise, over every float the case returns).
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _load(root: Path) -> dict:
    """The modules of the checkout at ``root`` (every packetloss_cvx module reloaded from there)."""
    for name in [k for k in sys.modules if k == "packetloss_cvx" or k.startswith("packetloss_cvx.")]:
        del sys.modules[name]
    sys.path.insert(0, str(root))
    try:
        return {"stability": importlib.import_module("packetloss_cvx.closedloop.stability"),
                "moments": importlib.import_module("packetloss_cvx.closedloop.moments"),
                "riccati": importlib.import_module("packetloss_cvx.closedloop.riccati"),
                "certificates": importlib.import_module("packetloss_cvx.closedloop.certificates"),
                "mjls": importlib.import_module("packetloss_cvx.closedloop.mjls"),
                "io": importlib.import_module("packetloss_cvx.model.files"),
                "channel": importlib.import_module("packetloss_cvx.model.channel")}
    finally:
        sys.path.pop(0)


def _floats(value) -> np.ndarray:
    """Every float of an answer, flattened (results by their numeric fields)."""
    if isinstance(value, tuple | list):
        return np.concatenate([_floats(v) for v in value]) if value else np.zeros(0)
    if hasattr(value, "__dataclass_fields__"):
        return _floats([getattr(value, f) for f in value.__dataclass_fields__
                        if isinstance(getattr(value, f), float | int | np.ndarray) and not isinstance(
                            getattr(value, f), bool)])
    return np.atleast_1d(np.asarray(value, dtype=float)).ravel()


def _law(rng: np.random.Generator, n: int, m: int, radius: float = 0.9):
    A = rng.normal(size=(n, n))
    A *= 1.2 / max(abs(np.linalg.eigvals(A)))
    B, K = rng.normal(size=(n, m)), rng.normal(size=(m, n)) * 0.05
    return A, B, K, rng.uniform(0.6, 1.0, m)


def _cases(mod: dict) -> list[tuple[str, object]]:
    """(label, zero-argument call) per case, built from ``mod``'s functions with the same seeded data."""
    st, mo, ri, ce, mj = mod["stability"], mod["moments"], mod["riccati"], mod["certificates"], mod["mjls"]
    ex, GE = mod["io"].load_example, mod["channel"].GilbertElliott
    rng = np.random.default_rng(2024)
    small, mid, big = _law(rng, 4, 2), _law(rng, 25, 3), _law(rng, 40, 3)
    two, pend = ex("two_actuator"), ex("pendulum")
    dp_two, dp_pend = ri.dp_riccati(two), ri.dp_riccati(pend)
    gains_tv = np.stack([dp_pend.gain * (1 + 0.01 * t) for t in range(200)])
    S = np.eye(4)
    step = st.second_moment_step(*small)
    out = [
        ("bernoulli radius n=4 (dense)", lambda: st.mean_square_radius(*small)),
        ("bernoulli radius n=25 (krylov)", lambda: st.mean_square_radius(*mid)),
        ("bernoulli radius n=40 (krylov)", lambda: st.mean_square_radius(*big)),
        ("bernoulli step n=4 x1000", lambda: [step(S) for _ in range(1000)][-1]),
        ("finite_horizon_costs pendulum N=1000", lambda: mo.finite_horizon_costs(pend, dp_pend.gain, 1000)),
        ("finite_horizon_costs time-varying N=200", lambda: mo.finite_horizon_costs(pend, gains_tv, 200)),
        ("closed_loop two_actuator", lambda: mo.closed_loop(two, dp_two.gain)),
        ("dp_riccati two_actuator", lambda: ri.dp_riccati(two)),
        ("dp_riccati pendulum", lambda: ri.dp_riccati(pend)),
        ("outside_proved pendulum (exact)", lambda: ce.outside_proved(pend.A, pend.B, pend.mu_schedule[0],
                                                                      dp_pend.cost_to_go, 0.5)),
        ("law_proved_stable pendulum", lambda: ce.law_proved_stable(pend.A, pend.B, dp_pend.gain,
                                                                    pend.mu_schedule[0])),
    ]
    ch2 = GE(p=[0.1, 0.2], r=[0.4, 0.5], h_good=[0.95, 0.9], h_bad=[0.1, 0.2])
    rng = np.random.default_rng(7)
    A3, B3 = rng.normal(size=(3, 3)) * 0.5, rng.normal(size=(3, 2))
    K3 = rng.normal(size=(4, 2, 3)) * 0.1
    A12, B12 = rng.normal(size=(12, 12)), rng.normal(size=(12, 2))
    A12 *= 0.95 / max(abs(np.linalg.eigvals(A12)))
    K12 = rng.normal(size=(4, 2, 12)) * 0.05
    chain_sys = two.with_channel(ch2) if hasattr(two, "with_channel") else None
    out += [
        ("chain operator n=3 M=4", lambda: mj.second_moment_operator(A3, B3, ch2, K3)),
        ("chain radius n=3 M=4 current", lambda: mj.mean_square_radius(A3, B3, ch2, K3)),
        ("chain radius n=3 M=4 next", lambda: mj.mean_square_radius(A3, B3, ch2, K3, "next")),
        ("chain radius n=12 M=4 (krylov) current", lambda: mj.mean_square_radius(A12, B12, ch2, K12)),
        ("chain radius n=12 M=4 (krylov) next", lambda: mj.mean_square_radius(A12, B12, ch2, K12, "next")),
    ]
    if chain_sys is not None:
        riccati = mj.coupled_riccati(chain_sys)
        out += [
            ("coupled_riccati two_actuator GE", lambda: mj.coupled_riccati(chain_sys)),
            ("jump_law_stage_costs current N=500", lambda: mj.jump_law_stage_costs(chain_sys, riccati.gains, 500)),
            ("jump_law_stage_costs next N=500", lambda: mj.jump_law_stage_costs(
                chain_sys, riccati.gains, 500, "next", first_gain=riccati.gains[0])),
        ]
    return out


def _time(call, repeat: int) -> tuple[float, object]:
    start = time.process_time()
    for _ in range(repeat):
        value = call()
    return (time.process_time() - start) / repeat, value


def side_by_side(cases, description: str, argv: list[str] | None = None) -> None:
    """The harness: ``cases(modules)`` (the dict `_load` returns -> [(label, call), ...]) timed for the checkout
    ``--baseline`` and this one, interleaved round by round (``--rounds``), each tree first every other round; prints
    per case the medians in milliseconds per call, the ratio this / baseline (median and range of the per-round
    ratios) and the largest relative change of the answers (`_floats`). benchmarks/riccati_engine.py runs its own
    cases through it."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--baseline", type=Path, required=True)
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args(argv)
    trees = {"base": args.baseline.resolve(), "this": ROOT}
    times: dict[str, dict[str, list[float]]] = {}
    answers: dict[str, dict[str, np.ndarray]] = {"base": {}, "this": {}}
    labels: list[str] = []
    for round_ in range(args.rounds):
        for tree, root in sorted(trees.items(), reverse=bool(round_ % 2)):      # each goes first every other round
            found = cases(_load(root))
            labels = labels or [label for label, _ in found]
            for label, call in found:
                call()                                                     # warm (lazy imports, caches)
                first, _ = _time(call, 1)
                seconds, value = _time(call, max(1, min(50, int(0.05 / max(first, 1e-6)))))
                times.setdefault(label, {"base": [], "this": []})[tree].append(seconds)
                answers[tree][label] = _floats(value)
    print(f"{'case':44s} {'base ms':>9s} {'this ms':>9s} {'this/base':>9s} {'range':>13s} {'max rel change':>15s}")
    for label in labels:
        base, this = times[label]["base"], times[label]["this"]
        ratios = [t / b for t, b in zip(this, base, strict=True)]
        a, b = answers["base"][label], answers["this"][label]
        with np.errstate(divide="ignore", invalid="ignore"):
            change = float(np.max(np.abs(b - a) / np.maximum(np.abs(a), np.finfo(float).tiny), initial=0.0)) \
                if a.shape == b.shape else float("nan")
        print(f"{label:44s} {1e3 * statistics.median(base):9.3f} {1e3 * statistics.median(this):9.3f} "
              f"{statistics.median(ratios):9.3f} {min(ratios):6.3f}-{max(ratios):6.3f} {change:15.2e}")


def main() -> None:
    side_by_side(_cases, __doc__.splitlines()[0])


if __name__ == "__main__":
    main()
