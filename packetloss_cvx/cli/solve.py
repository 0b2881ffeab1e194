"""``packetloss-cvx solve FILE``: optimal plans, costs and gains, cross-checked by a QP."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..costs import closed_form
from ..errors import NumericalError, ResourceError
from ..io import load_system
from ..model import System
from ..qp import solve_qp
from ..results import eigenvalue_pairs
from ..simulation import is_mean_square_stable, mean_square_radius
from .common import CommandResult, with_overrides

__all__ = ["run"]


def run(args: argparse.Namespace) -> CommandResult:
    """Both protocols' closed forms, each compared with its QP twin (a disagreement raises)."""
    system = with_overrides(load_system(args.file), args)
    protocols = ("tcp", "udp") if args.protocol == "both" else (args.protocol,)
    out: dict[str, Any] = {
        "name": system.name, "n": system.n, "m": system.m, "horizon": system.horizon,
        "mu": system.mu_schedule[0].tolist() if system.is_stationary else system.mu_schedule.tolist(),
    }
    lines = [f"{system.name or args.file}: n={system.n}, m={system.m}, N={system.horizon}"]
    for protocol in protocols:
        sol = closed_form(system, protocol, method=args.method)
        entry: dict[str, Any] = {
            "cost": sol.cost, "inputs": sol.inputs.tolist(), "gain": sol.gain.tolist(),
            "closed_loop_eigenvalues": eigenvalue_pairs(sol.closed_loop_eigenvalues),
            "method": sol.method,
        }
        line = f"  {protocol.upper()}-like: J* = {sol.cost:.10g} ({sol.method})"
        if not args.no_qp:
            try:
                qp = solve_qp(system, protocol, args.formulation, with_gain=False, reference=sol)
            except (NumericalError, ResourceError) as err:   # a disagreement (CrossCheckError) is not caught
                entry["qp"] = {"status": "skipped", "reason": str(err)}
                line += f"; QP cross-check skipped: {err}"
            else:
                check = qp.cross_check
                entry["qp"] = {
                    "status": qp.status, "cost": qp.cost, "solve_time": qp.solve_time,
                    "formulation": qp.method.removeprefix("qp-"),
                    "max_input_diff": check.max_input_diff, "cost_rel_diff": check.cost_rel_diff,
                }
                line += (f"; QP {qp.status}, J = {qp.cost:.10g}, max|Vbar dU| = {check.max_input_diff:.2e}, "
                         f"rel dJ = {check.cost_rel_diff:.2e}")
        out[protocol] = entry
        stability = _stability(system, sol.gain, entry)
        eig = ", ".join(f"{z.real:.4f}{z.imag:+.4f}j" for z in sol.closed_loop_eigenvalues)
        lines += [line, f"    K = {np.array2string(sol.gain, precision=4)}", f"    eig(A - B K) = {eig}", *stability]
    return CommandResult(out, "\n".join(lines))


def _stability(system: System, gain: np.ndarray, entry: dict[str, Any]) -> list[str]:
    """Mean-square stability of the receding-horizon law u = -K x run for ever over the file's channel
    (the first step's mu when the channel is non-stationary); adds its keys to ``entry``, returns text."""
    mu = system.mu_schedule[0]
    note = "" if system.is_stationary else " (first step's mu: the channel is non-stationary)"
    try:
        radius = mean_square_radius(system.A, system.B, gain, mu)
    except NumericalError as err:
        entry.update({"mean_square_spectral_radius": None, "stable": False, "stability_note": str(err)})
        return [f"    closed loop: stability not computed: {err}"]
    stable = is_mean_square_stable(radius)
    entry.update({"mean_square_spectral_radius": radius, "stable": stable})
    if note:
        entry["stability_note"] = note.strip(" ()")
    verdict = ("mean-square stable" if stable else
               "NOT mean-square stable: E[x x'] grows without bound when u = -K x runs in a loop over these losses"
               if radius >= 1 else "not proved mean-square stable (the radius is within 1e-9 of 1)")
    return [f"    closed loop u = -K x over mu = {np.array2string(mu, precision=4)}{note}: {verdict} "
            f"(second-moment spectral radius {radius:.6g})"]
