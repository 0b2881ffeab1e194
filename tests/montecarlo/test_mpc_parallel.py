"""The constrained loop's runs spread over threads and Dask (montecarlo/mpc.py): the same floats as the serial run
on the same seed, the progress bar over the runs, and the ``mpc_solves`` budget refusing a huge run before any path
is drawn.

Reference, not the code under test: the serial run (``threads=1``, no Dask) of the same call, compared float for
float through its whole JSON (every controller's per-step mean stage costs, violation and infeasibility counts per
step, fallbacks)."""

import json
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from packetloss_cvx.budgets import mpc_solves
from packetloss_cvx.errors import BudgetError, InputError
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo import mpc


def _plant(**extra) -> System:
    fields = dict(A=[[1.1, 0.2], [0.0, 0.8]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=4, state_weight=[1.0, 2.0],
                  input_weight=[1.0, 0.5], x0=[1.0, -0.5], noise_cov=[[0.02, 0.0], [0.0, 0.01]])
    return System(**{**dict(mu=[0.7, 0.6]), **fields, **extra})


#: the rate bound binds from rest, the expected-state limit makes some hard programs infeasible (the soft twin runs)
LIMITS = Constraints(u_min=[-1.0, -1.0], u_max=[1.0, 1.0], du_max=[0.15, 0.15], x_max=[1.02, 1e3],
                     chance=[([1.0, 0.0], 1.1, 0.2)])


def _json(sim):
    return json.dumps(sim.to_dict(), sort_keys=True)


def _same_trajectories(a, b):
    """The kept runs' states, commands and deliveries, float for float."""
    assert np.array_equal(a.delivered, b.delivered)
    for protocol, runs in b.runs.items():
        for name, run in runs.items():
            assert np.array_equal(a.runs[protocol][name].states, run.states)
            assert np.array_equal(a.runs[protocol][name].inputs, run.inputs)


@pytest.mark.parametrize("chain", [False, True])
def test_threads_give_the_serial_runs_float_for_float(chain):
    s = _plant(mu=None, channel=GilbertElliott(p=[0.2, 0.3], r=[0.5, 0.6])) if chain else _plant()
    samples = 2 * mpc.CHUNK + 3                             # three chunks, the last one shorter
    args = dict(samples=samples, steps=4, seed=3, progress=False, keep=mpc.CHUNK + 2)    # kept runs span two chunks
    serial = mpc.simulate_mpc(s, LIMITS, **args)
    spread = mpc.simulate_mpc(s, LIMITS, threads=2, **args)
    assert _json(spread) == _json(serial)
    _same_trajectories(spread, serial)
    if not chain:
        assert sum(serial.runs[p]["expected-cost"].fallback_steps for p in ("tcp", "udp")) > 0


def test_a_process_pool_and_a_dask_client_give_the_serial_runs_float_for_float(monkeypatch):
    distributed = pytest.importorskip("distributed")
    s = _plant()
    args = dict(samples=2 * mpc.CHUNK + 3, steps=3, seed=5, progress=False, controllers=["expected-cost"],
                keep=2 * mpc.CHUNK + 1)                     # kept runs reach into the second task
    serial = mpc.simulate_mpc(s, LIMITS, **args)
    monkeypatch.setattr(mpc, "TASK_CHUNKS", 2)             # two tasks per controller: the second one's runs offset
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        pooled = mpc.simulate_mpc(s, LIMITS, dask=pool, **args)
    assert _json(pooled) == _json(serial)
    _same_trajectories(pooled, serial)
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None) as client:
        tasks = mpc.simulate_mpc(s, LIMITS, dask=client, **args)
    assert _json(tasks) == _json(serial)
    _same_trajectories(tasks, serial)


