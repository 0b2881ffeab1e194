"""Stacked prediction matrices Phi, Gamma, Lambda and the Omega_* products (big, §III).

Everything here is dense: memory O((N n)^2 + (N n)(N m)), time O(N^2 n^2 (n + m) + (N m)^2 N n).
For long horizons use [`packetloss_cvx.lq.recursion`][packetloss_cvx.lq.recursion], which forms none of these.

None of the matrices depends on mu or x0, so they are built once per system structure and kept here
(`StructureStore`s, shared by a system's ``with_mu`` / ``with_x0`` copies) while they
fit ``model.STRUCTURE_CACHE_MAX_BYTES``; every array of a [`Prediction`][packetloss_cvx.lq.prediction.Prediction] is
read-only.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..linalg import block_diagonal, check_finite
from ..model.system import CacheKey, StructureStore, System

#: what is kept per system structure: each key says the fields its value depends on
CORE_KEY = CacheKey("prediction.core", ("A", "B", "horizon", "state_weights", "input_weights"))
OMEGA_KEY = CacheKey("prediction.Omega", ("horizon", "state_weights"))
NOISE_TERM_KEY = CacheKey("prediction.noise_term", ("A", "horizon", "state_weights", "noise_cov"))
_CORES, _OMEGAS, _NOISE_TERMS = StructureStore(CORE_KEY), StructureStore(OMEGA_KEY), StructureStore(NOISE_TERM_KEY)

__all__ = ["Prediction", "prediction"]


@dataclass(frozen=True)
class Prediction:
    """The paper's stacked matrices for one system (names follow §III).

    ``Vbar`` and ``Psi`` are the diagonals of the paper's diagonal matrices, ordered
    step-major: entry ``t * m + i`` is actuator i at step t. ``Lambda`` and
    ``Omega_l`` are built on first use (only the noise term needs them). The arrays are
    read-only: they may be shared with other predictions of the same system structure.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0],
    ...            noise_cov=[[0.1]])
    >>> p = prediction(s)
    >>> p.Lambda.tolist(), p.Omega_h.tolist()      # A^{i-j} below the diagonal; Omega_g off its diagonal
    ([[1.0, 0.0], [1.0, 1.0]], [[0.0, 1.0], [1.0, 0.0]])
    >>> round(p.noise_term, 12)                    # tr(Lambda' Lambda Sigma_W) = (2 + 1) * 0.1
    0.3
    """

    system: System
    Phi: np.ndarray        # (N n, n)
    Gamma: np.ndarray      # (N n, N m)
    Psi: np.ndarray        # (N m,)      diagonal of blkdiag(Psi_0..Psi_{N-1})
    Vbar: np.ndarray       # (N m,)      diagonal of E[Upsilon]
    Omega_p: np.ndarray    # Phi' Omega Phi
    Omega_g: np.ndarray    # Gamma' Omega Gamma
    Omega_gp: np.ndarray   # Gamma' Omega Phi
    Omega_d: np.ndarray    # diagonal of Omega_g (the paper's I ∘ Omega_g), (N m,)

    @property
    def Omega_h(self) -> np.ndarray:
        """Omega_g - Omega_d: the off-diagonal part of Omega_g."""
        return self.Omega_g - np.diag(self.Omega_d)

    @cached_property
    def Omega(self) -> np.ndarray:
        """blkdiag(Omega_1..Omega_N), (N n)×(N n); kept per system structure (read-only)."""
        s = self.system
        kept = _OMEGAS.get(s)
        if kept is None:
            kept = _OMEGAS.put(s, _read_only(block_diagonal(s.state_weights)), nbytes=8 * (s.horizon * s.n) ** 2)
        return kept

    @cached_property
    def Lambda(self) -> np.ndarray:
        """Noise propagation, (N n)×(N n), block (i, j) = A^{i-j} for i >= j."""
        s = self.system
        return _block_toeplitz(_powers(s.A, s.horizon), s.horizon, s.n, s.n, "Lambda")

    @cached_property
    def Omega_l(self) -> np.ndarray:
        """Lambda' Omega Lambda (the paper prints Lambda Omega Lambda; see docs/claims.md)."""
        with np.errstate(over="ignore", invalid="ignore"):
            return check_finite("Omega_l", self.Lambda.T @ self.Omega @ self.Lambda)

    @property
    def Sigma_W(self) -> np.ndarray:
        """blkdiag(Sigma_W, ..., Sigma_W), (N n)×(N n)."""
        return np.kron(np.eye(self.system.horizon), self.system.noise_cov)

    @cached_property
    def noise_term(self) -> float:
        """tr(Omega_l Sigma_W), the noise part of both optimal costs (0 without noise; eq:TCP-err).
        Kept on the system structure (it depends on neither mu nor x0)."""
        kept = _NOISE_TERMS.get(self.system)
        if kept is None:
            kept = _NOISE_TERMS.put(self.system, float(np.sum(self.Omega_l * self.Sigma_W))
                                    if np.any(self.system.noise_cov) else 0.0)
        return kept


