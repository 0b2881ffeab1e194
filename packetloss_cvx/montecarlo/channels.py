"""The stated model's random variables (eq:plant): Bernoulli packet deliveries, independent
across channels and steps with probability mu_{t,i}, and Gaussian process noise W_t ~ N(0, Sigma_W).

Every sampler of the package draws through these, so a change of channel model (e.g. bursty,
Markov channels) has one place to go.
"""

from __future__ import annotations

import numpy as np

from ..linalg import psd_factor
from ..model.system import System

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

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0],
    ...            noise_cov=[[4.0]])
    >>> v = sample_deliveries(s, 4000, np.random.default_rng(0))
    >>> v.shape, bool(abs(v.mean() - 0.3) < 4 * (0.3 * 0.7 / v.size) ** 0.5)   # delivery rate ~ mu
    ((4000, 2), True)
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
        (`psd_factor`); no draws when Sigma_W = 0.

    Returns
    -------
    ndarray, shape (samples, N n)
        Independent ``N(0, Sigma_W)`` blocks, one per step.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0],
    ...            noise_cov=[[4.0]])
    >>> w = sample_noise(s, 4000, np.random.default_rng(0))
    >>> w.shape, bool(abs(w.var() - 4.0) < 0.3), bool(abs(np.corrcoef(w.T)[0, 1]) < 0.1)   # Sigma_W; independent
    ((4000, 2), True, True)
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

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0],
    ...            noise_cov=[[4.0]])
    >>> v = sample_delivery_paths(s, 3, 2000, np.random.default_rng(0))
    >>> v.shape, bool(abs(v.mean() - 0.3) < 0.03)
    ((3, 2000, 1), True)
    >>> bool(np.array_equal(sample_delivery_paths(s, 3, 5, np.random.default_rng(0)), v[:, :5]))   # runs outermost
    True
    """
    return (rng.random((samples, steps, system.m)) < system.mu_schedule[0]).transpose(1, 0, 2)


def sample_noise_paths(system: System, steps: int, samples: int, rng: np.random.Generator) -> np.ndarray | None:
    """Process noise of a loop run: ``(steps, samples, n)`` draws of ``N(0, Sigma_W)`` (``L' z`` as in
    `sample_noise`), or None when Sigma_W = 0 (no draws). Time O(steps samples n r).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0],
    ...            noise_cov=[[4.0]])
    >>> w = sample_noise_paths(s, 3, 2000, np.random.default_rng(0))
    >>> w.shape, bool(abs(w.var() - 4.0) < 0.4)
    ((3, 2000, 1), True)
    >>> noiseless = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0])
    >>> print(sample_noise_paths(noiseless, 3, 5, np.random.default_rng(0)))
    None
    """
    root = psd_factor(system.noise_cov)
    if not root.shape[0]:
        return None
    return (rng.standard_normal((samples, steps, root.shape[0])) @ root).transpose(1, 0, 2)   # run by run


def sample_step_deliveries(system: System, t: int, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Deliveries of step t only: bool (samples, m), True with probability ``mu_{t,i}`` (one uniform per entry,
    row by row). For samplers that draw step by step. Time O(samples m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> s = s.with_mu([[0.0], [1.0]])                  # step 0 always lost, step 1 always delivered
    >>> rng = np.random.default_rng(0)
    >>> bool(sample_step_deliveries(s, 0, 50, rng).any()), bool(sample_step_deliveries(s, 1, 50, rng).all())
    (False, True)
    """
    return rng.random((samples, system.m)) < system.mu_schedule[t]


def sample_step_noise(root: np.ndarray, samples: int, rng: np.random.Generator) -> np.ndarray | None:
    """One step's process noise ``z @ root`` (samples, n) with ``root' root = Sigma_W``
    (`psd_factor`, computed once by the caller), or None when ``root`` has no rows
    (Sigma_W = 0: no draws). Time O(samples n r).

    Examples
    --------
    >>> root = psd_factor(np.diag([4.0, 0.0]))          # Sigma_W of rank 1: one draw per sample
    >>> w = sample_step_noise(root, 4000, np.random.default_rng(0))
    >>> w.shape, bool(abs(w[:, 0].var() - 4.0) < 0.3), bool(np.all(w[:, 1] == 0))
    ((4000, 2), True, True)
    >>> print(sample_step_noise(np.zeros((0, 2)), 3, np.random.default_rng(0)))
    None
    """
    return rng.standard_normal((samples, root.shape[0])) @ root if root.shape[0] else None
