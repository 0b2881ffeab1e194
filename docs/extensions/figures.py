"""The figures of docs/figures that no tutorial page draws, each made by the code named here.

    python docs/extensions/figures.py [NAME ...]     # redraw these figures (default: all but reproduce's)
    python docs/extensions/figures.py --reproduce    # also run `packetloss-cvx reproduce` and copy its four

Four come from `packetloss-cvx reproduce` (its results folder; `--reproduce` runs it, about as long as the paper's
figures take) and are copied as they are; the others are drawn here from the API or a command line.
docs/figures/tutorials/ belongs to tutorial_outputs.py. tests/docs/test_docs_figures.py checks that every PNG in
docs/figures is named in `FIGURES`.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
OUT = DOCS / "figures"
#: written by `packetloss-cvx reproduce` under the same name (cli/reproduce.py)
REPRODUCED = ("TCP-log-cost-mixed-mult.png", "UDP-log-cost-mixed-mult.png", "ack-break-even.png",
              "region-two-actuator.png")


def power_pareto(path: Path) -> None:
    """docs/mathematics.md, "The power-cost Pareto curve": two_actuator, mu_i = 1 - exp(-P_i / c_i), c = (1, 2),
    budgets 0-8, every point certified to 1e-4 (the UDP-like curve takes about 20 s)."""
    from packetloss_cvx.allocation.delivery import power_model
    from packetloss_cvx.allocation.power import power_pareto as pareto
    from packetloss_cvx.model.files import load_example
    from packetloss_cvx.plots.figures import plot_power_pareto

    system = load_example("two_actuator")
    model = power_model("exponential", system.m, scale=[1.0, 2.0])
    budgets = [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0]
    curves = {label: [point.to_dict() for point in pareto(system, protocol, model, budgets)]
              for protocol, label in (("tcp", "TCP-like"), ("udp", "UDP-like"))}
    plot_power_pareto(curves, title="two-actuator system, mu_i = 1 - exp(-P_i / c_i), c = (1, 2)", path=path)


def burstiness_map(path: Path) -> None:
    """docs/claims.md, plug-in-markov: the command line the page quotes, its burstiness_map_udp.png."""
    from packetloss_cvx.cli import main

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "map"
        code = main(["sweep", "pendulum_bursty", "--burstiness", "0:0.95:20", "--mean-rate", "0.5:1:26", "--protocol",
                     "udp", "--out", str(out), "-q"])
        if code != 0:
            raise SystemExit(f"the burstiness map's sweep ended with exit {code}")
        shutil.copyfile(out / "burstiness_map_udp.png", path)


def sensor_map(path: Path) -> None:
    """docs/tutorials/lossy-sensors.md, "Cost and stability over (gamma, mu)": pendulum_sensor on a 25 x 25 grid of
    (gamma, mu) scales in (0, 1] (as `region --sensor-grid 25`), the DP law's cost and each law's boundary."""
    import numpy as np

    from packetloss_cvx.model.files import load_example
    from packetloss_cvx.plots.figures import plot_sensor_map
    from packetloss_cvx.sensing.loop import loop_map, loop_verdict

    system = load_example("pendulum_sensor")
    scales = np.linspace(1.0 / 25, 1.0, 25)
    maps = loop_map(system, scales, scales)
    gamma = scales * float(np.max(system.sensor.gamma))
    mu = scales * float(np.max(system.mu))
    stable = {law: np.array([[np.nan if (v := loop_verdict(float(r))) is None else float(v) for r in row]
                             for row in radius]) for law, (radius, _) in maps.items()}
    plot_sensor_map(gamma, mu, maps["dp"][1], stable, path=path,
                    title=r"Pendulum, sensor link $\gamma$ and actuator link $\mu$: where each law on its estimate "
                          "stabilises the loop")


#: every figure of docs/figures (tutorials/ aside) and what makes it
FIGURES: dict[str, Callable[[Path], None] | None] = {
    "power-pareto.png": power_pareto,
    "burstiness-map-pendulum-bursty.png": burstiness_map,
    "pendulum-sensor-map.png": sensor_map,
    **dict.fromkeys(REPRODUCED),        # `packetloss-cvx reproduce`: copied by --reproduce
}


def reproduce() -> None:
    """Run `packetloss-cvx reproduce` into a temporary folder and copy its figures that docs/figures shows."""
    from packetloss_cvx.cli import main

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "results"
        code = main(["reproduce", "--out", str(out), "-q"])
        if code != 0:
            raise SystemExit(f"reproduce ended with exit {code}")
        for name in REPRODUCED:
            shutil.copyfile(out / name, OUT / name)
            print(f"wrote {OUT / name} (reproduce)")


def run(names: list[str]) -> None:
    with_reproduce = "--reproduce" in names
    names = [n for n in names if n != "--reproduce"] or [n for n, make in FIGURES.items() if make is not None]
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise SystemExit(f"unknown figure(s) {', '.join(unknown)}; known: {', '.join(FIGURES)}")
    for name in names:
        make = FIGURES[name]
        if make is None:
            with_reproduce = True
            continue
        make(OUT / name)
        print(f"wrote {OUT / name}")
    if with_reproduce:
        reproduce()


if __name__ == "__main__":
    run(sys.argv[1:])
