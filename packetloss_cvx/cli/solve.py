"""``packetloss-cvx solve FILE``: optimal plans, costs and gains, cross-checked by a QP."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..costs import closed_form
from ..errors import NumericalError, ResourceError
from ..io import load_system
from ..qp import solve_qp
from ..results import eigenvalue_pairs
from .common import CommandResult, with_overrides
from .markov_section import markov_section

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
        eig = ", ".join(f"{z.real:.4f}{z.imag:+.4f}j" for z in sol.closed_loop_eigenvalues)
        lines += [line, f"    K = {np.array2string(sol.gain, precision=4)}", f"    eig(A - B K) = {eig}"]
    if system.channel is not None:   # Gilbert-Elliott: the exact minimiser under the chain beside the plug-in laws
        out["markov"], more = markov_section(system, protocols, qp=not args.no_qp)
        lines += more
    return CommandResult(out, "\n".join(lines))
