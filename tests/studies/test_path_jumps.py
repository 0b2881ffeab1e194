"""studies.paper_figures.path_jumps: where a path of cheapest allocations jumps (its figure breaks the line there)
and where it slides, on cost maps whose cheapest points are known in closed form."""

import numpy as np

from packetloss_cvx.studies.paper_figures import path_jumps

AXIS = np.linspace(0.0, 1.0, 101)
MU1, MU2 = np.meshgrid(AXIS, AXIS)                     # [j, i] = (AXIS[i], AXIS[j])


def two_bowls():
    """J = min(2 + 40 |mu - (0.9, 0.1)|^2, 4 + 40 |mu - (0.1, 0.4)|^2). With beta = (1, 1) the cheapest point of
    {J <= a} is on the first bowl's disc (price 1 - sqrt(2 (a - 2) / 40)) until the second one opens at a = 4,
    whose centre is cheaper (0.5 < 1 - sqrt(2 * 2 / 40) = 0.68): the optimum jumps across the map there, and
    slides on either side of it."""
    first = 2.0 + 40.0 * ((MU1 - 0.9) ** 2 + (MU2 - 0.1) ** 2)
    second = 4.0 + 40.0 * ((MU1 - 0.1) ** 2 + (MU2 - 0.4) ** 2)
    return np.minimum(first, second)


def test_a_jump_between_two_bowls_is_found_and_only_there():
    J = two_bowls()
    assert path_jumps(AXIS, J, (1.0, 1.0), [2.5, 3.0, 3.5, 4.5, 5.0, 6.0]) == [2]      # from 3.5 to 4.5
    assert path_jumps(AXIS, J, (1.0, 1.0), [6.0, 5.0, 4.5, 3.5, 3.0]) == [2]           # either direction


def test_a_slide_along_a_flat_price_is_not_a_jump():
    """A convex cost (one bowl), so the cheapest point slides; with beta = (0.05, 1) the price hardly changes
    along mu1, and the cheapest grid point hops by up to a grid step * 1 / 0.05 = 0.2 along mu1 as the bound
    crosses a grid row in mu2: that is the grid's error, not a jump."""
    J = 2.0 + 30.0 * (1.0 - MU1) ** 2 + 200.0 * (1.0 - MU2) ** 2
    alphas = [2.5, 3.5, 4.78, 6.0, 8.0, 12.0, 20.0, 35.0, 50.0, 70.0, 100.0]
    for beta in [(1.0, 1.0), (0.05, 1.0), (1.0, 0.05)]:
        assert path_jumps(AXIS, J, beta, alphas) == [], beta
