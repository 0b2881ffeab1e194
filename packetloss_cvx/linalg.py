"""Small linear-algebra helpers shared by the evaluators."""

from __future__ import annotations

import numpy as np

from .tolerances import PSD_FACTOR_RTOL

__all__ = ["psd_factor"]


def psd_factor(W: np.ndarray) -> np.ndarray:
    """L with L'L = W for a symmetric PSD W (eigen-decomposition; zero rows dropped)."""
    vals, vecs = np.linalg.eigh(W)
    keep = vals > PSD_FACTOR_RTOL * max(1.0, float(vals.max(initial=0.0)))
    return np.sqrt(vals[keep])[:, None] * vecs[:, keep].T
