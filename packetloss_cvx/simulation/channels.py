"""The stated model's random variables (eq:plant): Bernoulli packet deliveries, independent
across channels and steps with probability mu_{t,i}, and Gaussian process noise W_t ~ N(0, Sigma_W).

Every sampler of the package draws through these, so a change of channel model (e.g. bursty,
Markov channels) has one place to go.
"""

from __future__ import annotations

import numpy as np

from ..linalg import psd_factor
from ..model import System

__all__ = ["sample_deliveries", "sample_noise"]


def sample_deliveries(system: System, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Sampled packet deliveries over the horizon: the diagonal of Upsilon (eq:big).

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
    """Sampled process noise over the horizon, stacked as W in eq:big: ``(W_k', ..., W_{k+N-1}')``.

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
    z = rng.standard_normal((samples, system.horizon * root.shape[0]))
    return z @ np.kron(np.eye(system.horizon), root)
