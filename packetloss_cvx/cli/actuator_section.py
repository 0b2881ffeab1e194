"""``--actuator``: what each law's loop costs when the actuator zeroes, holds or plays the buffered plan on a loss
(exact radius and cost, closedloop.actuator), as ``solve`` prints it per protocol."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..closedloop.actuator import Actuator, compare_actuators, parse_actuators
from ..errors import InputError
from ..model.system import System
from ..montecarlo.actuator import simulate_actuator
from ..montecarlo.simulate import law_gains
from . import format as fmt

__all__ = ["actuator_entry", "actuator_strategies", "simulate_actuator_section"]


def actuator_strategies(text: str | None, system: System) -> tuple[Actuator, ...]:
    """The strategies ``--actuator`` names (none without it), checked before any work.

    Raises
    ------
    InputError
        Field ``--actuator``, one line naming what is allowed.

    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> [str(a) for a in actuator_strategies("all", s)], actuator_strategies(None, s)
    (['zero', 'hold', 'buffer:3'], ())
    """
    if text is None:
        return ()
    try:
        return parse_actuators(text, system.horizon)
    except InputError as err:
        raise err.renamed("--actuator") from None


def actuator_entry(system: System, gain: np.ndarray, strategies: tuple[Actuator, ...],
                   steps: int) -> tuple[dict[str, Any], list[str]]:
    """The JSON entry (``steps`` and per strategy ``radius``, ``stable``, ``cost``, ``reason``) and the text lines of
    `compare_actuators` for the law ``u = -K x``."""
    try:
        rows = compare_actuators(system, gain, steps, strategies)
    except InputError as err:
        raise (err.renamed("--actuator") if err.field == "actuator" else err) from None
    lines = []
    for name, row in rows.items():
        radius = row["radius"]
        verdict = (f"radius {fmt.num(radius)}, " + ("mean-square stable" if row["stable"] else
                                                    "NOT mean-square stable")) if np.isfinite(radius) else \
            f"radius not computed ({row['reason']})"
        lines.append(f"{name}: {verdict}; exact loop cost over {steps} steps from x0 {fmt.num(row['cost'])}")
        if not np.isfinite(radius):
            row["radius"] = None
    return {"steps": steps, "basis": "loop", "strategies": rows}, lines


def simulate_actuator_section(system: System, laws: tuple[str, ...], strategies: tuple[Actuator, ...], steps: int,
                              samples: int, seed: int) -> tuple[dict[str, Any], list[str]]:
    """``simulate --closed-loop --actuator``: each law (montecarlo.simulate.law_gains) under each strategy, sampled
    (montecarlo.actuator) beside its exact mean stage cost and radius (closedloop.actuator); JSON per law and
    strategy, and the text lines. A law that does not exist (the DP optimum without a stabilising solution) is
    listed with its reason."""
    data: dict[str, Any] = {}
    lines = [f"  actuator on a loss: each law's loop sampled ({samples} runs, seed {seed}) and exact over {steps} "
             "steps"]
    for law, gain in law_gains(system, laws).items():
        label = "DP optimum" if law == "dp" else f"{law.upper()}-like law"
        if isinstance(gain, str):
            data[law] = {"reason": gain}
            lines.append(f"    {label}: no law: {gain}")
            continue
        data[law] = {}
        for strategy in strategies:
            row = {**simulate_actuator(system, gain, steps, strategy, samples, seed), "basis": "loop"}
            data[law][str(strategy)] = row
            verdict = (("mean-square stable" if row["stable"] else "NOT mean-square stable")
                       + f", radius {fmt.num(row['radius'])}") if row["radius"] is not None else \
                f"radius not computed ({row['reason']})"
            lines.append(f"    {label}, {strategy}: mean loop stage cost sampled {fmt.num(row['mean_stage_cost'])} "
                         f"+- "
                         f"{fmt.num(row['stderr'], 3)}, exact {fmt.num(row['exact_stage_cost'])} (z = "
                         f"{fmt.num(row['z'], 3)}); {verdict}")
    return data, lines
