"""Plants the stabilisable-set tests (tests/closedloop/test_region.py) and benchmarks/region_engine.py share: the
scalar and decoupled plants of the hand thresholds, the Jordan chain of Elia's single-input theorem and the seeded
single-input plants of known Mahler measure. Plain constructors (numpy and packetloss_cvx.System only), so the
benchmark loads this one file by path whichever checkout it times."""

import numpy as np

from packetloss_cvx import System


def scalar(a=2.0, b=(1.0,), psi=0.1):
    m = len(b)
    return System(A=[[a]], B=[list(b)], horizon=2, state_weight=[1.0], input_weight=[psi] * m, mu=[1.0] * m,
                  x0=[1.0])


def decoupled(a):
    n = len(a)
    return System(A=np.diag(a), B=np.eye(n), horizon=2, state_weight=[1.0] * n, input_weight=[1.0] * n,
                  mu=[1.0] * n, x0=[1.0] * n)


def chain(a0, n=4):
    """A = a0 I + N (ones on the superdiagonal: one Jordan block), b = e_n: controllable, one input."""
    A = a0 * np.eye(n) + np.eye(n, k=1)
    return System(A=A, B=np.eye(n)[:, n - 1:], horizon=2, state_weight=[1.0] * n, input_weight=[1.0], mu=[1.0],
                  x0=[1.0] * n)


def single_input_plant(rng):
    """A = Q J Q' (Q orthogonal), J block diagonal: Jordan blocks (size 1 to 3) of distinct real eigenvalues and
    perhaps one rotation block, each driven at its last state (b = Q (1 at each block's end)): controllable, one
    input. Returns the plant and its Mahler measure prod |lambda_i|^2 over |lambda_i| >= 1 (exact by construction)."""
    blocks, mahler = [], 1.0
    values = rng.permutation([1.08, 1.25, -1.4, 0.6, -0.3, 0.85, 1.6])[: int(rng.integers(2, 4))]
    for value in values:
        size = int(rng.integers(1, 4))
        blocks.append(value * np.eye(size) + np.eye(size, k=1))
        mahler *= value ** (2 * size) if abs(value) >= 1 else 1.0
    if rng.random() < 0.5:                                   # a complex pair r e^{+-i theta}
        r, theta = float(rng.choice([0.7, 1.15])), float(rng.uniform(0.3, 2.5))
        blocks.append(r * np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]]))
        mahler *= r ** 4 if r >= 1 else 1.0
    n = sum(len(b) for b in blocks)
    J, b, k = np.zeros((n, n)), np.zeros(n), 0
    for block in blocks:
        J[k:k + len(block), k:k + len(block)] = block
        k += len(block)
        b[k - 1] = 1.0
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    s = System(A=Q @ J @ Q.T, B=(Q @ b)[:, None], horizon=2, state_weight=[1.0] * n, input_weight=[1.0], mu=[1.0],
               x0=[1.0] * n)
    return s, mahler
