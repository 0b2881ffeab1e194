"""The Markov-channel (Gilbert–Elliott or k-state) part of ``packetloss-cvx solve FILE``: per protocol, the exact
minimiser of the
expected cost under the chain (closed form, with its QP twin), and what the plug-in law loses."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..closedloop.chain_dp import chain_attainable
from ..closedloop.mjls import mean_square_radius
from ..closedloop.stability import is_mean_square_stable
from ..errors import BudgetError, InputError, NumericalError, ResourceError
from ..lq.costs import closed_form
from ..model.channel import GE_MODEL
from ..model.system import System
from ..qp.markov_solution import markov_solution
from .common import CHAIN_BASIS

__all__ = ["PRIOR_MEAN_BASIS", "attainable_entry", "markov_section"]

#: The basis label of the paper's TCP-like cost behind a chain: its formula at the chain's predicted (prior-mean)
#: delivery rates mu_t, which no law with acknowledgements attains.
PRIOR_MEAN_BASIS = "paper, prior-mean rates"


def attainable_entry(system: System) -> tuple[dict[str, Any], str]:
    """The TCP-like attainable cost behind the system's chain for ``solve``: ``({"basis": "attainable", "cost",
    "lower", "upper", "exact", "note"}, text)``, closedloop.chain_dp.chain_attainable (exact, or the two bounds
    beyond its budget); a refusal or a numerical failure gives cost None and the reason, never a number.
    O(`chain_attainable`).

    >>> from packetloss_cvx.model.files import load_example
    >>> data, text = attainable_entry(load_example("pendulum_bursty"))
    >>> round(data["cost"], 1), data["exact"], text.split(" (")[0]
    (10668.7, True, 'attainable: J = 10668.66352')
    """
    entry: dict[str, Any] = {"basis": "attainable", "cost": None, "lower": None, "upper": None, "exact": False}
    if system.sensor is not None:
        entry["note"] = ("not computed with lossy sensor links (the DP with acknowledgements assumes the state is "
                         "measured)")
        return entry, f"attainable: {entry['note']}"
    try:
        found = chain_attainable(system)
    except (BudgetError, NumericalError) as err:
        entry["note"] = f"not computed: {err}"
        return entry, f"attainable: not computed ({err})"
    entry.update(cost=found.cost, lower=found.lower, upper=found.upper, exact=found.cost is not None,
                 note=found.note)
    if found.cost is not None:
        return entry, (f"attainable: J = {found.cost:.10g} (the least expected cost of any law with "
                       f"acknowledgements behind the chain; {found.note}) [basis: attainable]")
    return entry, (f"attainable: between {found.lower:.10g} and {found.upper:.10g} ({found.note}) "
                   "[basis: attainable]")


def _percent(loss: float) -> str:
    """The plug-in law's relative loss in words. Below 5e-9 (five times SELF_CHECK_RTOL, the precision
    each cost is checked to) the two costs are not told apart: "equal within 5e-9 relative", not
    "+0.0000%" or "-0.0000%" (a real loss of 4.4e-10 at lambda = 1e-4 is below it); a loss under 0.01 %
    keeps 3 significant digits (a loss of 4.4e-8 read "+0.0000%").

    >>> _percent(1e-12), _percent(4.36e-8), _percent(-2e-6), _percent(0.078959)
    ('equal within 5e-9 relative', '+4.36e-06%', '-0.0002%', '+7.8959%')
    """
    if abs(loss) < 5e-9:
        return "equal within 5e-9 relative"
    return f"{100 * loss:+.3g}%" if abs(loss) < 1e-6 else f"{100 * loss:+.4f}%"


def _radius(system: System, gain: np.ndarray) -> tuple[float | None, bool, str]:
    """``(radius, stable, words)`` of u = -K x behind the chain; ``stable`` by the proven rule."""
    try:
        radius = mean_square_radius(system.A, system.B, system.channel, gain)
    except (InputError, NumericalError, ResourceError) as err:      # InputError: more channels than modes allow
        return None, False, f"not computed ({err})"
    stable = is_mean_square_stable(radius)
    verdict = "mean-square stable" if stable else (
        "NOT mean-square stable" if radius >= 1 else "not proved mean-square stable (within 1e-9 of 1)")
    return radius, stable, f"{radius:.6g}, {verdict}"


def markov_section(system: System, protocols: tuple[str, ...], qp: bool) -> tuple[dict[str, Any], list[str]]:
    """``(data, lines)`` for a system with a Markov channel: JSON under "markov" and the text lines.

    Per protocol: `markov_solution`, and the mean-square radius of the loop
    u = -K x behind the chain (a Markov jump linear system) for the plug-in and the exact receding-horizon
    gains, both computed at the file's belief; "stable" only where
    [`is_mean_square_stable`][packetloss_cvx.closedloop.stability.is_mean_square_stable] proves it (a radius not
    computed is reported with its reason, never as stable).

    A disagreement of the QP with the closed form (CrossCheckError) propagates; a QP beyond the
    memory budget or the solver's range is reported as skipped.

    Examples
    --------
    The TCP-like cost holds only the marginals mu_t, so its plug-in law is the exact minimiser under the chain:

    >>> from packetloss_cvx.model.files import load_example
    >>> data, lines = markov_section(load_example("pendulum_bursty"), ("tcp",), qp=False)
    >>> abs(data["tcp"]["relative_loss"]) < 1e-9, sorted(data["tcp"]["stable"]), lines[1].startswith("the laws above")
    (True, ['exact', 'plug_in'], True)
    """
    ch = system.channel
    given_as_rates = ch.form == GE_MODEL             # the file's Gilbert–Elliott table: its parameters and P(good)
    belief = ch.initial_belief[:, 0] if given_as_rates else ch.initial_belief
    data: dict[str, Any] = {"channel": ch.to_dict(), "belief": belief.tolist(),
                            "correlation": ch.correlation.tolist(), "mean_rate": ch.mean_rate.tolist()}
    if not given_as_rates:
        first = (f"{len(ch.sizes)} chain(s) of {list(ch.sizes)} states; state distribution now "
                 f"{[np.round(b[:k], 6).tolist() for b, k in zip(ch.initial_belief, ch.sizes, strict=True)]}; long-run "
                 f"delivery rate {np.round(ch.mean_rate, 6).tolist()}; slowest memory (eigenvalue after 1) "
                 f"{np.round(ch.correlation, 6).tolist()}")
    else:
        first = (f"p = {np.round(ch.p, 6).tolist()} (P(good -> bad)), r = {np.round(ch.r, 6).tolist()} "
                 "(P(bad -> good)), "
                 f"h_good = {np.round(ch.h_good, 6).tolist()}, h_bad = {np.round(ch.h_bad, 6).tolist()}; P(good) now "
                 f"{np.round(belief, 6).tolist()}; burstiness lambda = 1 - p - r = "
                 f"{np.round(ch.correlation, 6).tolist()}")
    lines = [first, "the laws above are the plug-in laws: the paper's laws with the mu_t the chain predicts"]
    for protocol in protocols:
        skipped = None
        try:
            res = markov_solution(system, protocol, qp=qp)
        except (NumericalError, ResourceError) as err:
            if not qp:
                raise
            res, skipped = markov_solution(system, protocol, qp=False), str(err)
        entry = res.to_dict()
        plug_in = _radius(system, closed_form(system.with_mu(system.mu_schedule), protocol).gain)
        exact = _radius(system, res.exact.gain)
        entry["mean_square_radius"] = {"plug_in": plug_in[0], "exact": exact[0]}
        entry["stable"] = {"plug_in": plug_in[1], "exact": exact[1]}
        entry["basis"] = CHAIN_BASIS[protocol]
        line = (f"{protocol.upper()}-like exact: J* = {res.exact.cost:.10g} ({res.exact.method}) [basis: "
                f"{CHAIN_BASIS[protocol]}], the exact minimum; the plug-in law's cost {res.plugin_cost:.10g} [basis: "
                f"realised: its plan's expected cost under the chain] ({_percent(res.relative_loss)})")
        if protocol == "tcp":
            entry["basis"] = PRIOR_MEAN_BASIS
            line = (f"TCP-like exact: J* = {res.exact.cost:.10g} ({res.exact.method}) [basis: {PRIOR_MEAN_BASIS}], "
                    f"the exact minimum of the paper's cost; the plug-in law's cost on the same basis "
                    f"{res.plugin_cost:.10g} "
                    f"({_percent(res.relative_loss)}) (the TCP-like cost holds only the marginals mu_t, so the "
                    "plug-in law is its exact minimiser; no law with acknowledgements attains it: see attainable); "
                    f"E[realised cost] of its plan under the chain {res.plan_expected_cost:.10g}")
        # each cost its own basis: the exact minimum and the QP's on the entry's; the plug-in plan's expected cost
        # under the chain realised; the plug-in law's cost TCP-like the paper's on the prior-mean rates, UDP-like its
        # plan's expected cost under the chain (realised)
        entry["plugin_cost_basis"] = entry["basis"] if protocol == "tcp" else "realised"
        entry["plan_expected_cost_basis"] = "realised"
        entry["exact"]["basis"] = entry["basis"]
        if isinstance(entry.get("qp"), dict) and "cost" in entry["qp"]:
            entry["qp"]["basis"] = entry["basis"]
        if skipped is not None:
            entry["qp"] = {"status": "skipped", "reason": skipped}
            line += f"; QP skipped: {skipped}"
        elif res.qp is not None:
            check = res.qp.cross_check
            line += (f"; QP {res.qp.status}, J = {res.qp.cost:.10g} (same basis), max|Vbar dU| = "
                     f"{check.max_input_diff:.2e}, "
                     f"rel dJ = {check.cost_rel_diff:.2e}")
        data[protocol] = entry
        lines.append(line)
        if protocol == "tcp":
            entry["attainable"], text = attainable_entry(system)
            lines.append(f"  {text}")
        lines.append(f"  u = -K x in a loop over the chain (a Markov jump linear system; mean-square radius): plug-in "
                     f"gain {plug_in[2]}; exact minimiser's gain {exact[2]}")
    return data, lines
