"""``--actuator``: what each law's loop costs when the actuator zeroes, holds or plays the buffered plan on a loss
(exact radius and cost, closedloop.actuator), as ``solve`` prints it per protocol."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..closedloop.actuator import Actuator, compare_actuators, parse_actuators
from ..closedloop.actuator_design import actuator_dp, check_protocol, design_modes
from ..closedloop.actuator_region import MAX_CERTIFIED_ROWS, actuator_critical, actuator_membership
from ..errors import BudgetError, InputError, NumericalError
from ..model.system import System, loop_weights
from ..montecarlo.actuator import simulate_actuator
from ..montecarlo.simulate import law_gains
from . import format as fmt

__all__ = ["actuator_entry", "actuator_strategies", "critical_section", "design_section", "membership_section",
           "simulate_actuator_section"]


def actuator_strategies(text: str | None, system: System, protocol: str = "tcp") -> tuple[Actuator, ...]:
    """The strategies ``--actuator`` names (none without it), checked before any work, each with its optimal law
    runnable under ``protocol`` (closedloop.actuator_design.check_protocol: UDP-like, zero on Bernoulli links, and
    hold without noise and with B of full column rank).

    Raises
    ------
    InputError
        Field ``--actuator``, one line naming what is allowed.
    UnobservedModeError
        Field ``--actuator``, one line: a strategy whose optimal law a UDP-like controller cannot run, why, and what
        to use instead.

    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> [str(a) for a in actuator_strategies("all", s)], actuator_strategies(None, s)
    (['zero', 'hold', 'buffer:3'], ())
    """
    if text is None:
        return ()
    try:
        strategies = parse_actuators(text, system.horizon)
        for strategy in strategies:
            check_protocol(system, strategy, protocol)
    except InputError as err:
        raise err.renamed("--actuator") from None
    return strategies


def actuator_entry(system: System, gain: np.ndarray, strategies: tuple[Actuator, ...],
                   steps: int) -> tuple[dict[str, Any], list[str]]:
    """The JSON entry (``steps`` and per strategy ``radius``, ``stable``, ``cost``, ``reason``) and the text lines of
    `compare_actuators` for the law ``u = -K x`` (its loop's one stage weight: `loop_weights`). A cost that
    overflows the double range is None with its ``cost_reason``."""
    loop_weights(system, "cost.state_weights")
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
        if np.isfinite(row["cost"]):
            cost = f"exact loop cost over {steps} steps from x0 {fmt.num(row['cost'])}"
        else:
            row["cost"], row["cost_reason"] = None, (
                f"not computed: the loop's second moments over {steps} steps exceed the double range (about "
                "1.8e308, an overflow, not a value); use fewer steps or a law that stabilises the loop")
            cost = f"exact loop cost over {steps} steps from x0 {row['cost_reason']}"
        lines.append(f"{name}: {verdict}; {cost}")
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
            spread = "" if row.get("stderr_reason") else f" +- {fmt.num(row['stderr'], 3)}"
            z = "" if row.get("stderr_reason") else f" (z = {fmt.num(row['z'], 3)})"
            lines.append(f"    {label}, {strategy}: mean loop stage cost sampled {fmt.num(row['mean_stage_cost'])}"
                         f"{spread}, exact {fmt.num(row['exact_stage_cost'])}{z}; {verdict}")
            if row.get("stderr_reason"):
                lines.append(f"      ({row['stderr_reason']})")
    return data, lines


def _critical_row(system: System, strategy: Actuator, direction: list[float] | None,
                  tol: float) -> tuple[dict[str, Any], str]:
    """One strategy's critical point along the ray (closedloop.actuator_region.actuator_critical): its dict and
    a text fragment saying which ends are proved, with the point's note (the JSON's ``note``: how far the proved
    lower end lies below the float crossing, or why it is not proved) where it has one."""
    modes = design_modes(system.A, system.B, np.ones(system.m) if system.channel is None else system.channel,
                         strategy)
    rows = modes.modes * modes.A.shape[-1] ** 2
    if rows > MAX_CERTIFIED_ROWS:
        reason = (f"{strategy}'s information map has {rows} rows, beyond the {MAX_CERTIFIED_ROWS} of an exact "
                  "certificate: use a shorter buffer")
        return {"reason": reason}, f"critical mu not computed ({reason})"
    try:
        point = actuator_critical(system, strategy, direction, tol)
    except InputError as err:
        if err.field != "channel":
            raise
        reason = err.detail
        return {"reason": reason}, f"critical mean rate not computed ({reason})"
    except NumericalError as err:
        return {"reason": str(err)}, f"critical mu undecided ({err})"
    row = point.to_dict()
    row["basis"] = "mean rate of the chain (burstiness kept)" if system.channel is not None else "delivery probability"
    if not np.isfinite(point.t):
        return row, "not stabilisable even at the ray's end"
    lower = "proved unstable" if point.outside is not None and point.outside.verdict == "unstable" else \
        "an estimate (not certified)"
    upper = "proved stable" if point.inside is not None and point.inside.verdict == "stable" else \
        f"undecided ({point.inside.reason if point.inside is not None else 'no membership'})"
    what = "critical mean rate" if system.channel is not None else "critical mu"
    note = f"; {point.note}" if point.note else ""      # where the lower end was stepped below the float crossing
    return row, (f"{what} {fmt.numbers(point.mu)} (t in [{fmt.num(point.lower, 8)}, {fmt.num(point.t, 8)}]: "
                 f"upper end {upper}, lower end {lower}{note})")


def critical_section(system: System, strategies: tuple[Actuator, ...], direction: list[float] | None,
                     tol: float) -> tuple[dict[str, Any], list[str]]:
    """``region --actuator``: per strategy its critical point along the ray (JSON per strategy name) and a line."""
    data: dict[str, Any] = {}
    lines = ["actuator on a loss: the channels some TCP-like law of each strategy stabilises, along the ray"]
    for strategy in strategies:
        data[str(strategy)], text = _critical_row(system, strategy, direction, tol)
        lines.append(f"  {strategy}: {text}")
    return data, lines


def _links_cell(row: dict[str, Any] | None) -> str:
    """The ``compare --target`` columns of one strategy: beta'mu and mu* of its cheapest links, or the verdict."""
    if row is None:
        return ""
    if row["verdict"] == "reachable":
        star = "" if row["status"] == "optimal" else "*"
        return f" {fmt.num(row['communication_cost']) + star:>12} {fmt.numbers(row['mu']):<22}"
    if row["verdict"] == "unreachable":
        least = "none" if row.get("least_cost") is None else fmt.num(row["least_cost"])
        return f" {'unreachable':>12} {'(least ' + least + ')':<22}"
    return f" {row['verdict']:>12} {'-':<22}"


