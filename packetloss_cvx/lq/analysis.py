"""Monotonicity of the optimal cost (Theorem 3) and the closed-loop eigenvalues of Tables I–II.

The cost difference between the protocols and its maximisers (§IV) live in
[`packetloss_cvx.lq.difference`][packetloss_cvx.lq.difference], under their own names there.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..model.system import System
from .costs import closed_form, hessian_factor
from .prediction import prediction

__all__ = [
    "closed_loop_eigenvalues",
    "eigenvalue_table",
    "gain_conventions",
    "LOOPS",
    "monotonicity_violations",
]


def monotonicity_violations(system: System, protocol: str, steps: int = 11) -> list[tuple[int, float, float]]:
    """Theorem 3 (eq:monotonic-cost-pos-def) along each channel: raise mu_i on a grid with the others fixed and report
    ``(i, mu_i, increase)`` wherever J* does not strictly decrease. O(m steps) closed forms.

    >>> from packetloss_cvx import load_example
    >>> monotonicity_violations(load_example("two_actuator"), "udp", steps=5)
    []
    """
    out = []
    base = system.mu_schedule[0].copy() if system.is_stationary else None
    if base is None:
        raise InputError("system", "expected a stationary channel")
    for i in range(system.m):
        prev = None
        for value in np.linspace(0.05, 1.0, steps):
            mu = base.copy()
            mu[i] = value
            cost = closed_form(system.with_mu(mu), protocol, method="auto").cost
            if prev is not None and cost >= prev[1]:
                out.append((i, float(value), float(cost - prev[1])))
            prev = (value, cost)
    return out


#: The closed loops whose eigenvalues Tables I–II may report: every packet delivered
#: (``"A-BK"``, the paper's convention) and the mean loop (``"A-BMK"``, M = diag(mu_0)).
LOOPS = ("A-BK", "A-BMK")


def closed_loop_eigenvalues(system: System, gain: np.ndarray, loops: Sequence[str] = LOOPS) -> dict[str, np.ndarray]:
    """Eigenvalues of the closed loops of ``u = -K x`` named in ``loops``.

    .. math:: \\operatorname{eig}(A - BK), \\qquad \\operatorname{eig}(A - BMK),\\ M = \\operatorname{diag}(\\mu_0)

    Parameters
    ----------
    system : System
        The plant; ``M`` uses the channel of the first step.
    gain : ndarray, shape (m, n)
        The gain ``K``.
    loops : sequence of {"A-BK", "A-BMK"}
        Which closed loops, in the order wanted.

    Returns
    -------
    dict of str to ndarray
        Complex eigenvalues (unsorted) per loop name.

    Raises
    ------
    InputError
        An unknown loop name.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> {k: v.real.tolist() for k, v in closed_loop_eigenvalues(s, np.array([[0.5]])).items()}  # 1 - K, 1 - K/2
    {'A-BK': [0.5], 'A-BMK': [0.75]}
    """
    unknown = [loop for loop in loops if loop not in LOOPS]
    if unknown:
        raise InputError("loops", f"expected names from {LOOPS}, found {unknown}")
    A, B, M = system.A, system.B, np.diag(system.mu_schedule[0])
    return {loop: np.linalg.eigvals(A - B @ gain if loop == "A-BK" else A - B @ M @ gain) for loop in loops}


def gain_conventions(system: System, protocol: str) -> dict[str, np.ndarray]:
    """The receding-horizon gain ``K`` (m×n) under each reading of the paper tried for Tables I–II.

    ``"first block of G^-1 Omega_gp"`` (eq:opt-law-1, eq:opt-law-2: the law the paper derives);
    ``"first block of G Omega_gp (literal)"`` (G without the inverse, as a misprint would have it);
    ``"nominal (Omega_g + Psi)^-1 Omega_gp"`` (the mu = 1 law); ``"last block of G^-1 Omega_gp"``
    (a shifted prediction, Omega on X_k..X_{k+N-1}). Dense: O((N m)^3).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> [round(float(K[0, 0]), 4) for K in gain_conventions(s, "tcp").values()]  # min (1 + u/2)^2 + u^2/2
    [0.6667, 1.5, 0.5, 0.6667]
    """
    pred = prediction(system)
    G = hessian_factor(pred, protocol)
    m = system.m
    law = np.linalg.solve(G, pred.Omega_gp)
    return {
        "first block of G^-1 Omega_gp": law[:m],
        "first block of G Omega_gp (literal)": (G @ pred.Omega_gp)[:m],
        "nominal (Omega_g + Psi)^-1 Omega_gp": np.linalg.solve(hessian_factor(pred, "tcp", np.ones_like(pred.Vbar)),
                                                               pred.Omega_gp)[:m],
        "last block of G^-1 Omega_gp": law[-m:],
    }


def eigenvalue_table(system: System, mu=None) -> dict[str, dict[str, list[complex]]]:
    """Tables I–II: closed-loop eigenvalues of the receding-horizon laws at ``mu``.

    For each protocol: ``"A-BK"`` (the paper's convention, K the first block of G^-1 Omega_gp)
    and ``"A-BMK"`` (the mean closed loop, which accounts for the delivery probability), each
    sorted by descending modulus (see [`closed_loop_eigenvalues`][packetloss_cvx.lq.analysis.closed_loop_eigenvalues]).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> {p: [round(v[0].real, 4) for v in d.values()] for p, d in eigenvalue_table(s).items()}  # 1 - K, 1 - K/2
    {'tcp': [0.3333, 0.6667], 'udp': [0.5, 0.75]}
    """
    s = system if mu is None else system.with_mu(mu)
    out = {}
    for protocol in ("tcp", "udp"):
        K = closed_form(s, protocol, method="auto").gain
        out[protocol] = {loop: sorted(eigs.tolist(), key=lambda z: (-abs(z), z.imag))
                         for loop, eigs in closed_loop_eigenvalues(s, K).items()}
    return out
