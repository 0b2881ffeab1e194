"""The mean-square radius when a channel never delivers (mu_i = 0): its gain row never acts, whatever its size (the
TCP-like plan's limit at mu = 0 can be 1e190), so the radius is the loop without that actuator; and a gain beyond
the square root of the double range is scaled out without overflowing. References by hand: decoupled scalar loops,
radius max_i (a_i - mu_i k_i)^2 + mu_i (1 - mu_i) k_i^2."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.closedloop.stability import mean_square_radius


def test_a_huge_gain_on_a_channel_that_never_delivers_leaves_the_open_loop_radius():
    assert mean_square_radius([[3.0]], [[1.0]], [[2.6e190]], [0.0]) == pytest.approx(9.0, rel=1e-14)


def test_the_other_channels_still_act():
    A, B, K = np.diag([3.0, 4.0]), np.eye(2), np.diag([2.6e190, 0.4])
    by_hand = max(9.0, (4.0 - 0.5 * 0.4) ** 2 + 0.25 * 0.4 ** 2)          # 14.48
    assert mean_square_radius(A, B, K, [0.0, 0.5]) == pytest.approx(by_hand, rel=1e-13)


def test_a_huge_gain_on_a_rarely_delivering_channel_is_rescaled_without_overflow():
    # x+ = -v k x, mu = 1e-300, k = 1e200: radius mu k^2 = 1e100 (scale^2 = 1e400 overflows if formed first)
    assert mean_square_radius([[0.0]], [[1.0]], [[1e200]], [1e-300]) == pytest.approx(1e100, rel=1e-12)
