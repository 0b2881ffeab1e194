"""Sweeps on Dask: a LocalCluster over loopback TCP (in this process) gives the in-process arrays bit for
bit, through a scheduler address or a Client; a worker's error comes back with its own type."""

import importlib.util
import logging

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.studies import sweep

#: the file needs Dask's distributed; it is imported by the first test that uses it (0.3 s at collection otherwise,
#: paid by every xdist worker whether or not it runs this file)
pytestmark = pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="needs distributed")


@pytest.fixture(scope="module")
def distributed():
    import distributed
    return distributed


@pytest.fixture(scope="module")
def cluster(distributed):
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp",
                                  host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR) as c:
        yield c


def _same(a, b):
    assert a.arrays().keys() == b.arrays().keys()
    for key, value in a.arrays().items():
        assert np.array_equal(value, b.arrays()[key]), key


def test_dask_over_loopback_is_bit_identical(cluster, two_actuator):
    assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
    here = sweep(two_actuator, mu_grid=13, chunk_size=20, progress=False)
    there = sweep(two_actuator, mu_grid=13, chunk_size=20, dask=cluster.scheduler_address, progress=False)
    _same(here, there)
    # the reference is independent of both: the QP twin at a corner of the grid
    qp = pl.solve_qp(two_actuator.with_mu([1.0, 0.0]), "udp", with_gain=False, cross_check=False).cost
    assert there.costs["udp"].reshape(13, 13)[0, 12] == pytest.approx(qp, rel=1e-6)


def test_dask_client_and_other_sweeps(cluster, pendulum, distributed):
    with distributed.Client(cluster) as client:
        for kwargs in ({"x0_scales": [0.5, 1.0, 2.0]}, {"horizons": [5, 20, 40]}, {"mu_grid": 7}):
            _same(sweep(pendulum, chunk_size=2, progress=False, **kwargs),
                  sweep(pendulum, chunk_size=2, dask=client, progress=False, **kwargs))


def test_stability_on_dask_is_bit_identical(cluster, two_actuator):
    here = sweep(two_actuator, mu_grid=4, chunk_size=5, stability=True, progress=False)
    there = sweep(two_actuator, mu_grid=4, chunk_size=5, stability=True, dask=cluster.scheduler_address,
                  progress=False)
    _same(here, there)
    assert "radius_tcp" in there.arrays()


def test_a_worker_error_keeps_its_type(cluster):
    # badly scaled weights: every closed form refuses them (NumericalError), on the worker as here
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1e12], input_weight=[1e-6], mu=[0.5], x0=[1.0])
    try:
        pl.closed_form(s, "tcp")
    except pl.NumericalError:
        with pytest.raises(pl.NumericalError):
            sweep(s, mu_grid=3, dask=cluster.scheduler_address, progress=False)
    else:
        pytest.skip("this system is not refused here")


def test_workers_only_with_a_local_cluster(cluster, two_actuator):
    with pytest.raises(pl.InputError, match="^workers: applies to dask='local' only"):
        sweep(two_actuator, mu_grid=2, dask=cluster.scheduler_address, workers=3, progress=False)


@pytest.mark.parametrize("dask", [3, "local-ish", "no address"])
def test_bad_dask_argument(two_actuator, dask):
    with pytest.raises(pl.InputError) as info:
        sweep(two_actuator, mu_grid=2, dask=dask, progress=False)
    assert info.value.field == "dask"


def test_the_dask_docs_example_grid_is_within_the_sweep_cap():
    # was: docs/dask.md ran sweep(system, mu_grid=1001, ...): 1001^2 > MAX_SWEEP_POINTS, an InputError
    import re
    from pathlib import Path

    from packetloss_cvx.studies.design import MAX_SWEEP_POINTS

    text = (Path(__file__).resolve().parents[1] / "docs" / "dask.md").read_text()
    sizes = [int(k) for k in re.findall(r"mu_grid=(\d+)", text) + re.findall(r"--mu-grid (\d+)", text)]
    assert sizes
    assert all(k * k <= MAX_SWEEP_POINTS for k in sizes), sizes


def test_an_unreachable_scheduler_is_one_line_and_no_wait():
    # the failed client is closed at once: it used to wait 20 s at exit, then print a 9-line Client.__del__ traceback
    import os
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, "-m", "packetloss_cvx", "sweep", "two_actuator", "--mu-grid", "3",
                           "--dask", "http://example.invalid:8786"], capture_output=True, text=True, check=False,
                          timeout=120, env=dict(os.environ))
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("packetloss-cvx: error: --dask: cannot reach")
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr


#: the no-worker timeout the test sets (the product's is NO_WORKER_TIMEOUT, 60 s): the test waits it out, so it
#: is short; above POLL_FIRST_SECONDS, so the clock is read several times before it runs out
NO_WORKER_WAIT = 0.25


def test_a_scheduler_without_workers_stops_the_sweep(two_actuator, monkeypatch, distributed):
    # the last worker killed (or none joined): the sweep used to wait for ever
    from packetloss_cvx.studies import engine
    monkeypatch.setattr(engine, "NO_WORKER_TIMEOUT", NO_WORKER_WAIT)
    with distributed.LocalCluster(n_workers=0, processes=False, protocol="tcp", host="127.0.0.1",
                                  dashboard_address=":0", silence_logs=logging.ERROR) as empty:
        with pytest.raises(pl.InputError, match=f"no worker for {NO_WORKER_WAIT:g} s") as info:
            sweep(two_actuator, mu_grid=3, dask=empty.scheduler_address, progress=False)
    assert info.value.field == "dask" and "0 of 1 chunks done" in str(info.value)
