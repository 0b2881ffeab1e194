"""recursion_cost, the one forward referee (recursion.forward_cost on a batch of one), against two independent
references: a step-by-step forward pass written out here, and the paper's dense quadratic form
(costs.dense_cost), including channels with mu = 0 or 1 (the loss-variance term skips perfect channels) and many
actuators. Every term of the forward sum is nonnegative, so the batched order of summation moves it by a few
units in the last place only: 1e-14 relative. plan_cost's rounding bound against the exact rational cost of
the float plan: a forward pass that rounding has not resolved is refused (NumericalError), never returned."""

from fractions import Fraction

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.lq.costs import dense_cost
from packetloss_cvx.lq.recursion import plan_cost, recursion_cost, udp_variance_weights
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import PLAN_COST_RTOL
from tests.references import exact_plan_cost


def step_by_step(system, inputs, protocol):
    A, B, W, mu, psi = system.A, system.B, system.state_weights, system.mu_schedule, system.input_weights
    d, noise = udp_variance_weights(system)
    x = system.x0.copy()
    total = float(x @ system.initial_weight @ x) + noise
    for t in range(system.horizon):
        u = inputs[t]
        mean_u = mu[t] * u
        total += float(np.sum(mean_u * (psi[t] * u)))
        if protocol == "udp":
            lossy = mu[t] < 1.0
            total += float(np.sum((mean_u * ((1.0 - mu[t]) * d[t] * u))[lossy]))
        x = A @ x + B @ (mu[t] * u)
        total += float(x @ W[t] @ x)
    return total


@pytest.mark.parametrize("seed", range(40))
def test_forward_cost_equals_the_step_by_step_pass_and_the_dense_form(seed):
    rng = np.random.default_rng(seed)
    s = random_system(rng, m=int(rng.integers(1, 12)) if seed % 3 == 0 else None, edge_mu=bool(seed % 2),
                      non_stationary=bool(seed % 5 == 0))
    U = rng.normal(size=(s.horizon, s.m)) * 10 ** rng.uniform(-3, 3)
    for protocol in ("tcp", "udp"):
        value = recursion_cost(s, U, protocol)
        assert value == pytest.approx(step_by_step(s, U, protocol), rel=1e-14, abs=0)
        assert value == pytest.approx(dense_cost(s, U, protocol), rel=1e-9, abs=0)


def test_forward_cost_by_hand():
    s = System(A=[[1.0]], B=[[1.0, 1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0, 2.0], mu=[0.5, 1.0],
               x0=[1.0])
    U = np.array([[1.0, -1.0], [0.0, 0.0]])
    # x1 = 1 + 0.5 - 1 = 0.5, x2 = 0.5; inputs 0.5 * 1 + 1 * 2 = 2.5; UDP adds 0.5 * 0.5 * (B'S_0 B = 2) * 1 = 0.5
    assert recursion_cost(s, U, "tcp") == 0.25 + 0.25 + 2.5
    assert recursion_cost(s, U, "udp") == 0.25 + 0.25 + 2.5 + 0.5


def _pendulum_over(N: int) -> pl.System:
    data = pl.load_example("pendulum").to_dict()
    data["cost"]["horizon"] = N
    return system_from_dict(data)


def test_expected_cost_of_the_pendulums_plan_over_2000_steps_raises():
    """The closed form's plan steers the unstable pendulum (rho(A) = 1.061) to zero, so its states rolled out open
    loop carry its rounding amplified 1.061^t: a forward pass gives 1.48e80 where the optimum is 25445. The exact
    open-loop cost of that float plan (fractions, 7 minutes) is 1.4687e80; the forward pass is off by 1.1e78, which
    the bound says (1.1097728365937e78 against the true 1.1097728365867e78). expected_cost raises NumericalError
    saying why and what to use; the closed form's own cost is unaffected."""
    s = _pendulum_over(2000)
    sol = pl.closed_form(s, "tcp")
    assert sol.method == "recursion"
    for method in ("auto", "recursion"):
        with pytest.raises(pl.NumericalError, match=r"not resolved(.|\n)*open-loop growth of A(.|\n)*closed_form"):
            pl.expected_cost(s, sol.inputs, "tcp", method=method)
    with pytest.raises(pl.NumericalError, match="condition estimate"):
        pl.expected_cost(s, sol.inputs, "tcp", method="dense")
    with pytest.raises(pl.NumericalError, match="not resolved"):
        recursion_cost(s, sol.inputs, "tcp")
    value, bound = plan_cost(s, sol.inputs, "tcp")
    # the float plan, hence the forward pass's error, depends on the BLAS kernel: the bound is 0.75 % of the value
    # under Haswell (the docstring's measurement, the true error to 6e-12 relative) and 0.083 % under Prescott
    assert bound > 1e-4 * value


def test_a_refused_plan_cost_was_in_fact_inaccurate():
    """The pendulum over 500 steps: its forward pass is off by 7.7e-7 (relative, against the exact rational cost of
    the float plan), and it is refused; the bound is within 1e-5 of the true error."""
    s = _pendulum_over(500)
    U = pl.closed_form(s, "tcp").inputs
    exact = exact_plan_cost(s, U, np.broadcast_to(s.input_weights, U.shape))
    value, bound = plan_cost(s, U, "tcp")
    error = abs(Fraction(value) - exact)
    assert error > Fraction(PLAN_COST_RTOL) * exact
    assert error <= Fraction(bound) <= error * Fraction(1 + 1e-5)
    with pytest.raises(pl.NumericalError, match="not resolved"):
        pl.expected_cost(s, U, "tcp")


def _held(N: int, psi: float) -> tuple[pl.System, np.ndarray]:
    """x_t = 0.1 held by u_t = -0.2 on a = 3 (0.2 is 2 x 0.1 in binary too, so 3 x 0.1 - 0.2 is 0.1 exactly): the
    exact states never move; the rolled-out ones drift from the first step's rounding, times 3^t."""
    s = pl.System(A=[[3.0]], B=[[1.0]], horizon=N, state_weight=[1.0], input_weight=[psi], mu=[1.0], x0=[0.1])
    return s, np.full((N, 1), -0.2)


@pytest.mark.parametrize(("psi", "resolved"), [(40.0, True), (4.0, False)])
def test_plan_cost_tolerance_is_pinned_on_both_sides(psi, resolved):
    """The held plan over 20 steps: rounding moves its rolled-out cost by 9.68e-9 (against fractions). With psi = 40
    the cost is 32.2: 3.0e-10 relative, inside PLAN_COST_RTOL = 1e-9 (returned) and outside a band 10x tighter; with
    psi = 4 it is 3.4: 2.8e-9, outside (refused) and inside a band 10x wider. Either verdict is the true error's
    (the bound is within 1e-5 of it)."""
    s, U = _held(20, psi)
    exact = exact_plan_cost(s, U, np.full(U.shape, psi))
    value, bound = plan_cost(s, U, "tcp")
    error = abs(Fraction(value) - exact)
    assert error <= Fraction(bound) <= error * Fraction(1.001)
    assert Fraction(PLAN_COST_RTOL / 10) * exact < error < Fraction(PLAN_COST_RTOL * 10) * exact
    if resolved:
        assert error <= Fraction(PLAN_COST_RTOL) * exact
        assert pl.expected_cost(s, U, "tcp") == value
        assert recursion_cost(s, U, "tcp") == value
    else:
        assert error > Fraction(PLAN_COST_RTOL) * exact
        for evaluate in (pl.expected_cost, recursion_cost):
            with pytest.raises(pl.NumericalError, match="not resolved"):
                evaluate(s, U, "tcp")
