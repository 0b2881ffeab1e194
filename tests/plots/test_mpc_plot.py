"""plot_mpc (and MPCSimulation.plot) draws the trajectories and frequencies it is given: a simulation built by hand
(no solve), its lines and error bars read back from the figure."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from packetloss_cvx.errors import InputError
from packetloss_cvx.plots import plot_mpc
from packetloss_cvx.results.mpc import ControllerRun, Frequency, MPCSimulation

STEPS = 3
LABELS = ["clipped LQ law", "certainty-equivalent MPC", "expected-cost MPC"]


def _frequency(name, worst, ci, allowed=0.0, runs=10, runs_with=0, runs_ci=(0.0, 0.3)):
    return Frequency(name=name, allowed=allowed, step_counts=np.zeros(STEPS, int), runs=runs, count=0, frequency=0.0,
                     worst_step=0, worst_frequency=worst, worst_ci=ci, runs_with=runs_with, runs_ci=runs_ci,
                     confidence=0.95)


def _run(name, offset, keep=2, applied=False):
    states = offset + np.arange(keep * (STEPS + 1) * 2, dtype=float).reshape(keep, STEPS + 1, 2)
    inputs = -offset - np.arange(keep * STEPS, dtype=float).reshape(keep, STEPS, 1)
    # what a holding actuator applied: the command, except the previous one at the first run's lost step 1
    played = inputs.copy()
    played[:1, 1] = inputs[:1, 0]
    violations = (_frequency("u_max[0]", 0.0, (0.0, 0.3)),
                  _frequency("x_max[1]", 0.1 * offset, (0.0, 0.5)),
                  _frequency("chance[0]", 0.2 * offset - 0.1, (0.1, 0.6), allowed=0.1, runs_with=4, runs_ci=(0.2, 0.7)))
    return ControllerRun(controller=name, protocol="tcp", mean_stage_cost=1.0, stderr=0.1,
                         stage_cost_mean=np.ones(STEPS), violations=violations,
                         infeasible=None if name == "clipped" else _frequency("infeasible", 0.3, (0.1, 0.6)),
                         fallback_steps=0, failed_steps=0, slack_steps=0, action="", states=states, inputs=inputs,
                         applied=played if applied else None)


def _sim(keep=2, actuator="zero"):
    runs = {name: _run(name, k + 1.0, keep, actuator != "zero")
            for k, name in enumerate(["clipped", "certainty-equivalent", "expected-cost"])}
    delivered = np.ones((keep, STEPS, 1), bool)
    delivered[:1, 1, 0] = False
    constraints = {"u_min": [-2.0], "u_max": [2.0], "x_max": [np.inf, 5.0], "chance": [[[0.0, -2.0], 1.0, 0.1]]}
    return MPCSimulation(samples=10, steps=STEPS, seed=0, channel="gilbert-elliott", constraints=constraints,
                         runs={"tcp": runs}, delivered=delivered if keep else None, actuator=actuator)


def test_the_trajectories_limits_and_losses_are_drawn():
    sim = _sim()
    fig = sim.plot(state=1)
    assert isinstance(fig, Figure)
    assert fig.get_suptitle() == "TCP-like controllers over a Gilbert–Elliott link: 2 of 10 runs drawn"
    top = [ax for ax in fig.axes if ax.get_ylabel() == "state $x_{2}$"][0]
    assert top.get_title() == "clipped LQ law"
    run = sim.runs["tcp"]["clipped"]
    drawn = [line.get_ydata().tolist() for line in top.lines if line.get_linewidth() in (0.8, 2.0)]
    assert drawn == [run.states[1, :, 1].tolist(), run.states[0, :, 1].tolist()]          # the first run last
    levels = sorted(line.get_ydata()[0] for line in top.lines if line.get_linestyle() in ("--", ":"))
    assert levels == [-0.5, 5.0]                 # x_max[1] dashed; the chance row -2 x2 <= 1 is x2 >= -0.5, dotted
    spans = [p.get_x() for p in top.patches]
    assert spans == [1.0]                        # the first run's packet lost at step 1: [1, 2] shaded


def _input_panels(fig):
    return [ax for ax in fig.axes if ax.get_xlabel() == "step t" and not ax.get_title()]


def _drawn(ax):
    return [line.get_ydata().tolist() for line in ax.lines if line.get_linewidth() in (0.8, 2.0)]


def test_under_zero_the_commanded_inputs_are_drawn_and_labelled_so():
    sim = _sim()
    panels = _input_panels(sim.plot())
    assert [ax.get_ylabel() for ax in panels] == ["commanded $u_{1}$", "", ""]
    for ax, run in zip(panels, sim.runs["tcp"].values(), strict=True):
        # the first run last, on top
        assert _drawn(ax) == [run.inputs[1, :, 0].tolist(), run.inputs[0, :, 0].tolist()]


def test_under_hold_the_applied_inputs_are_drawn_and_labelled_so():
    sim = _sim(actuator="hold")
    fig = sim.plot()
    assert fig.get_suptitle() == ("TCP-like controllers over a Gilbert–Elliott link, actuator hold: "
                                  "2 of 10 runs drawn")
    panels = _input_panels(fig)
    assert [ax.get_ylabel() for ax in panels] == ["applied $u_{1}$", "", ""]
    for k, (ax, run) in enumerate(zip(panels, sim.runs["tcp"].values(), strict=True)):
        offset = k + 1.0
        # by hand: the first run commanded -offset - (0, 1, 2); the actuator held -offset at the lost step 1
        assert _drawn(ax) == [run.inputs[1, :, 0].tolist(), [-offset, -offset, -offset - 2]]


def test_the_frequencies_are_drawn_with_their_intervals():
    sim = _sim()
    rates = next(ax for ax in sim.plot().axes if ax.get_title().startswith("Violations at the worst step"))
    labels = [t.get_text() for t in rates.get_yticklabels()]
    assert labels == ["x2 > 5\n(limit on E[x2])", "x2 < -0.5\n(chance row 1, eps 0.1)", "hard program\ninfeasible"]
    points = {}
    for container in rates.containers:
        x, y = container.lines[0].get_xydata()[0]
        (bars,) = container.lines[2]
        (lo, _), (hi, _) = bars.get_segments()[0]
        row = int(round(y))
        k = int(round((y - row + 0.4) / (0.8 / 3) - 0.5))          # the controller's slot within the row
        points[(LABELS[k], row)] = (x, lo, hi)
    assert points[("certainty-equivalent MPC", 1)] == pytest.approx((0.3, 0.1, 0.6))
    assert points[("expected-cost MPC", 0)] == pytest.approx((0.3, 0.0, 0.5))
    assert points[("expected-cost MPC", 2)] == pytest.approx((0.3, 0.1, 0.6))
    assert ("clipped LQ law", 2) not in points                                      # the clipped law solves nothing
    eps = [line.get_xdata()[0] for line in rates.lines if line.get_label() == "allowed eps"]
    assert eps == [0.1]
    assert [c.get_label() for c in rates.containers if not c.get_label().startswith("_")] == LABELS
    runs = next(ax for ax in sim.plot(measure="runs").axes if ax.get_title().startswith("Runs with some violation"))
    x, y = runs.containers[1].lines[0].get_xydata()[0]                              # the clipped law's chance row
    assert (x, y) == pytest.approx((0.4, 1 - 0.4 + 0.4 / 3))


@pytest.mark.parametrize(("kwargs", "field"), [({"protocol": "udp"}, "protocol"), ({"state": 2}, "state"),
                                               ({"input": 1}, "input"), ({"measure": "mean"}, "measure")])
def test_bad_requests_name_the_field(kwargs, field):
    with pytest.raises(InputError) as err:
        plot_mpc(_sim(), **kwargs)
    assert err.value.field == field


def test_a_simulation_without_trajectories_says_to_keep_some():
    with pytest.raises(InputError, match="keep >= 1") as err:
        _sim(keep=0).plot()
    assert err.value.field == "keep"