def _read_only(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def _powers(A: np.ndarray, N: int) -> list[np.ndarray]:
    """[I, A, A^2, ..., A^N]."""
    powers = [np.eye(A.shape[0])]
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(N):
            powers.append(powers[-1] @ A)
    return powers


def _block_toeplitz(blocks: list[np.ndarray], N: int, r: int, c: int, name: str) -> np.ndarray:
    """Lower block-triangular Toeplitz matrix with block (i, j) = blocks[i - j]: one gather from the blocks
    behind N - 1 zero blocks (index N - 1 + i - j), the same copies as a loop over the diagonals without its
    per-diagonal overhead. Time and memory O(N^2 r c)."""
    padded = np.zeros((2 * N - 1, r, c))
    padded[N - 1:] = blocks[:N]
    index = (N - 1) + np.arange(N)[:, None] - np.arange(N)[None, :]
    flat = np.empty((N * r, N * c))          # owns its data: a read-only result has no writable base
    flat.reshape(N, r, N, c)[...] = padded[index].transpose(0, 2, 1, 3)
    return check_finite(name, flat)


def prediction(system: System) -> Prediction:
    """Build the dense prediction matrices (the paper's big) and their Omega products.

    The paper's labels: big (Phi, Gamma, Lambda), eq:matrix-plant (X = Phi x + Gamma Y U + Lambda W).

    Time O((N n)^2 N m + (N m)^2 N n), memory O(N^2 n (n + m)), the first time for a system structure;
    O(1) after that while the matrices fit ``STRUCTURE_CACHE_MAX_BYTES`` (kept per system structure, shared by its
    ``with_mu`` / ``with_x0`` copies: they depend on neither mu nor x0).

    Raises
    ------
    NumericalError
        If any entry overflows (unstable A over a long horizon).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> p = prediction(s)                          # A = 2, B = 1, N = 2, Omega_t = 1
    >>> p.Phi.ravel().tolist(), p.Gamma.tolist()   # (A, A^2) and [[B, 0], [A B, B]]
    ([2.0, 4.0], [[1.0, 0.0], [2.0, 1.0]])
    >>> p.Omega_g.tolist(), p.Omega_d.tolist()     # Gamma' Gamma and its diagonal
    ([[5.0, 2.0], [2.0, 1.0]], [5.0, 1.0])
    """
    N, n, m = system.horizon, system.n, system.m
    size = 8 * (N * n * (n + N * m) + (N * m) * (2 * N * m + n + 2) + n * n)
    core = _CORES.get(system)
    if core is None:
        core = _CORES.put(system, _structure(system), nbytes=size)
    return Prediction(system=system, Vbar=system.mu_schedule.reshape(-1), **core)


def _structure(system: System) -> dict[str, np.ndarray]:
    """Phi, Gamma, the Omega products and Psi of [`prediction`][packetloss_cvx.lq.prediction.prediction] (none depends
        on mu or x0), read-only."""
    A, B, N = system.A, system.B, system.horizon
    powers = _powers(A, N)
    with np.errstate(over="ignore", invalid="ignore"):
        Phi = check_finite("Phi", np.vstack(powers[1:]))
        Gamma = _block_toeplitz([Ak @ B for Ak in powers[:N]], N, system.n, system.m, "Gamma")
        W = system.state_weights
        n = system.n
        # blkdiag(Omega_t) times a stacked matrix, block by block: O(N n^2) per column
        OG = np.einsum("tij,tjk->tik", W, Gamma.reshape(N, n, -1)).reshape(N * n, -1)
        OP = np.einsum("tij,tjk->tik", W, Phi.reshape(N, n, n)).reshape(N * n, n)
        Omega_g = check_finite("Omega_g", Gamma.T @ OG)
        Omega_gp = check_finite("Omega_gp", OG.T @ Phi)
        Omega_p = check_finite("Omega_p", Phi.T @ OP)
    Omega_g = 0.5 * (Omega_g + Omega_g.T)
    core = {"Phi": Phi, "Gamma": Gamma, "Psi": system.input_weights.ravel().copy(),
            "Omega_p": 0.5 * (Omega_p + Omega_p.T), "Omega_g": Omega_g, "Omega_gp": Omega_gp,
            "Omega_d": np.diag(Omega_g).copy()}
    for value in core.values():
        value.setflags(write=False)
    return core
