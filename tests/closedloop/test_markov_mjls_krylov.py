"""The MJLS mean-square radius without the dense operator: ARPACK on the coupled map, checked by proven
Collatz–Wielandt bounds, against the dense eigenvalues (small sizes) and against the Bernoulli operator of
simulation/stability.py (memoryless chains, beyond the dense limit); the dense operator refused in advance."""

import numpy as np
import pytest

from packetloss_cvx.closedloop.mjls import MAX_OPERATOR_DIM, mean_square_radius, second_moment_operator
from packetloss_cvx.closedloop.stability import mean_square_radius as bernoulli_radius
from packetloss_cvx.errors import ResourceError
from packetloss_cvx.model.channel import GilbertElliott


def case(seed, n, m, scale=1.0):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= scale / max(abs(np.linalg.eigvals(A)))
    B, K = rng.normal(size=(n, m)), rng.normal(size=(2**m, m, n)) * 0.3
    ch = GilbertElliott(p=rng.uniform(0.05, 0.4, m), r=rng.uniform(0.1, 0.6, m), h_good=rng.uniform(0.6, 1, m),
                        h_bad=rng.uniform(0, 0.4, m))
    return A, B, K, ch


@pytest.mark.parametrize(("seed", "n", "m"), [(401, 3, 1), (402, 4, 2), (403, 6, 3), (404, 9, 2)])
@pytest.mark.parametrize("delivery", ["current", "next"])
def test_krylov_matches_the_dense_eigenvalues(seed, n, m, delivery):
    A, B, K, ch = case(seed, n, m)
    dense = mean_square_radius(A, B, ch, K, delivery, method="dense")
    assert mean_square_radius(A, B, ch, K, delivery, method="krylov") == pytest.approx(dense, rel=1e-10)


def test_dense_operator_is_refused_in_advance_naming_its_size():
    A, B, K, ch = case(405, 12, 4)          # 16 modes * 144 = 2304 rows
    assert 16 * 144 > MAX_OPERATOR_DIM
    with pytest.raises(ResourceError, match="2304 rows"):
        second_moment_operator(A, B, ch, K)
    with pytest.raises(ResourceError, match="2304 rows"):
        mean_square_radius(A, B, ch, K, method="dense")


def test_beyond_the_dense_limit_a_memoryless_chain_gives_the_bernoulli_radius():
    rng = np.random.default_rng(406)
    n, m = 24, 2                             # 4 modes * 576 = 2304 rows: no dense route
    A = rng.normal(size=(n, n))
    A *= 0.95 / max(abs(np.linalg.eigvals(A)))
    B, K = rng.normal(size=(n, m)), rng.normal(size=(m, n)) * 0.1
    r = np.array([0.7, 0.35])
    ch = GilbertElliott(p=1 - r, r=r)
    reference = bernoulli_radius(A, B, K, r, method="krylov")
    assert mean_square_radius(A, B, ch, K) == pytest.approx(reference, rel=1e-9)
    assert mean_square_radius(A, B, ch, K, "next") == pytest.approx(reference, rel=1e-9)
