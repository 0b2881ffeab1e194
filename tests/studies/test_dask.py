"""Sweeps on Dask: a LocalCluster over loopback TCP (in this process) gives the in-process arrays bit for
bit, through a scheduler address or a Client; a worker's error comes back with its own type."""

import importlib.util
import logging
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.studies import sweep

#: the file needs Dask's distributed; it is imported by the first test that uses it (0.3 s at collection otherwise,
#: paid by every xdist worker whether or not it runs this file)
pytestmark = pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="needs distributed")

ROOT = Path(__file__).resolve().parents[2]


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


def test_a_worker_error_keeps_its_type(cluster, two_actuator, monkeypatch):
    """A typed error raised inside a Dask task reaches the caller with its own type and message. The error is
    planted in the chunk evaluation (the cluster's workers are threads of this process, so they see the patch) and
    names the thread that raised it: a worker's, not this one's."""
    from packetloss_cvx.studies import engine

    def refuse(system_data):
        raise pl.NumericalError(f"planted refusal on thread {threading.current_thread().name!r}")

    monkeypatch.setattr(engine, "system_from_dict", refuse)
    with pytest.raises(pl.NumericalError, match="^planted refusal on thread") as info:
        sweep(two_actuator, mu_grid=3, dask=cluster.scheduler_address, progress=False)
    assert repr(threading.main_thread().name) not in str(info.value)


def test_workers_only_with_a_local_cluster(cluster, two_actuator):
    with pytest.raises(pl.InputError, match="^workers: applies to dask='local' only"):
        sweep(two_actuator, mu_grid=2, dask=cluster.scheduler_address, workers=3, progress=False)


@pytest.mark.parametrize("dask", [3, "local-ish", "no address"])
def test_bad_dask_argument(two_actuator, dask):
    with pytest.raises(pl.InputError) as info:
        sweep(two_actuator, mu_grid=2, dask=dask, progress=False)
    assert info.value.field == "dask"


def test_the_dask_docs_example_grid_is_within_the_sweep_cap():
    # every grid the page shows runs: mu_grid^2 points within MAX_SWEEP_POINTS (else the example is an InputError)
    import re
    from pathlib import Path

    from packetloss_cvx.studies.design import MAX_SWEEP_POINTS

    text = (Path(__file__).resolve().parents[2] / "docs" / "dask.md").read_text()
    sizes = [int(k) for k in re.findall(r"mu_grid=(\d+)", text) + re.findall(r"--mu-grid (\d+)", text)]
    assert sizes
    assert all(k * k <= MAX_SWEEP_POINTS for k in sizes), sizes


def test_an_unreachable_scheduler_is_one_line_and_no_wait():
    # the failed client is closed at once: no 20 s wait at exit, no Client.__del__ traceback
    import os
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, "-m", "packetloss_cvx", "sweep", "two_actuator", "--mu-grid", "3",
                           "--dask", "http://example.invalid:8786"], capture_output=True, text=True, check=False,
                          timeout=120, env=dict(os.environ))
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1
    assert proc.stderr.startswith("packetloss-cvx: error: --dask: cannot reach")
    assert "Traceback" not in proc.stderr
    assert "Exception ignored" not in proc.stderr


#: the no-worker timeout the test sets (the product's is NO_WORKER_TIMEOUT, 60 s): the test waits it out, so it
#: is short; above POLL_FIRST_SECONDS, so the clock is read several times before it runs out
NO_WORKER_WAIT = 0.25


def test_a_scheduler_without_workers_stops_the_sweep(two_actuator, monkeypatch, distributed):
    # the last worker killed (or none joined): the sweep stops with an error instead of waiting for ever
    from packetloss_cvx.studies import engine
    monkeypatch.setattr(engine, "NO_WORKER_TIMEOUT", NO_WORKER_WAIT)
    with distributed.LocalCluster(n_workers=0, processes=False, protocol="tcp", host="127.0.0.1",
                                  dashboard_address=":0", silence_logs=logging.ERROR) as empty:
        with pytest.raises(pl.InputError, match=f"no worker for {NO_WORKER_WAIT:g} s") as info:
            sweep(two_actuator, mu_grid=3, dask=empty.scheduler_address, progress=False)
    assert info.value.field == "dask"
    assert "0 of 1 chunks done" in str(info.value)


