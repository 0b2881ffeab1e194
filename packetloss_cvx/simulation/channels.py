"""The stated model's random variables (eq:plant): Bernoulli packet deliveries, independent
across channels and steps with probability mu_{t,i}, and Gaussian process noise W_t ~ N(0, Sigma_W).

Every sampler of the package draws through these, so a change of channel model (e.g. bursty,
Markov channels) has one place to go.
"""

from __future__ import annotations

import numpy as np

from ..linalg import psd_factor
from ..model import System

__all__ = [
    "sample_deliveries", "sample_delivery_paths", "sample_noise", "sample_noise_paths", "sample_step_deliveries",
    "sample_step_noise",
]


def sample_deliveries(system: System, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Sampled packet deliveries over the horizon: the diagonal of Upsilon (big; the losses of eq:plant).

    Parameters
    ----------
    system : System
    samples : int
    rng : numpy.random.Generator
        One uniform draw per entry, in the order of the returned array.

    Returns
    -------
    ndarray of bool, shape (samples, N m)
        Entry ``[s, t m + i]`` is ``v_{i,t}``: True (delivered) with probability ``mu_{t,i}``,
        independently across samples, channels and steps (the order of Vbar).
    """
    mu = system.mu_schedule.ravel()
    return rng.random((samples, mu.size)) < mu


def sample_noise(system: System, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Sampled process noise over the horizon, stacked as W in big: ``(W_k', ..., W_{k+N-1}')``.

    Parameters
    ----------
    system : System
    samples : int
    rng : numpy.random.Generator
        ``W_t = L' z_t`` with ``z_t ~ N(0, I)`` standard normal draws and ``L' L = Sigma_W``
        (:func:`~packetloss_cvx.linalg.psd_factor`); no draws when Sigma_W = 0.

    Returns
    -------
    ndarray, shape (samples, N n)
        Independent ``N(0, Sigma_W)`` blocks, one per step.
    """
    root = psd_factor(system.noise_cov)
    z = rng.standard_normal((samples, system.horizon, root.shape[0]))
    return (z @ root).reshape(samples, system.horizon * system.n)   # = z @ kron(I_N, root), without the N n square


def sample_delivery_paths(system: System, steps: int, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Deliveries of a loop run over ``steps`` steps of the system's (stationary) channel.

    Returns a bool array ``(steps, samples, m)``: ``[t, s, i]`` is ``v_{i,t}`` of run s, True with
    probability ``mu_i`` (the first row of ``mu_schedule``), independent across steps, runs and
    channels. The draws go run by run (one uniform per entry, runs outermost), so the first runs of
    a larger draw from the same stream are the same. Time and memory O(steps samples m).
    """
    return (rng.random((samples, steps, system.m)) < system.mu_schedule[0]).transpose(1, 0, 2)


def sample_noise_paths(system: System, steps: int, samples: int, rng: np.random.Generator) -> np.ndarray | None:
    """Process noise of a loop run: ``(steps, samples, n)`` draws of ``N(0, Sigma_W)`` (``L' z`` as in
    :func:`sample_noise`), or None when Sigma_W = 0 (no draws). Time O(steps samples n r)."""
    root = psd_factor(system.noise_cov)
    if not root.shape[0]:
        return None
    return (rng.standard_normal((samples, steps, root.shape[0])) @ root).transpose(1, 0, 2)   # run by run


def sample_step_deliveries(system: System, t: int, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Deliveries of step t only: bool (samples, m), True with probability ``mu_{t,i}`` (one uniform per entry,
    row by row). For samplers that draw step by step. Time O(samples m)."""
    return rng.random((samples, system.m)) < system.mu_schedule[t]


def sample_step_noise(root: np.ndarray, samples: int, rng: np.random.Generator) -> np.ndarray | None:
    """One step's process noise ``z @ root`` (samples, n) with ``root' root = Sigma_W``
    (:func:`~packetloss_cvx.linalg.psd_factor`, computed once by the caller), or None when ``root`` has no rows
    (Sigma_W = 0: no draws). Time O(samples n r)."""
    return rng.standard_normal((samples, root.shape[0])) @ root if root.shape[0] else None