def test_the_progress_bar_counts_every_run_of_every_controller(monkeypatch):
    seen = {}

    class Bar:
        def __init__(self, total, **kwargs):
            seen["total"], seen["done"] = total, 0

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def update(self, n=1):
            seen["done"] += n
    monkeypatch.setattr(mpc, "progress_bar", lambda total, **kwargs: Bar(total, **kwargs))
    mpc.simulate_mpc(_plant(), Constraints(u_max=[1.0, 1.0]), samples=mpc.CHUNK + 1, steps=2, seed=0,
                     protocols=["tcp"], threads=2)
    total = 3 * (mpc.CHUNK + 1)                            # clipped, certainty-equivalent, expected-cost
    assert seen == {"total": total, "done": total}


def test_a_run_beyond_the_budget_is_refused_before_any_path_is_drawn(monkeypatch):
    def no_paths(*args, **kwargs):
        raise AssertionError("paths drawn before the budget was checked")
    monkeypatch.setattr(mpc, "loop_paths", no_paths)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MPC_SOLVES", "40")
    # 10 runs x 4 steps x (2 expected-cost + 1 certainty-equivalent) programs = 120 solves, each 0.366 of a 5 ms solve
    # (N = 4, n = m = 2, 40 linear rows, 1 chance row: tests/montecarlo/test_mpc_budget.py): 43.9 > 40
    assert mpc_solves(10, 4, 3) == 120
    with pytest.raises(BudgetError, match="samples: 10 runs of 4 steps x 3 programs"):
        mpc.simulate_mpc(_plant(), LIMITS, samples=10, steps=4)
    # the clipped law solves nothing: within the budget whatever the runs
    monkeypatch.setattr(mpc, "loop_paths", lambda *a: (np.ones((4, 10, 2)), None))
    sim = mpc.simulate_mpc(_plant(), LIMITS, samples=10, steps=4, controllers=["clipped"], progress=False)
    assert sim.runs["tcp"]["clipped"].infeasible is None


def test_bad_spreading_arguments_name_their_field():
    with pytest.raises(InputError, match="threads"):
        mpc.simulate_mpc(_plant(), LIMITS, samples=2, steps=1, threads=0)
    with pytest.raises(InputError, match="dask"):
        mpc.simulate_mpc(_plant(), LIMITS, samples=2, steps=1, dask="local")


def test_every_kept_run_across_chunks_is_the_run_the_summaries_count():
    # noise-free: each kept run obeys x' = A x + B (v * u) from x0, and the kept runs (all of them) give back the
    # per-step mean stage cost x'Qx + (v u)'R(v u) the summaries report
    s = _plant(noise_cov=None)
    samples = 2 * mpc.CHUNK + 3
    sim = mpc.simulate_mpc(s, LIMITS, samples=samples, steps=3, seed=2, progress=False, keep=samples, threads=2,
                           controllers=["expected-cost"], protocols=["udp"])
    run, v = sim.runs["udp"]["expected-cost"], sim.delivered
    X, U = run.states, run.inputs
    assert np.array_equal(X[:, 0], np.repeat(s.x0[None], samples, axis=0))
    applied = v * U
    np.testing.assert_allclose(X[:, 1:], X[:, :-1] @ s.A.T + applied @ s.B.T, rtol=1e-13, atol=1e-15)
    Q, R = s.state_weights[0], s.input_weights[0]
    stage = np.einsum("rti,ij,rtj->rt", X[:, :-1], Q, X[:, :-1]) + (applied ** 2) @ R
    np.testing.assert_allclose(run.stage_cost_mean, stage.mean(axis=0), rtol=1e-13)
    assert len({X[r, -1].tobytes() for r in range(samples)}) > samples // 2        # the runs differ
    # keeping fewer, ending inside the second chunk: the same first runs
    some = mpc.CHUNK + 2
    part = mpc.simulate_mpc(s, LIMITS, samples=samples, steps=3, seed=2, progress=False, keep=some,
                            controllers=["expected-cost"], protocols=["udp"]).runs["udp"]["expected-cost"]
    assert np.array_equal(part.states, X[:some])
    assert np.array_equal(part.inputs, U[:some])