def _links_notes(name: str, row: dict[str, Any] | None) -> list[str]:
    """The lines under the table that say why a strategy's links are not reported, or that a gap is uncertified."""
    if row is None:
        return []
    if row["verdict"] == "reachable":
        note = "" if row["stabilisable"] else f"; stability of mu*: {row['stability_note']}"
        uncertified = f" (gap {fmt.num(row['gap'], 3)} not certified)" if row["status"] != "optimal" else ""
        return [f"  {name}: cheapest links{uncertified}{note}"] if uncertified or note else []
    if row["verdict"] == "unreachable":
        why = "" if row.get("least_cost") is not None else f" ({row.get('least_cost_reason', '')})"
        return [f"  {name}: cost target unreachable (proved); least cost at mu = "
                f"{fmt.numbers(row['least_cost_mu'])}: {fmt.num(row['least_cost']) if why == '' else 'none'}{why}"]
    return [f"  {name}: cheapest links {row['verdict']}: {row['reason']}"]


def design_section(system: System, strategies: tuple[Actuator, ...], direction: list[float] | None,
                   tol: float, links: dict[str, dict[str, Any]] | None = None) -> tuple[dict[str, Any], list[str]]:
    """``compare``: per strategy the optimal TCP-like law's (closedloop.actuator_design.actuator_dp) mean-square
    radius, average stage cost under the noise and total noise-free cost from x0, and the strategy's critical
    point along the ray; with ``links`` (allocation.api.cheapest_links per strategy name) the cheapest links for the
    cost target, beta'mu and mu* (JSON ``links``); JSON per strategy name and the text table. The costs need the
    loop's one stage weight (`loop_weights`: time-varying weights refused)."""
    loop_weights(system, "cost.state_weights")
    data: dict[str, Any] = {}
    w = max([11, *(len(str(strategy)) for strategy in strategies)])     # buffer:L:hold is wider than 11
    extra = "" if links is None else f" {'beta' + chr(39) + 'mu':>12} {'mu*':<22}"
    # the costs are the optimal law's in its loop (basis loop): the average stage cost, the noise-free cost from x0
    lines = [f"{'strategy':<{w}} {'radius':>12} {'avg cost [loop]':>15} {'x0 cost [loop]':>14}{extra}  critical mu"]
    notes: list[str] = []
    for strategy in strategies:
        link = None if links is None else links[str(strategy)]
        row: dict[str, Any] = {}
        try:
            design = actuator_dp(system, strategy)
            row.update(radius=design.radius, average_stage_cost=design.cost, initial_cost=design.initial,
                       modes=design.modes.modes)
            numbers = (f"{fmt.num(design.radius):>12} {fmt.num(design.cost):>15} "
                       f"{fmt.num(design.initial):>14}")
        except NumericalError as err:
            row.update(radius=None, average_stage_cost=None, initial_cost=None, reason=str(err))
            numbers = f"{'no law':>12} {'-':>15} {'-':>14}"
        except BudgetError as err:      # refused before any work: the others are still compared
            row.update(radius=None, average_stage_cost=None, initial_cost=None, reason=str(err),
                       critical=None)
            if link is not None:
                row["links"] = link
            data[str(strategy)] = row
            lines.append(f"{str(strategy):<{w}} {'refused':>12} {'-':>15} {'-':>14}{_links_cell(link)}  -")
            lines.append(f"  {strategy}: not computed: {err}")
            if link is not None and link.get("reason") != str(err):
                notes += _links_notes(str(strategy), link)
            continue
        notes += _links_notes(str(strategy), link)
        row["critical"], text = _critical_row(system, strategy, direction, tol)
        if link is not None:
            row["links"] = link
        data[str(strategy)] = row
        lines.append(f"{str(strategy):<{w}} {numbers}{_links_cell(link)}  {text}")
        if "reason" in row:
            lines.append(f"  {strategy}: no optimal law: {row['reason']}")
    return data, lines + notes


def membership_section(system: System, strategies: tuple[Actuator, ...], mu: np.ndarray,
                       protocol: str = "tcp") -> tuple[dict[str, Any], list[tuple[str, str]]]:
    """``allocate --actuator``: is the allocation mu* stabilisable under each strategy by a law the ``protocol``'s
    controller can run (closedloop.actuator_region.actuator_membership)? JSON per strategy (verdict, radius,
    reason) and text rows."""
    data: dict[str, Any] = {}
    rows = []
    label = f"{protocol.upper()}-like"
    for strategy in strategies:
        found = actuator_membership(system, strategy, mu, protocol)
        radius = found.radius if np.isfinite(found.radius) else None
        data[str(strategy)] = {"verdict": found.verdict, "radius": radius, "reason": found.reason}
        text = {"stable": f"stabilisable (a {label} law proved mean-square stable)",
                "unstable": f"NOT stabilisable by any {label} law (proved)"}.get(found.verdict,
                                                                              f"undecided ({found.reason})")
        rows.append((f"{strategy} at mu*", text))
    return data, rows
