"""§V: the paper's case studies — Tables I–II (closed-loop eigenvalues) and the pendulum's
maximiser of the cost difference — recomputed under every convention tried."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from ..lq import analysis as an
from ..lq import difference
from ..lq.costs import closed_form
from ..lq.prediction import prediction
from ..model.files import system_from_dict
from ..model.system import System
from ..results import ClaimResult
from .context import Context
from .paper import PENDULUM_NU_D, STATEMENTS, TABLE_1, TABLE_1_MU, TABLE_2, TABLE_2_MU

__all__ = ["pendulum_maximiser", "table_1", "table_2"]


def _eig_distance(a: np.ndarray, b: np.ndarray) -> float:
    best = np.inf
    for perm in itertools.permutations(range(len(b))):
        best = min(best, float(np.max(np.abs(a - b[list(perm)]))))
    return best


#: The (gain convention, closed loop) pairs tried for Tables I–II, in order (analysis.gain_conventions,
#: analysis.closed_loop_eigenvalues); the shifted prediction's last block is tried with A - B K only.
_TRIED = [(gain, loop) for gain in ("first block of G^-1 Omega_gp", "first block of G Omega_gp (literal)",
                                     "nominal (Omega_g + Psi)^-1 Omega_gp") for loop in an.LOOPS]
_TRIED.append(("last block of G^-1 Omega_gp", "A-BK"))
_LOOP_LABELS = {"A-BK": "eig(A - B K)", "A-BMK": "eig(A - B M K)"}


def _conventions(system: System, protocol: str) -> dict[str, np.ndarray]:
    """Closed-loop eigenvalues under each convention tried for Tables I–II."""
    gains = an.gain_conventions(system, protocol)
    return {f"K = {gain}; {_LOOP_LABELS[loop]}": an.closed_loop_eigenvalues(system, gains[gain], (loop,))[loop]
            for gain, loop in _TRIED}


def _table(ctx: Context, claim_id: str, name: str, mu: Sequence[float], printed: dict) -> ClaimResult:
    system = ctx.paper[name].with_mu(mu)
    tried, best, best_name = 0, np.inf, ""
    for N in (system.horizon, system.horizon - 1, system.horizon + 1):
        data = system.to_dict()
        data["cost"]["horizon"] = N
        s = system_from_dict(data)
        eigs = {p: _conventions(s, p) for p in ("tcp", "udp")}
        for conv in eigs["tcp"]:
            tried += 2   # both protocols under this convention and horizon
            both = max(_eig_distance(np.asarray(printed[p], dtype=complex), eigs[p][conv]) for p in ("tcp", "udp"))
            if both < best:
                best, best_name = both, f"{conv}, N = {N}"
    ours = {p: np.round(closed_form(system, p).closed_loop_eigenvalues, 4).tolist() for p in ("tcp", "udp")}
    verdict = "holds" if best < 5e-4 else "not-reproduced"
    note = (f"Printed {printed}. Ours (K = first block of G^-1 Omega_gp, eig(A - B K)): {ours}. Tried "
            f"{tried} protocol-convention-horizon combinations: K from G^-1 Omega_gp, literal G Omega_gp, or "
            f"the nominal (mu = 1) law; eig(A - B K) or eig(A - B M K); first or last block; N - 1, N, N + 1. "
            f"Closest to both columns: {best_name}, max distance {best:.4f}.")
    return ClaimResult(claim_id, STATEMENTS[claim_id], verdict, tried, 0 if verdict == "holds" else 1,
                       float(best), None, note)


def table_1(ctx: Context) -> ClaimResult:
    """Table I: the pendulum's (eq:pendulum-ss) closed-loop eigenvalues.

    Examples
    --------
    >>> from packetloss_cvx.claims.context import paper_systems
    >>> r = table_1(Context(paper=paper_systems(), random=[], seed=0))
    >>> r.verdict, r.checked                         # 7 conventions x 3 horizons x 2 protocols; docs/claims.md
    ('not-reproduced', 42)
    """
    return _table(ctx, "table-1", "pendulum", list(TABLE_1_MU), TABLE_1)


def table_2(ctx: Context) -> ClaimResult:
    """Table II: the two-actuator system's (eq:mixed-ss) closed-loop eigenvalues.

    Examples
    --------
    >>> from packetloss_cvx.claims.context import paper_systems
    >>> r = table_2(Context(paper=paper_systems(), random=[], seed=0))
    >>> r.verdict, r.checked                         # 7 conventions x 3 horizons x 2 protocols; docs/claims.md
    ('not-reproduced', 42)
    """
    return _table(ctx, "table-2", "two_actuator", list(TABLE_2_MU), TABLE_2)


def _points(by_variant: dict[str, float | None]) -> str:
    """Roots of the paper's equations by variant, to 6 digits: their last digits move with the rounding (a root
    of theorem 4's equation moved 2.4e-8 relative between BLAS kernels).

    >>> _points({"lemma": None, "proof": 0.9914399952049379})
    'none (lemma), 0.99144 (proof)'
    """
    return ", ".join(f"{'none' if v is None else f'{v:.6g}'} ({k})" for k, v in by_variant.items())


def pendulum_maximiser(ctx: Context) -> ClaimResult:
    """The pendulum's nu^D* = 0.0031, against the numerical maximiser for several x0.

    Examples
    --------
    >>> s = System(A=np.eye(4), B=np.eye(4), horizon=1, state_weight=np.ones(4), input_weight=np.ones(4),
    ...            mu=np.full(4, 0.5), x0=np.ones(4))    # four copies of J_Delta = 1 - nu/2 - 1/(1 + nu)
    >>> r = pendulum_maximiser(Context(paper={"pendulum": s}, random=[], seed=0))
    >>> r.verdict, r.checked, bool(np.isclose(r.worst, 2**0.5 - 1 - PENDULUM_NU_D))   # peak sqrt 2 - 1 for each x0
    ('not-reproduced', 6, True)
    """
    s = ctx.paper["pendulum"]
    x0s = [np.eye(4)[i] for i in range(4)] + [np.ones(4), s.x0]
    found = []
    for x0 in x0s:
        base = difference.scalar_channel(s.with_x0(x0), 0.5)
        found.append(float(difference.maximise_cost_difference(base, grid=200).point[0]))
    base = difference.scalar_channel(s, 0.5)
    pred = prediction(base)
    cands = {}
    for variant in ("lemma", "proof"):
        c = difference.lemma3_candidates(base, variant, pred)
        real = np.sort(c[(np.abs(c.imag) < 1e-12) & (c.real > 0) & (c.real < 1)].real)
        cands[variant] = real
    nearest = {v: float(c[np.argmin(np.abs(c - PENDULUM_NU_D))]) if c.size else None for v, c in cands.items()}
    thm4 = {v: (None if (r := difference.theorem4_maximiser(base, v, pred=pred)) is None else float(r.point[0]))
            for v in ("lemma", "proof")}
    distance = min(abs(f - PENDULUM_NU_D) for f in found)
    verdict = "holds" if distance < 5e-5 else "not-reproduced"
    note = (f"Paper: nu^D* = {PENDULUM_NU_D} (x0 not given). Numerical maximiser of J_Delta for x0 = e1..e4, "
            f"(1,1,1,1), file x0: {[round(f, 6) for f in found]}. Theorem 4 gives {_points(thm4)}; the Lemma 3 "
            f"candidate nearest {PENDULUM_NU_D} is {_points(nearest)}.")
    return ClaimResult("pendulum-maximiser", STATEMENTS["pendulum-maximiser"], verdict, len(x0s),
                       0 if verdict == "holds" else 1, float(distance), None, note)
