"""The BLAS thread policy: the library's calls run with the limit, the caller's setting is restored,
nested calls limit once, and the limit can be raised or lifted."""

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import packetloss_cvx as pl
import packetloss_cvx.lq.costs as costs_module
import packetloss_cvx.lq.policy as policy_module
from packetloss_cvx import threads
from packetloss_cvx.errors import InputError
from packetloss_cvx.lq.evaluator import CostEvaluator
from packetloss_cvx.threads import blas_threads, set_blas_threads


def _blas_threads() -> set[int]:
    return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}


@pytest.fixture
def spy(monkeypatch):
    """Record the BLAS thread counts seen inside closed_form and expected_cost (through a function each calls once:
    the policy's choice of weights, expected_cost's variance weights)."""
    seen = []
    real, real_weights = policy_module.lyapunov_weights_if_needed, costs_module.udp_variance_weights

    def recording(system, protocol, method):
        seen.append(_blas_threads())
        return real(system, protocol, method)

    def recording_weights(system):
        seen.append(_blas_threads())
        return real_weights(system)

    monkeypatch.setattr(policy_module, "lyapunov_weights_if_needed", recording)
    monkeypatch.setattr(costs_module, "udp_variance_weights", recording_weights)
    return seen


def test_library_calls_run_single_threaded_and_restore_the_callers_setting(two_actuator, spy):
    if not _blas_threads():
        pytest.skip("no BLAS thread pool found by threadpoolctl")
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        pl.closed_form(two_actuator, "udp")
        after = _blas_threads()
    assert spy == [{1}]
    assert before == after                     # the caller's setting is back


def test_the_limit_can_be_raised_and_lifted(two_actuator, spy):
    if not _blas_threads():
        pytest.skip("no BLAS thread pool found by threadpoolctl")
    try:
        with threadpool_limits(limits=2, user_api="blas"):
            callers = _blas_threads()              # 2, or 1 for a library loaded single-threaded
            threads.set_blas_threads(2)
            pl.closed_form(two_actuator, "tcp")
            threads.set_blas_threads(None)
            pl.closed_form(two_actuator, "tcp")
    finally:
        threads.set_blas_threads(1)
    assert spy == [callers, callers]


def test_nested_calls_limit_once(two_actuator, monkeypatch):
    calls = []
    real = threads.ThreadpoolController.limit

    def counting(self, *args, **kwargs):
        calls.append(1)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(threads.ThreadpoolController, "limit", counting)
    ev = CostEvaluator(two_actuator, "udp")
    ev.cost(np.array([0.5, 0.5]))
    assert len(calls) == 1
    pl.allocate(two_actuator, "udp", 8.0, [1.0, 1.0])          # hundreds of inner closed forms
    assert len(calls) == 2


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "two"])
def test_bad_thread_counts_are_refused(bad):
    with pytest.raises(pl.InputError, match="threads"):
        threads.set_blas_threads(bad)
    assert threads.blas_threads() == 1


def test_overlapping_threads_leave_the_process_setting_as_it_was(two_actuator):
    """Two threads inside the library at once: when both are out, BLAS is as the caller had it."""
    import threading

    if not _blas_threads():
        pytest.skip("no BLAS thread pool found by threadpoolctl")
    before = _blas_threads()
    inside, release = threading.Event(), threading.Event()
    real = policy_module.lyapunov_weights_if_needed

    def slow(system, protocol, method):
        inside.set()
        release.wait(5)
        return real(system, protocol, method)

    policy_module.lyapunov_weights_if_needed = slow
    try:
        first = threading.Thread(target=pl.closed_form, args=(two_actuator, "tcp"))
        first.start()
        inside.wait(5)
        policy_module.lyapunov_weights_if_needed = real
        second = threading.Thread(target=pl.closed_form, args=(two_actuator, "udp"))
        second.start()
        second.join(5)                                # in and out while the first is inside
        release.set()
        first.join(5)
    finally:
        policy_module.lyapunov_weights_if_needed = real
    assert _blas_threads() == before


def test_expected_cost_runs_single_threaded_too(two_actuator, spy):
    """expected_cost carries the limit (a stray decorator had moved to refuse_correlated)."""
    if not _blas_threads():
        pytest.skip("no BLAS thread pool found by threadpoolctl")
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        pl.expected_cost(two_actuator, np.zeros((two_actuator.horizon, two_actuator.m)), "udp")
        after = _blas_threads()
    assert spy == [{1}]
    assert before == after


def test_set_blas_threads_takes_numpy_integers():
    # a NumPy integer is an integer: accepted, and stored as a plain int
    try:
        set_blas_threads(np.int64(2))
        assert blas_threads() == 2
        assert type(blas_threads()) is int
        for bad in (0, -1, 1.5, True, "abc", np.float64(2.0)):
            with pytest.raises(InputError, match="threads"):
                set_blas_threads(bad)
    finally:
        set_blas_threads(1)



def test_the_grid_sweeps_run_under_the_blas_policy(monkeypatch, two_actuator):
    # shared_channel_sweep / two_channel_sweep evaluate many small dense problems: they run under the BLAS thread
    # policy (one thread), where small products are faster than threaded ones
    from threadpoolctl import threadpool_info, threadpool_limits

    import packetloss_cvx.studies.sweeps as sweeps

    seen = []
    original = sweeps.cost_differences

    def spy(*args, **kwargs):
        seen.append(max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
        return original(*args, **kwargs)

    monkeypatch.setattr(sweeps, "cost_differences", spy)
    with threadpool_limits(2, user_api="blas"):
        sweeps.shared_channel_sweep(two_actuator, [0.2, 0.7])
        sweeps.two_channel_sweep(two_actuator, [0.2, 0.7])
        after = max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
    assert seen == [1] * 2     # one stacked difference per sweep (difference.cost_differences)
    assert after == 2          # the caller's setting is restored



def test_reproduce_computes_under_the_blas_policy(monkeypatch):
    # every step of reproduce, the maximisers and tables outside the sweeps included, runs under the BLAS policy
    from threadpoolctl import threadpool_info, threadpool_limits

    import packetloss_cvx.cli.reproduce as rep

    seen = []

    def spy(*args, **kwargs):
        seen.append(max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
        return {}

    def allocations(*args, **kwargs):       # the break-even steps read the designs at beta = (1, 1)
        spy()
        return {(1.0, 1.0): []}

    def break_even(*args, **kwargs):
        spy()
        return {"alpha": []}

    for name in ("log_cost_pendulum", "mixed_grids", "eigenvalue_tables"):
        monkeypatch.setattr(rep.pf, name, spy)
    monkeypatch.setattr(rep.pf, "mixed_allocations", allocations)
    monkeypatch.setattr(rep, "attainable_break_even", break_even)
    monkeypatch.setattr(rep, "audit", spy)
    with threadpool_limits(2, user_api="blas"):
        rep.compute(rep.SETTINGS["quick"], False, {})
    assert seen == [1] * 7
