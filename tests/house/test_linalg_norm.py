"""linalg.frobenius: the Frobenius norm at every scale, against math.hypot (scaled, correctly rounded per step)."""

import math

import numpy as np
import pytest

from packetloss_cvx.linalg import frobenius


@pytest.mark.parametrize("scale", [1e-300, 1e-200, 1e-160, 1e-20, 1.0, 1e20, 1e160, 1e200, 1e300])
@pytest.mark.parametrize("seed", range(4))
def test_equals_hypot_at_every_scale(scale, seed):
    X = np.random.default_rng(seed).normal(size=(4, 3)) * scale
    reference = math.hypot(*X.ravel())
    assert frobenius(X) == pytest.approx(reference, rel=1e-15 * X.size)


@pytest.mark.parametrize("seed", range(4))
def test_is_numpys_float_where_the_squares_are_safe(seed):
    X = np.random.default_rng(seed).normal(size=(5, 5)) * 10.0 ** seed
    assert frobenius(X) == float(np.linalg.norm(X))


def test_underflow_and_overflow_that_numpy_does_not_survive():
    X = np.array([[3e-200, 0.0], [0.0, 4e-200]])
    Y = np.array([[3e200, 0.0], [0.0, 4e200]])
    with np.errstate(under="ignore", over="ignore"):
        assert float(np.linalg.norm(X)) == 0.0                   # the squares underflow
        assert float(np.linalg.norm(Y)) == math.inf              # the squares overflow
    assert frobenius(X) == pytest.approx(5e-200, rel=1e-15)
    assert frobenius(Y) == pytest.approx(5e200, rel=1e-15)


def test_zero_empty_and_non_finite():
    assert frobenius(np.zeros((3, 3))) == 0.0
    assert frobenius(np.zeros((0, 2))) == 0.0
    assert frobenius(np.array([1.0, np.inf])) == math.inf
    assert math.isnan(frobenius(np.array([1.0, np.nan])))
