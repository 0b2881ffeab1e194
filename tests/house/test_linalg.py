"""linalg's thresholds, each pinned on both sides: solve_checked's residual (DENSE_RESIDUAL_RTOL) and psd_factor's
cut (PSD_FACTOR_RTOL). A case 3 times outside the band is refused (dropped), 0.3 times inside kept. (controllable_split
has its own file, tests/house/test_linalg_controllability.py.)"""

import numpy as np
import pytest

from packetloss_cvx.errors import NumericalError
from packetloss_cvx.linalg import psd_factor, solve_checked
from packetloss_cvx.tolerances import DENSE_RESIDUAL_RTOL, PSD_FACTOR_RTOL


@pytest.mark.parametrize("columns", [1, 3])
@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_solve_checked_refuses_3_and_keeps_0_3_times_dense_residual_rtol(monkeypatch, columns, factor, kept):
    """The LU solve returned X whose residual ||G X - rhs|| is factor DENSE_RESIDUAL_RTOL (||G|| ||X|| + ||rhs||)
    (Frobenius norms), on a well-conditioned G (cond < 10) so that the planted residual is the residual to 1e-15."""
    rng = np.random.default_rng(0)
    G = np.eye(6) + 0.1 * rng.normal(size=(6, 6))
    rhs = rng.normal(size=(6, columns)) if columns > 1 else rng.normal(size=6)
    exact = np.linalg.solve(G, rhs)
    r = rng.normal(size=rhs.shape)
    scale = np.linalg.norm(G) * np.linalg.norm(exact) + np.linalg.norm(rhs)
    r *= factor * DENSE_RESIDUAL_RTOL * scale / np.linalg.norm(r)
    off = exact + np.linalg.solve(G, r)
    assert np.linalg.cond(G) < 10
    monkeypatch.setattr(np.linalg, "solve", lambda a, b: off)
    if kept:
        assert np.array_equal(solve_checked(G, rhs, "G"), off)
    else:
        with pytest.raises(NumericalError, match="G: the dense solve lost its accuracy"):
            solve_checked(G, rhs, "G")


@pytest.mark.parametrize("scale", [1e-20, 1.0, 1e20])
@pytest.mark.parametrize(("factor", "kept"), [(3.0, True), (0.3, False)])
def test_psd_factor_keeps_3_and_drops_0_3_times_psd_factor_rtol_relative_to_the_largest(scale, factor, kept):
    """An eigenvalue 3 PSD_FACTOR_RTOL times the largest is kept, one 0.3 times is dropped (L'L = W to rounding either
    way), at any scale of W (the cut is relative: a weight of 1e-20 keeps its small direction)."""
    Q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    W = scale * (Q * [1.0, 0.5, factor * PSD_FACTOR_RTOL]) @ Q.T
    L = psd_factor(0.5 * (W + W.T))
    assert L.shape == ((3, 3) if kept else (2, 3))
    assert np.abs(L.T @ L - W).max() <= 1e-14 * scale          # the dropped direction weighed 3e-15 of W at most
