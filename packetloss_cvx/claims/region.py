"""stability-region-paper-systems (the paper leaves it open): where can the paper's systems be stabilised at all, and by
which law? Along the shared channel mu = t (1, ..., 1) each law's critical t (simulation.region_map): the
stabilisable set S (some linear law; the DP law's region) and the paper's TCP-like and UDP-like receding-horizon
laws re-designed at each mu. Every law's region lies in S (a law proved stable where S is certified empty is a
CrossCheckError), so the margin is how much later each paper law starts to stabilise."""

from __future__ import annotations

import numpy as np

from ..model.system import System
from ..results import ClaimResult
from ..studies.region_map import region_map
from .context import Context
from .evaluate import Tally

__all__ = ["STATEMENT", "critical_shared_mu", "stability_region"]

STATEMENT = ("(Not the paper's: its conclusion leaves the region open.) On the paper's systems, over a shared "
             "channel mu = t (1, ..., 1), the paper's TCP-like and UDP-like laws stabilise the loop only where some "
             "linear law does (their regions lie in the stabilisable set S); the note gives each law's critical "
             "shared mu.")

#: the laws compared along the shared channel
LAWS = ("dp", "tcp", "udp")


def critical_shared_mu(system: System) -> dict[str, float]:
    """Each law's critical t along mu = t (1, ..., 1) (inf: not stable even at mu = 1), certified for "dp"
    (a stabilising gain above, an infeasibility certificate below). Time: three bisections of O(log(1/tol))
    memberships or re-designs.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> round(critical_shared_mu(s)["dp"], 5)      # 1 - 1/a^2
    0.75
    """
    found = region_map(system, laws=LAWS, direction=np.ones(system.m))
    return {p.law: float(p.t) for p in found.critical}


def _margin(t: dict[str, float]) -> float:
    """min over the paper's laws of (t_law - t_dp) / t_dp from each law's critical t: >= 0 when their regions lie
    in S along the ray (a law that never stabilises has t = inf: margin 1)."""
    gaps = [1.0 if not np.isfinite(t[law]) else (t[law] - t["dp"]) / max(t["dp"], 1e-12) for law in ("tcp", "udp")]
    return min(gaps)


def stability_region(ctx: Context) -> ClaimResult:
    """The check on the paper's systems (the random cases are not run: three bisections each).

    Examples
    --------
    >>> from packetloss_cvx.claims.context import paper_systems
    >>> r = stability_region(Context(paper=paper_systems(), random=[], seed=0))
    >>> r.verdict, r.checked
    ('holds', 2)
    """
    tally = Tally()
    rows = []
    found: dict[str, dict[str, float]] = {}

    def margin(s: System, name: str) -> float:     # the three bisections once: the margin and the note's row
        found[name] = critical_shared_mu(s)
        return _margin(found[name])

    for name, s in ctx.paper.items():
        tally.run(lambda case, name=name: margin(case, name), s, ctx.label(s))
        try:       # after an error the bisections run again, for the note to name it (as the tally does)
            t = found[name] if name in found else critical_shared_mu(s)
        except ArithmeticError as err:
            rows.append(f"{name}: {type(err).__name__}")
            continue
        rows.append(f"{name}: " + ", ".join(
            f"{law} {'never' if not np.isfinite(t[law]) else f'mu > {t[law]:.5f}'}" for law in LAWS)
            + "".join(f"; {law} needs {t[law] / t['dp']:.2f} times the shared mu S does" for law in ("tcp", "udp")
                      if np.isfinite(t[law]) and t["dp"] > 0))
    note = ("Critical shared mu (bisection to 1e-6 on certified points; dp = the stabilisable set S, a stabilising "
            "gain above and an infeasibility certificate below; tcp / udp = the paper's laws at the system's "
            "horizon, re-designed at each mu; never = not stable even at mu = 1): " + "; ".join(rows) + ". Margin = "
            "min over tcp, udp of (t_law - t_dp) / t_dp (1 where a law never stabilises).")
    return tally.result("stability-region-paper-systems", STATEMENT, note)
