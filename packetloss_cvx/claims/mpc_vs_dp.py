"""How far the paper's receding-horizon laws are from the dynamic-programming optimum in closed loop.

Both laws ``u = -K x`` (Theorem 1's first gain) and the DP law run for ever over the system's channel
(stationary cases; stage weights Omega_1 and Psi_0). Exact costs from second moments: a law's cost-to-go
``P_K`` (x0' P_K x0 is its total cost from x0 without noise, tr(P_K Sigma_W) its average stage cost with
noise) against the modified Riccati solution P. No law can beat the DP optimum: ``P_K - P`` is PSD.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..closedloop.moments import closed_loop
from ..closedloop.riccati import NO_SOLUTION, dp_riccati
from ..errors import NumericalError
from ..linalg import frobenius
from ..lq.costs import closed_form
from ..model.system import System
from ..results import ClaimResult, Riccati
from ..threads import blas_limited
from .context import Context, loop_case
from .evaluate import evaluate, resolved
from .ordering import optimal_plan

__all__ = ["mpc_vs_dp", "relative_excess"]

#: P_K - P may be negative by rounding only: this much of ||P||.
PSD_SLACK = 1e-9


def relative_excess(system: System, gain: Callable[[str], np.ndarray] | None = None,
                    solve: Callable[[System], Riccati] = dp_riccati) -> dict[str, float] | None:
    """Each law's exact closed-loop cost over the DP optimum's, minus one, at the system's own x0 and
    Sigma_W (cost ``tr(P (x0 x0' + Sigma_W))``: the total cost from x0 plus the average stage cost);
    ``inf`` for a law that is not mean-square stable; the key ``"psd"``: min eig(P_K - P) / ||P|| over
    the stable laws. None when the channel is non-stationary or no law stabilises (no DP solution).
    ``gain``: protocol -> K (asked only once a DP solution exists) when the caller has them, else closed_form's;
    ``solve``: the DP solver (the audit's `Context.dp`, which keeps each case's for the other claims).
    Time O(n^6) (two moment solves per law) plus the Riccati iteration.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> r = relative_excess(s)   # P = 1 + sqrt 3 solves P = 1 + P - P^2/(2(1 + P)); P_K = 2.75 (TCP-like), 3 (UDP-like)
    >>> bool(np.allclose([r["tcp"], r["udp"]], [2.75 / (1 + 3**0.5) - 1, 3 / (1 + 3**0.5) - 1]))
    True
    """
    if not system.is_stationary:
        return None
    try:
        dp = solve(system)
    except NumericalError as err:
        if str(err).startswith(NO_SOLUTION):
            return None
        raise
    C = np.outer(system.x0, system.x0) + system.noise_cov
    base = float(np.sum(dp.cost_to_go * C))
    scale = resolved(frobenius(dp.cost_to_go), "||P|| of the DP law")
    out: dict[str, float] = {"psd": np.inf}
    for p in ("tcp", "udp"):
        loop = closed_loop(loop_case(system), closed_form(system, p).gain if gain is None else gain(p), p)
        if not loop.stable:
            out[p] = np.inf
            continue
        out["psd"] = min(out["psd"], float(np.linalg.eigvalsh(loop.cost_to_go - dp.cost_to_go).min()) / scale)
        out[p] = float(np.sum(loop.cost_to_go * C)) / base - 1.0 if base > 0 else 0.0
    return out


def _summary(values: list[float]) -> str:
    finite = np.array([v for v in values if np.isfinite(v)])
    unstable = len(values) - finite.size
    if not finite.size:
        return f"not mean-square stable in all {unstable} cases"
    return (f"median {100 * np.median(finite):.3g} %, 90th percentile {100 * np.quantile(finite, 0.9):.3g} %, "
            f"max {100 * finite.max():.3g} % above the optimum; not mean-square stable (infinite cost) in "
            f"{unstable} of the {len(values)} cases (the DP law is stable in all)")


@blas_limited
def mpc_vs_dp(ctx: Context) -> ClaimResult:
    """The DP optimum is no worse than either receding-horizon law; the note says how far each is.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> r = mpc_vs_dp(Context(paper={}, random=[s], seed=0))   # min eig(P_K - P) / ||P|| = 2.75 / (1 + sqrt 3) - 1
    >>> r.verdict, bool(np.isclose(r.worst, 2.75 / (1 + 3**0.5) - 1))
    ('holds', True)
    """
    found: dict[int, dict[str, float] | None | Exception] = {}
    for s in ctx.cases:
        try:
            found[id(s)] = relative_excess(s, lambda p, s=s: optimal_plan(ctx, s, p, case=True).gain, ctx.dp)
        except (ArithmeticError, ValueError) as err:
            found[id(s)] = err

    def margin(s: System) -> float | None:
        result = found[id(s)] if id(s) in found else relative_excess(s)
        if isinstance(result, Exception):
            raise result
        if result is None:
            return None
        return min(result["psd"], 1.0) + PSD_SLACK   # >= 0: P_K - P is PSD for every stable law

    ok = [r for r in found.values() if isinstance(r, dict)]
    paper = []
    for name, s in ctx.paper.items():
        r = found[id(s)]
        if isinstance(r, dict):
            paper.append(f"{name}: TCP-like {_pct(r['tcp'])}, UDP-like {_pct(r['udp'])}")
    note = ("Exact closed-loop costs (second moments, no sampling) of u = -K x for each protocol's receding-horizon "
            "gain against the DP optimum (modified Riccati equation), stationary channels, weights Omega_1 and "
            "Psi_0; a case without any stabilising law (no DP solution) or with a non-stationary channel does not "
            "apply. Margin = min eig(P_K - P) / ||P|| + 1e-9 over the stable laws (>= 0: no law beats DP for any "
            "x0 or noise). Distance = tr(P_K C) / tr(P C) - 1 with C = x0 x0' + Sigma_W. "
            + ("; ".join(paper) + ". " if paper else "")
            + f"Over the {len(ok)} cases: TCP-like {_summary([r['tcp'] for r in ok])}; "
            f"UDP-like {_summary([r['udp'] for r in ok])}.")
    return evaluate("mpc-vs-dp", ctx, ctx.cases, margin, note, shrinkable=False)


def _pct(value: float) -> str:
    return f"{100 * value:.3g} % above the optimum" if np.isfinite(value) else "not mean-square stable"