def _session(sid):
    """The processes of session ``sid`` (the command and every process it started), from /proc: pid -> cmdline."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = open(f"/proc/{entry}/stat").read()
            cmdline = open(f"/proc/{entry}/cmdline").read().replace("\0", " ")
        except OSError:          # gone meanwhile
            continue
        fields = stat[stat.rindex(")") + 2:].split()     # after "pid (comm) ": state, ppid, pgrp, session, ...
        if int(fields[3]) == sid and fields[0] != "Z":
            found[int(entry)] = cmdline
    return found


#: a signal as a terminal sends Ctrl-C (to the whole foreground process group: the workers too) or as `kill PID`
SENDS = {"group": os.killpg, "pid": os.kill}


@pytest.mark.skipif(not os.path.isdir("/proc") or not hasattr(os, "killpg"), reason="needs /proc and process groups")
def test_a_signal_during_a_local_dask_sweep_is_one_line_and_leaves_no_process(tmp_path):
    """``sweep --dask local`` stopped by SIGINT (Ctrl-C: the whole process group, workers included, or the command's
    pid alone) or SIGTERM at seeded moments after its two workers are started: exit 130 / 143, exactly one stderr
    line, no traceback, each file written complete, and no process of the run left. The workers must not hear a
    Ctrl-C themselves (KeyboardInterrupt tracebacks from their imports and loops, 50-90 lines) nor log heartbeat
    failures while the cluster is torn down."""
    rng = random.Random(9)
    cases = [(how, signum, rng.uniform(lo, hi)) for how, signum, lo, hi in
             [("group", signal.SIGINT, 0.0, 0.6), ("group", signal.SIGINT, 0.6, 2.0),
              ("group", signal.SIGTERM, 0.0, 2.0), ("pid", signal.SIGINT, 1.0, 2.5),
              ("pid", signal.SIGINT, 1.5, 3.0), ("pid", signal.SIGTERM, 0.5, 2.5)]]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    results = {}

    def one(k, how, signum, delay):
        folder = tmp_path / str(k)
        folder.mkdir()
        proc = subprocess.Popen([sys.executable, "-m", "packetloss_cvx", "sweep", "two_actuator", "--mu-grid", "201",
                                 "--dask", "local", "--workers", "2", "--out", "run", "-q"], cwd=folder, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        end = time.monotonic() + 60
        while (proc.poll() is None and time.monotonic() < end
               and sum("spawn_main" in line for line in _session(proc.pid).values()) < 2):
            time.sleep(0.01)
        time.sleep(delay)
        alive = proc.poll() is None
        if alive:
            SENDS[how](proc.pid, signum)
        out, err = proc.communicate(timeout=60)
        end = time.monotonic() + 10            # a worker notices its parent gone within a moment
        while _session(proc.pid) and time.monotonic() < end:
            time.sleep(0.05)
        results[k] = (alive, proc.returncode, err, _session(proc.pid), folder / "run")

    for start in range(0, len(cases), 2):        # two at a time: two cores, shared
        threads = [threading.Thread(target=one, args=(start + j, *case))
                   for j, case in enumerate(cases[start:start + 2])]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    interrupted = 0
    for k, (how, signum, delay) in enumerate(cases):
        alive, code, err, left, run = results[k]
        where = (how, signal.Signals(signum).name, round(delay, 3), code, err[-800:])
        assert left == {}, where
        assert "Traceback" not in err, where
        if (run / "sweep.npz").exists():          # written atomically: complete, with the whole grid
            with np.load(run / "sweep.npz") as data:
                assert data["cost_tcp"].size == 201 * 201, where
        if code == 0:            # the run had ended before the signal
            assert err == "", where
            assert (run / "sweep.npz").exists(), where
            continue
        assert alive, where
        assert code == {signal.SIGINT: 130, signal.SIGTERM: 143}[signum], where
        assert err.splitlines() == [f"packetloss-cvx: interrupted by {signal.Signals(signum).name}"], where
        interrupted += 1
    assert interrupted >= len(cases) - 1      # the delays lie within the sweep: the signals land in it
