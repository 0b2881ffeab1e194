"""Independent references shared by several test files (written without the package's algebra)."""

import itertools

import numpy as np


def enumerated_operator(A, B, K, mu):
    """E[(A - B V K) ⊗ (A - B V K)] over all 2^m delivery patterns: independent of the closed form."""
    out = np.zeros((A.shape[0] ** 2,) * 2)
    for v in itertools.product((0, 1), repeat=len(mu)):
        p = np.prod([m if bit else 1 - m for bit, m in zip(v, mu, strict=True)])
        F = A - B @ np.diag(v) @ K
        out += p * np.kron(F, F)
    return out


def enumerated_radius(A, B, K, mu):
    """The mean-square radius of u = -K x by enumeration: rho of :func:`enumerated_operator`."""
    return float(np.max(np.abs(np.linalg.eigvals(enumerated_operator(A, B, K, mu)))))
