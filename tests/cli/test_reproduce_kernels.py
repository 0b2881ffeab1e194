"""``reproduce`` under another BLAS kernel: the same verdicts, counts and texts, and every number within its
tolerance (tests/kernels.py; the README's "Other machines")."""

import json
import os
import subprocess
import sys

import pytest

from packetloss_cvx.cli import main

from ..kernels import compare_results, other_kernel


@pytest.fixture(scope="module")
def two_kernels(tmp_path_factory):
    kernel = other_kernel()
    if kernel is None:
        pytest.skip("OpenBLAS kernels are chosen by name on x86-64 only")
    here, there = tmp_path_factory.mktemp("here"), tmp_path_factory.mktemp("there")
    assert main(["reproduce", "--out", str(here), "--quick", "--quiet"]) == 0
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
    run = subprocess.run([sys.executable, "-m", "packetloss_cvx", "reproduce", "--out", str(there), "--quick",
                          "--quiet"], env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    return (json.loads((here / "results.json").read_text()), json.loads((there / "results.json").read_text()),
            kernel)


def test_reproduce_under_another_kernel_agrees_within_the_tolerance_registry(two_kernels):
    here, there, kernel = two_kernels
    assert compare_results(here, there) == [], kernel


def test_the_comparison_fails_on_a_moved_cost_a_changed_verdict_and_a_changed_count(two_kernels):
    """The comparison can fail: a cost moved by 10x its tolerance, one verdict and one count changed."""
    here, _, _ = two_kernels
    moved = json.loads(json.dumps(here))
    moved["pendulum"]["tcp"][0] *= 1 + 1e-8
    assert any("/pendulum/tcp[0]" in p for p in compare_results(here, moved))
    within = json.loads(json.dumps(here))
    within["pendulum"]["tcp"][0] *= 1 + 1e-10
    assert compare_results(here, within) == []
    flipped = json.loads(json.dumps(here))
    flipped["audit"][0]["verdict"] = "fails" if flipped["audit"][0]["verdict"] != "fails" else "holds"
    assert any("/audit[0]/verdict" in p for p in compare_results(here, flipped))
    counted = json.loads(json.dumps(here))
    counted["audit"][0]["checked"] += 1
    assert any("/audit[0]/checked" in p for p in compare_results(here, counted))


def _moved(data, path, factor):
    out = json.loads(json.dumps(data))
    *keys, last = path
    node = out
    for key in keys:
        node = node[key]
    node[last] *= factor
    return out


def test_each_band_of_the_comparison_fails_at_ten_times_and_passes_at_a_tenth(two_kernels):
    from packetloss_cvx.tolerances import ALLOCATION_GAP_DEFAULT, KERNEL_MARGIN_RTOL, KERNEL_POINT_RTOL

    here, _, _ = two_kernels
    allocation = next(iter(here["allocations"]["udp"]))
    holding = next(i for i, c in enumerate(here["audit"]) if c["verdict"] == "holds" and c["worst"] > 1e-6)
    cases = [(("allocations", "udp", allocation, 0, "communication_cost"), ALLOCATION_GAP_DEFAULT),
             (("audit", holding, "worst"), KERNEL_MARGIN_RTOL),
             (("pendulum", "maximiser", "nu"), KERNEL_POINT_RTOL)]
    for path, rtol in cases:
        assert compare_results(here, _moved(here, path, 1 + 10 * rtol)) != [], path
        assert compare_results(here, _moved(here, path, 1 + 0.1 * rtol)) == [], path


@pytest.mark.parametrize(("factor", "agree"), [(3.0, False), (0.3, True)])
def test_a_quantity_zero_in_one_run_is_compared_to_kernel_zero_atol(factor, agree):
    """A number exactly zero under one kernel (a radius at a deadbeat point) against factor KERNEL_ZERO_ATOL under
    another: a difference at 3 times the floor is reported, at 0.3 times it is rounding."""
    from packetloss_cvx.tolerances import KERNEL_ZERO_ATOL

    here, there = {"radius": [0.0]}, {"radius": [factor * KERNEL_ZERO_ATOL]}
    assert (compare_results(here, there) == []) is agree


def test_the_command_bands_fail_at_ten_times_and_pass_at_a_tenth():
    """The bands of a command's JSON (tests/cli/test_examples_kernels.py): a stability allocation's DP cost (a value),
    its cost (the certified gap), and a cross-check's measure (within the cross-check's band, whatever its value)."""
    from packetloss_cvx.tolerances import ALLOCATION_GAP_DEFAULT, CROSS_CHECK_INPUT_ATOL, KERNEL_VALUE_RTOL

    allocation = {"target": "stable", "dp_cost": 4.5e4, "cost": 0.5}
    for key, rtol in (("dp_cost", KERNEL_VALUE_RTOL), ("cost", ALLOCATION_GAP_DEFAULT)):
        assert compare_results(allocation, {**allocation, key: allocation[key] * (1 + 10 * rtol)}) != [], key
        assert compare_results(allocation, {**allocation, key: allocation[key] * (1 + 0.1 * rtol)}) == [], key
    check = {"qp": {"max_input_diff": 1e-11}}
    assert compare_results(check, {"qp": {"max_input_diff": 0.1 * CROSS_CHECK_INPUT_ATOL}}) == []
    assert compare_results(check, {"qp": {"max_input_diff": 10 * CROSS_CHECK_INPUT_ATOL}}) != []


def test_an_accuracy_estimate_is_compared_by_its_size_not_its_value():
    """``lambda_error`` is an error's size: rounding-level on both kernels (pendulum_bursty's 3.96e-12 and 3.97e-13)
    agrees, so do estimates within a factor of ten (the defective chain's 6.2e-6 and 1.8e-6); a hundredfold
    change, or one kernel knowing the value to rounding and the other only to 1e-6, is a disagreement."""
    assert compare_results({"dp": {"lambda_error": 3.96e-12}}, {"dp": {"lambda_error": 3.97e-13}}) == []
    assert compare_results({"grid": {"lambda_error": [[6.2e-6, 1e-13]]}},
                           {"grid": {"lambda_error": [[1.8e-6, 2e-12]]}}) == []
    assert compare_results({"dp": {"lambda_error": 6.2e-6}}, {"dp": {"lambda_error": 6.2e-8}}) != []
    assert compare_results({"dp": {"lambda_error": 1e-6}}, {"dp": {"lambda_error": 1e-13}}) != []
