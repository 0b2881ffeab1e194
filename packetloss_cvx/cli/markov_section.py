"""The Gilbert–Elliott part of ``packetloss-cvx solve FILE``: per protocol, the exact minimiser of the
expected cost under the chain (closed form, with its QP twin), and what the plug-in law loses."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..costs import closed_form
from ..errors import NumericalError, ResourceError
from ..markov import markov_solution, mean_square_radius
from ..model import System

__all__ = ["markov_section"]


def markov_section(system: System, protocols: tuple[str, ...], qp: bool) -> tuple[dict[str, Any], list[str]]:
    """``(data, lines)`` for a system with a Markov channel: JSON under "markov" and the text lines.

    Per protocol: :func:`~packetloss_cvx.markov.markov_solution`, and the mean-square radius of the loop
    u = -K x behind the chain (a Markov jump linear system) for the plug-in and the exact receding-horizon
    gains, both computed at the file's belief.

    A disagreement of the QP with the closed form (CrossCheckError) propagates; a QP beyond the
    memory budget or the solver's range is reported as skipped.
    """
    ch = system.channel
    data: dict[str, Any] = {"channel": ch.to_dict(), "belief": ch.initial_belief.tolist(),
                            "correlation": ch.correlation.tolist(), "mean_rate": ch.mean_rate.tolist()}
    lines = [f"  Gilbert-Elliott channel: p = {np.round(ch.p, 6).tolist()}, r = {np.round(ch.r, 6).tolist()}, "
             f"P(good) now = {np.round(ch.initial_belief, 6).tolist()}, lambda = 1 - p - r = "
             f"{np.round(ch.correlation, 6).tolist()}; the laws above are the plug-in laws (mu_t from the chain)"]
    for protocol in protocols:
        skipped = None
        try:
            res = markov_solution(system, protocol, qp=qp)
        except (NumericalError, ResourceError) as err:
            if not qp:
                raise
            res, skipped = markov_solution(system, protocol, qp=False), str(err)
        entry = res.to_dict()
        radii = {"plug_in": mean_square_radius(system.A, system.B, ch, closed_form(system, protocol).gain),
                 "exact": mean_square_radius(system.A, system.B, ch, res.exact.gain)}
        entry["mean_square_radius"] = radii
        line = (f"  {protocol.upper()}-like exact: J* = {res.exact.cost:.10g} ({res.exact.method}); plug-in law "
                f"{res.plugin_cost:.10g} ({100 * res.relative_loss:+.4f}%); E[cost] of the plug-in plan "
                f"{res.plan_expected_cost:.10g}")
        if skipped is not None:
            entry["qp"] = {"status": "skipped", "reason": skipped}
            line += f"; QP skipped: {skipped}"
        elif res.qp is not None:
            check = res.qp.cross_check
            line += (f"; QP {res.qp.status}, J = {res.qp.cost:.10g}, max|Vbar dU| = {check.max_input_diff:.2e}, "
                     f"rel dJ = {check.cost_rel_diff:.2e}")
        data[protocol] = entry
        lines.append(line)
        lines.append(f"    u = -K x behind the chain (mean-square radius of the switched loop): plug-in "
                     f"{radii['plug_in']:.6g}{'' if radii['plug_in'] < 1 else ' (not stable)'}, exact "
                     f"{radii['exact']:.6g}{'' if radii['exact'] < 1 else ' (not stable)'}")
    return data, lines
