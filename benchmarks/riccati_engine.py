"""The DP solvers (``closedloop.riccati.mode_riccati``: dp_riccati at one mode, coupled_riccati behind a chain,
dp_finite_horizon) against a baseline checkout, interleaved round by round in one process.

    OPENBLAS_NUM_THREADS=1 python benchmarks/riccati_engine.py --baseline /path/to/baseline/checkout [--rounds 7]

The harness of ``benchmarks/mode_engine.py`` (CPU time, every packetloss_cvx module reloaded from the checkout before
its turn, the first of the two alternating from round to round): medians in milliseconds per call, the ratio
this / baseline (median and range of the per-round ratios) and the largest relative change of the answers
(elementwise over every float the case returns: for the Bernoulli cases the bits kept, for the chains how far the
answer moved from the stopped value iteration to the fixed point).
"""

from __future__ import annotations

import sys

import numpy as np
from mode_engine import side_by_side


def _chain(mj, system) -> tuple[np.ndarray, ...]:
    """coupled_riccati's P, radius and the gain rows of the actuators that can deliver (the others' rows are a
    convention that changed: 0 before, the h -> 0+ limit now)."""
    res = mj.coupled_riccati(system)
    h = mj.mode_chain(system.channel)[2]
    return res.cost_matrices, np.array([res.spectral_radius]), res.gains[h > 0]


def _cases(mod: dict) -> list[tuple[str, object]]:
    """(label, zero-argument call) per case, built from ``mod``'s functions with the same data."""
    ri, mj, files, GE = mod["riccati"], mod["mjls"], mod["io"], mod["channel"].GilbertElliott
    System = sys.modules["packetloss_cvx"].System                  # the checkout's, loaded by _load
    out = []
    for name in files.example_names():
        s = files.load_example(name)
        if s.channel is None:
            out.append((f"dp_riccati {name}", lambda s=s: ri.dp_riccati(s)))
        else:
            out.append((f"coupled_riccati {name}", lambda s=s: _chain(mj, s)))
    two, pend = files.load_example("two_actuator"), files.load_example("pendulum")
    proved = ri.dp_riccati(two, [0.9, 0.9]).gain
    jordan = System(A=1.001 * np.eye(4) + np.eye(4, k=1), B=np.eye(4)[:, 3:], horizon=2, state_weight=[1.0] * 4,
                    input_weight=[1.0], mu=[0.0186], x0=[1.0] * 4)
    below = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])

    def denied():
        try:
            ri.dp_riccati(below)
        except mod["riccati"].NumericalError as err:                 # the proof's error is the answer
            return float(str(err).startswith(mod["riccati"].NO_SOLUTION))
        return -1.0

    out += [
        ("dp_riccati two_actuator mu=(0.9, 0)", lambda: ri.dp_riccati(two, [0.9, 0.0])),
        ("dp_riccati two_actuator from a gain", lambda: ri.dp_riccati(two, [0.9, 0.9], gain=proved)),
        ("dp_riccati Jordan mu=0.0186 (||P|| 2e16)", lambda: ri.dp_riccati(jordan)),
        ("dp_riccati denied by proof (a=2, mu=0.5)", denied),
        ("dp_finite_horizon pendulum N=1000", lambda: ri.dp_finite_horizon(pend, 1000)),
    ]
    ch2 = GE(p=[0.1, 0.2], r=[0.4, 0.5], h_good=[0.95, 0.9], h_bad=[0.1, 0.2])
    gilbert = GE(p=[0.1, 0.2], r=[0.4, 0.5])
    scalar = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                    channel=GE(p=[0.0], r=[0.5]))
    out += [
        ("coupled_riccati two_actuator GE fractional", lambda: _chain(mj, two.with_channel(ch2))),
        ("coupled_riccati two_actuator Gilbert", lambda: _chain(mj, two.with_channel(gilbert))),
        ("coupled_riccati pendulum Gilbert", lambda: _chain(mj, pend.with_channel(GE(p=[0.1], r=[0.6])))),
        ("coupled_riccati scalar p=0 r=0.5", lambda: _chain(mj, scalar)),
    ]
    return out


def main() -> None:
    side_by_side(_cases, __doc__.splitlines()[0])


if __name__ == "__main__":
    main()
