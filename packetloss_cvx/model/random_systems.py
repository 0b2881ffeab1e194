"""Seeded random systems for property tests and the audit.

Every draw is a valid [`System`][packetloss_cvx.model.system.System]; the options switch on the schema's
features one by one so that a test can cover each combination.
"""

from __future__ import annotations

import numpy as np

from .system import System

__all__ = ["random_system"]


def _psd(rng: np.random.Generator, n: int, full: bool) -> np.ndarray:
    if not full:
        return np.diag(rng.uniform(0.1, 2.0, n))
    F = rng.normal(size=(n, n))
    return F @ F.T / n + 0.05 * np.eye(n)


def random_system(
    rng: np.random.Generator,
    n: int | None = None,
    m: int | None = None,
    horizon: int | None = None,
    *,
    spectral_radius: float | None = None,
    full_weights: bool | None = None,
    time_varying: bool | None = None,
    non_stationary: bool | None = None,
    noise: bool | None = None,
    edge_mu: bool | None = None,
) -> System:
    """Draw a random system; any option left as None is itself drawn at random.

    ``spectral_radius`` scales A (values above 1 give unstable plants);
    ``edge_mu`` puts some channels at 1.0 and some at 0.01.

    Examples
    --------
    >>> s = random_system(np.random.default_rng(0), n=3, m=2, horizon=4, spectral_radius=0.5)
    >>> (s.n, s.m, s.horizon)
    (3, 2, 4)
    >>> bool(np.isclose(max(abs(np.linalg.eigvals(s.A))), 0.5))     # A is scaled to the radius asked for
    True
    """
    def coin(value: bool | None) -> bool:
        return bool(rng.random() < 0.5) if value is None else value

    n = int(rng.integers(1, 5)) if n is None else n
    m = int(rng.integers(1, 5)) if m is None else m
    N = int(rng.integers(1, 9)) if horizon is None else horizon
    rho = float(rng.uniform(0.5, 1.3)) if spectral_radius is None else spectral_radius
    A = rng.normal(size=(n, n))
    radius = max(abs(np.linalg.eigvals(A)))
    A = A * (rho / radius) if radius > 0 else A
    B = rng.normal(size=(n, m))
    kwargs: dict = {"A": A, "B": B, "horizon": N, "x0": rng.normal(size=n)}
    full = coin(full_weights)
    if coin(time_varying):
        kwargs["state_weights"] = [_psd(rng, n, full) for _ in range(N)]
        kwargs["input_weights"] = rng.uniform(0.2, 2.0, (N, m))
    else:
        kwargs["state_weight"] = _psd(rng, n, full)
        kwargs["input_weight"] = rng.uniform(0.2, 2.0, m)
    if coin(non_stationary):
        mu = rng.uniform(0.05, 0.99, (N, m))
    else:
        mu = rng.uniform(0.05, 0.99, m)
    if coin(edge_mu):
        flat = mu.reshape(-1, m)
        flat[:, 0] = 1.0
        if m > 1:
            flat[:, -1] = 0.01
    kwargs["mu_schedule" if mu.ndim == 2 else "mu"] = mu
    if coin(noise):
        kwargs["noise_cov"] = _psd(rng, n, True) * 0.1
    if rng.random() < 0.5:
        kwargs["initial_weight"] = _psd(rng, n, full)
    return System(**kwargs)
