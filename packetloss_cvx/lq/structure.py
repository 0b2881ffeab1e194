"""What Theorem 1 needs of a system that does not depend on mu or x0: one frozen `Structure` per system
structure, built by this module and kept here (a `StructureStore`, weakly keyed by the
system's structure token: shared by its ``with_mu`` / ``with_x0`` / ``with_channel`` copies, gone with the last of
them). Nothing is kept on the System and nothing calls back into it.

The kernels ([`recursion`][packetloss_cvx.lq.recursion], `dense`) take a structure and a channel mu;
the policy (`policy`) chooses between them. The parts that cost more than reading the system
are computed on first use and kept on the structure:

* `Structure.weight_head`, the leading state weights equal to the first (O(N n^2) once);
* `Structure.variance_weights`, ``(d, noise)``: ``d[t] = diag(B'S_tB)`` of the backward Lyapunov sum
  ``S_t = Omega_{t+1} + A'S_{t+1}A`` (the UDP-like law's loss-variance weight, eq:opt-law-2) and the noise term
  ``sum_t tr(S_t Sigma_W)`` (O(N n^3) once, O(L n^3) for a sum that settles in L steps);
* `Structure.condition`, the condition estimate of the dense forms (O(N m) once the sums are there).

The test of a backward iterate having settled, which the Lyapunov sum here and the Riccati passes share, is
`settling`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..model.system import CacheKey, StructureStore, System
from .settling import STATIONARY_RUN, leading_run, small_change, spectral_radius, stationary_close

__all__ = ["STRUCTURE_KEY", "Structure", "condition_from", "lyapunov_weights", "structure_of"]

#: What a Structure depends on: the kept value is shared by the copies that keep these fields.
STRUCTURE_KEY = CacheKey("structure.Structure",
                         ("A", "B", "horizon", "state_weights", "input_weights", "initial_weight", "noise_cov"))
_STRUCTURES = StructureStore(STRUCTURE_KEY)


@dataclass(frozen=True, eq=False)
class Structure:
    """The mu- and x0-free data of Theorem 1 for one system structure (read-only arrays of the system; no
    reference to the system itself). Attributes named as on [`System`][packetloss_cvx.model.system.System], so a kernel
    reads either; the derived parts are computed on first use (see the module docstring).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> st = structure_of(s)
    >>> st is structure_of(s.with_mu([0.9])), st.variance_weights[0].ravel().tolist(), st.condition
    (True, [5.0, 1.0], 7.0)
    """

    A: np.ndarray
    B: np.ndarray
    horizon: int
    state_weights: np.ndarray
    input_weights: np.ndarray
    initial_weight: np.ndarray
    noise_cov: np.ndarray

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.B.shape[1]

    @cached_property
    def has_noise(self) -> bool:
        return bool(np.any(self.noise_cov != 0))

    @cached_property
    def weight_head(self) -> np.ndarray:
        """The leading state weights equal to the first, ``state_weights[:h + 1]`` (a read-only view; all N for a
        time-invariant weight). The backward passes close a stationary tail only inside it, and the forward cost
        weighs every state with one product when it is the whole horizon. O(N n^2) once."""
        W = self.state_weights
        return W[:leading_run(W[None]) + 1]

    @cached_property
    def time_invariant_weight(self) -> bool:
        """Whether one state weight serves every step (`weight_head` is the whole horizon). O(1) after it."""
        return len(self.weight_head) == self.horizon

    @cached_property
    def open_loop_radius(self) -> float:
        """rho(A). O(n^3) once."""
        return float(spectral_radius(self.A))

    @cached_property
    def variance_weights(self) -> tuple[np.ndarray, float]:
        """``(d, noise)``: ``d[t, i] = (B'S_tB)_{ii}`` (N, m, read-only) and ``noise = sum_t tr(S_t Sigma_W)``
        (`lyapunov_weights`). O(N n^3) once."""
        return lyapunov_weights(self)[:2]

    @cached_property
    def condition(self) -> float:
        """``(trace Omega_g + max Psi) / min Psi`` from `variance_weights` (`condition_from`).
        O(N m) once the sums are there."""
        return condition_from(self, self.variance_weights[0])


def structure_of(system: System | Structure) -> Structure:
    """The structure of ``system``, built on the first call for its structure and kept while some system of that
    structure lives (a Structure is its own structure). O(1) after the first call.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> structure_of(s) is structure_of(s.with_x0([3.0])) is structure_of(structure_of(s))
    True
    """
    if isinstance(system, Structure):
        return system
    kept = _STRUCTURES.get(system)
    if kept is None:
        kept = _STRUCTURES.put(system, Structure(A=system.A, B=system.B, horizon=system.horizon,
                                                 state_weights=system.state_weights,
                                                 input_weights=system.input_weights,
                                                 initial_weight=system.initial_weight, noise_cov=system.noise_cov))
    return kept


def condition_from(structure: Structure, d: np.ndarray) -> float:
    """``(sum d + max Psi) / min Psi`` (trace Omega_g = sum d): the condition estimate of the dense forms for the
    variance weights ``d``; inf where the sum overflows. O(N m)."""
    psi = structure.input_weights
    with np.errstate(over="ignore", invalid="ignore"):
        total = float(np.sum(d))
    if not np.isfinite(total):
        return float("inf")
    return (total + float(psi.max())) / float(psi.min())


def lyapunov_weights(structure: Structure, cross: bool = False) -> tuple:
    """The backward Lyapunov sum ``S_t = Omega_{t+1} + A'S_{t+1}A`` weighed as ``(d, noise)`` (see
    `Structure.variance_weights`), and with ``cross`` the products ``B'S_tA`` (N, m, n) per step. O(N n^3);
    once S stops changing (`stationary_close`) over a stationary head (Omega_t the same for every earlier t),
    the earlier steps take its value: O(L n^3) for a sum that settles in L steps. An unstable A's sum never settles
    (q = rho(A)^2 >= 1): its steps are not weighed at all."""
    A, B, W, N = structure.A, structure.B, structure.state_weights, structure.horizon
    d = np.empty((N, structure.m))
    BSA = np.empty((N, structure.m, structure.n)) if cross else None
    noise = 0.0
    has_noise, noise_cov = structure.has_noise, structure.noise_cov
    # only long horizons are worth the checks, and only a stable A's sum settles (q = rho(A)^2 < 1)
    q = structure.open_loop_radius ** 2 if N >= 2 * STATIONARY_RUN else math.inf
    settle = q < 1.0
    head = None                                         # Omega_1..Omega_head+1 (W[0..head]) are one weight
    S = W[N - 1].copy()
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(N - 1, -1, -1):
            d[t] = np.einsum("ij,ik,kj->j", B, S, B)
            if cross:
                BSA[t] = B.T @ S @ A
            if has_noise:
                noise += float(np.sum(S * noise_cov))
            if t > 0:
                new = W[t - 1] + A.T @ S @ A
                if (settle and (head is None or t - 1 <= head) and small_change(new, S)
                        and stationary_close(new, S, q)):
                    head = len(structure.weight_head) - 1 if head is None else head
                    if t - 1 <= head:                                     # S_{t-1} = ... = S_0 = new
                        d[:t] = np.einsum("ij,ik,kj->j", B, new, B)
                        if cross:
                            BSA[:t] = B.T @ new @ A
                        if has_noise:
                            noise += t * float(np.sum(new * noise_cov))
                        break
                S = new
    d.setflags(write=False)
    return (d, noise, BSA) if cross else (d, noise)
