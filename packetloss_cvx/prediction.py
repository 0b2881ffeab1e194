"""Stacked prediction matrices Phi, Gamma, Lambda and the Omega_* products (eq:big, §III).

Everything here is dense: memory O((N n)^2 + (N n)(N m)), time O(N^2 n^2 (n + m) + (N m)^2 N n).
For long horizons use :mod:`packetloss_cvx.recursion`, which forms none of these.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .errors import NumericalError
from .model import System

__all__ = ["Prediction", "prediction"]


@dataclass(frozen=True)
class Prediction:
    """The paper's stacked matrices for one system (names follow §III).

    ``Vbar`` and ``Psi`` are the diagonals of the paper's diagonal matrices, ordered
    step-major: entry ``t * m + i`` is actuator i at step t.
    """

    Phi: np.ndarray        # (N n, n)
    Gamma: np.ndarray      # (N n, N m)
    Lambda: np.ndarray     # (N n, N n)
    Omega: np.ndarray      # (N n, N n)  blkdiag(Omega_1..Omega_N)
    Psi: np.ndarray        # (N m,)      diagonal of blkdiag(Psi_0..Psi_{N-1})
    Vbar: np.ndarray       # (N m,)      diagonal of E[Upsilon]
    Omega_p: np.ndarray    # Phi' Omega Phi
    Omega_g: np.ndarray    # Gamma' Omega Gamma
    Omega_gp: np.ndarray   # Gamma' Omega Phi
    Omega_l: np.ndarray    # Lambda' Omega Lambda
    Omega_d: np.ndarray    # diagonal of Omega_g (the paper's I ∘ Omega_g), (N m,)
    Sigma_W: np.ndarray    # (N n, N n)  blkdiag(Sigma_W, ..)

    @property
    def Omega_h(self) -> np.ndarray:
        """Omega_g - Omega_d: the off-diagonal part of Omega_g."""
        return self.Omega_g - np.diag(self.Omega_d)

    @property
    def noise_term(self) -> float:
        """tr(Omega_l Sigma_W), the noise part of both optimal costs."""
        return float(np.trace(self.Omega_l @ self.Sigma_W))


def _check_finite(name: str, arr: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(arr)):
        raise NumericalError(
            f"{name} overflowed (the dense prediction of an unstable plant over a long horizon); "
            "use method='recursion'"
        )
    return arr


def prediction(system: System) -> Prediction:
    """Build the dense prediction matrices of eq:big and their Omega products.

    Raises
    ------
    NumericalError
        If any entry overflows (unstable A over a long horizon).
    """
    A, B, N = system.A, system.B, system.horizon
    n, m = system.n, system.m
    powers = [np.eye(n)]
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(N):
            powers.append(powers[-1] @ A)
        Phi = _check_finite("Phi", np.vstack(powers[1:]))
        AB = [P @ B for P in powers[:N]]
        Gamma = np.zeros((N * n, N * m))
        Lambda = np.zeros((N * n, N * n))
        for i in range(N):
            for j in range(i + 1):
                Gamma[i * n:(i + 1) * n, j * m:(j + 1) * m] = AB[i - j]
                Lambda[i * n:(i + 1) * n, j * n:(j + 1) * n] = powers[i - j]
        _check_finite("Gamma", Gamma)
        Omega = sla.block_diag(*system.state_weights)
        OG = Omega @ Gamma
        Omega_g = _check_finite("Omega_g", Gamma.T @ OG)
        Omega_gp = _check_finite("Omega_gp", OG.T @ Phi)
        Omega_p = _check_finite("Omega_p", Phi.T @ Omega @ Phi)
        Omega_l = _check_finite("Omega_l", Lambda.T @ Omega @ Lambda)
    Omega_g = 0.5 * (Omega_g + Omega_g.T)
    return Prediction(
        Phi=Phi, Gamma=Gamma, Lambda=Lambda, Omega=Omega,
        Psi=system.input_weights.ravel().copy(), Vbar=system.mu_schedule.ravel().copy(),
        Omega_p=0.5 * (Omega_p + Omega_p.T), Omega_g=Omega_g, Omega_gp=Omega_gp,
        Omega_l=Omega_l, Omega_d=np.diag(Omega_g).copy(),
        Sigma_W=np.kron(np.eye(N), system.noise_cov),
    )
