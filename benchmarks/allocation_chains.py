"""UDP-like allocation behind Markov chains, each channel along its family (allocation/chains.py): Gilbert
channels with their burstiness held, every other chain with its deliveries scaled (docs/mathematics.md §5, the
k-state rule).

    OPENBLAS_NUM_THREADS=1 python benchmarks/allocation_chains.py [--json]

Cases, CPU time (time.process_time), best of 3: pendulum_bursty (a Gilbert channel, burstiness held) at
alpha = 60000; the same file with h_bad = 0.1 (fractional deliveries: scaled); the two-channel N = 4 system of
tests/allocation/test_allocation_chains.py behind a Gilbert channel and a 3-state chain (mixed families), gap 1e-5. Printed:
mu*, the boxes, the time and the method note.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import packetloss_cvx as pl  # noqa: E402
from packetloss_cvx.allocation import allocate  # noqa: E402
from packetloss_cvx.lq.markov_cost import exact_closed_form  # noqa: E402
from packetloss_cvx.model.channel import (
    GilbertElliott,  # noqa: E402
    MarkovChannel,  # noqa: E402
)

THREE = [[0.8, 0.15, 0.05], [0.2, 0.6, 0.2], [0.1, 0.3, 0.6]]


def cases():
    bursty = pl.load_example("pendulum_bursty")
    ch = bursty.channel
    leaky = bursty.with_channel(GilbertElliott(p=ch.p, r=ch.r, h_good=ch.h_good, h_bad=[0.1]))
    mixed = pl.System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[0.0, 1.0], [1.0, 0.3]], horizon=4, state_weight=[1.0, 1.0],
                      input_weight=[0.5, 0.5], x0=[1.0, 1.0],
                      channel=MarkovChannel(transition=[[[0.9, 0.1], [0.3, 0.7]], THREE],
                                            delivery=[[1.0, 0.0], [0.9, 0.5, 0.0]]))
    return [("pendulum_bursty (Gilbert, held)", bursty, 60000.0, [1.0], 1e-4),
            ("pendulum_bursty, h_bad = 0.1 (scaled)", leaky, 60000.0, [1.0], 1e-4),
            ("two channels, Gilbert + 3-state (mixed)", mixed, 1.1 * exact_closed_form(mixed).cost, [1.0, 0.7], 1e-5)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    for name, system, alpha, beta, gap in cases():
        best, out = float("inf"), None
        for _ in range(3):
            start = time.process_time()
            out = allocate(system, "udp", alpha, beta, gap=gap)
            best = min(best, time.process_time() - start)
        rows.append({"case": name, "seconds": best, "mu": out.mu.tolist(), "boxes": out.boxes, "status": out.status,
                     "cost": out.cost, "alpha": alpha, "method": out.method})
        if not args.json:
            print(f"{name}: {best:.3f} s, mu* = {[round(v, 4) for v in out.mu.tolist()]}, {out.boxes} boxes, "
                  f"{out.status}; {out.method}", flush=True)
    if args.json:
        print(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
