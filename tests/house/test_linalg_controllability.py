"""controllable_split: the Kalman decomposition by an orthogonal staircase, against the PBH test and planted
structure."""

import numpy as np
import pytest
from scipy.stats import ortho_group

from packetloss_cvx.linalg import controllable_split
from packetloss_cvx.tolerances import CONTROLLABILITY_RTOL


def _pbh_uncontrollable_eigenvalues(A, B, tol=1e-8):
    """Eigenvalues lam of A with rank [A - lam I, B] < n (Popov–Belevitch–Hautus), an independent test."""
    n = A.shape[0]
    out = []
    for lam in np.linalg.eigvals(A):
        s = np.linalg.svd(np.hstack([A - lam * np.eye(n), B]), compute_uv=False)
        if s[-1] <= tol * max(1.0, s[0]):
            out.append(lam)
    return np.array(out)


@pytest.mark.parametrize("seed", range(40))
def test_split_finds_the_planted_uncontrollable_part_and_its_eigenvalues(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 7))
    nc = int(rng.integers(0, n))
    m = int(rng.integers(1, 3))
    A = rng.normal(size=(n, n))
    A[nc:, :nc] = 0.0
    B = rng.normal(size=(n, m))
    B[nc:] = 0.0
    Q = ortho_group.rvs(n, random_state=rng)
    split = controllable_split(Q @ A @ Q.T, Q @ B)
    assert split.nc == nc
    assert np.allclose(split.T.T @ split.T, np.eye(n), atol=1e-13)
    assert np.allclose(split.T @ split.A @ split.T.T, Q @ A @ Q.T, atol=1e-12 * np.linalg.norm(A))
    assert np.allclose(split.T @ split.B, Q @ B, atol=1e-12 * np.linalg.norm(B))
    expected = np.sort_complex(np.linalg.eigvals(A[nc:, nc:]))
    found = np.sort_complex(np.linalg.eigvals(split.A_uu)) if split.nc < n else np.array([])
    assert np.allclose(found, expected, atol=1e-9)
    pbh = np.sort_complex(_pbh_uncontrollable_eigenvalues(Q @ A @ Q.T, Q @ B))
    assert np.allclose(pbh, expected, atol=1e-6)
    assert split.uncontrollable_radius == pytest.approx(float(np.abs(expected).max(initial=0.0)), rel=1e-9)


def test_a_mode_no_input_touches_is_split_exactly():
    A = np.diag([0.5, 1.3, 0.9])
    B = np.array([[1.0], [0.0], [1.0]])
    split = controllable_split(A, B)
    assert (split.nc, split.dropped) == (2, 0.0)
    assert split.uncontrollable_radius == 1.3


def test_a_chain_of_integrators_is_controllable_from_its_last_state():
    A = np.eye(4) + np.eye(4, k=1)
    B = np.eye(4)[:, 3:]
    split = controllable_split(A, B)
    assert split.nc == 4
    assert split.uncontrollable_radius == 0.0


def test_threshold_is_relative_to_the_plant_on_both_sides():
    """A coupling of 100x or 3x the threshold counts as reached, one of 0.3x or 1/100 of it does not, at any scale of
    [A, B] (so the threshold moved 10x either way fails here)."""
    for scale in (1e-8, 1.0, 1e8):
        for factor, expected_nc in ((100.0, 2), (3.0, 2), (0.3, 1), (0.01, 1)):
            eps = factor * CONTROLLABILITY_RTOL
            A = scale * np.array([[0.5, 0.0], [eps, 1.2]])
            B = scale * np.array([[1.0], [0.0]])
            norm = np.linalg.norm(np.hstack([A, B]) / scale, 2)
            A[1, 0] *= norm                                   # eps relative to ||[A, B]||
            assert controllable_split(A, B).nc == expected_nc, (scale, factor)
