"""Validation: every bad input names its field and says what was expected (a typed InputError, never a
traceback, a MemoryError or a RecursionError), in the System, in system files and at the public API."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.tolerances import ROUNDING_ORDER_RTOL

GOOD = {
    "A": [[1.0, 0.1], [0.0, 1.0]], "B": [[0.0], [1.0]], "horizon": 3,
    "state_weight": [1.0, 1.0], "input_weight": [1.0], "mu": [0.5], "x0": [1.0, 0.0],
}


def make(**changes):
    kwargs = {**GOOD, **changes}
    return pl.System(**{k: v for k, v in kwargs.items() if v is not None})


@pytest.mark.parametrize(
    ("changes", "error", "match"),
    [
        ({"A": [[1.0, 0.0]]}, pl.DimensionError, r"A: expected shape \(n, n\) \(square\) but found \(1, 2\)"),
        ({"B": [[1.0], [0.0], [0.0]]}, pl.DimensionError, r"B: expected shape \(2, m\) but found \(3, 1\)"),
        ({"x0": [1.0]}, pl.DimensionError, r"x0: expected shape \(2,\)"),
        ({"state_weight": [1.0, 1.0, 1.0]}, pl.DimensionError, r"state_weight: expected shape"),
        ({"input_weight": [1.0, 2.0]}, pl.DimensionError, r"input_weight: expected shape \(1,\)"),
        ({"mu": None, "mu_schedule": [[0.5], [0.5]]}, pl.DimensionError, r"mu_schedule: expected shape \(3, 1\)"),
        ({"mu": [1.2]}, pl.ProbabilityError, r"mu: expected probabilities in \[0, 1\], found 1.2"),
        ({"mu": [-0.1]}, pl.ProbabilityError, r"mu: expected probabilities in \[0, 1\]"),
        ({"A": [[np.nan, 0.0], [0.0, 1.0]]}, pl.InputError, r"A: expected finite numbers"),
        ({"x0": [np.inf, 0.0]}, pl.InputError, r"x0: expected finite numbers"),
        ({"state_weight": [[1.0, 0.5], [0.0, 1.0]]}, pl.InputError, r"state_weight: expected a symmetric"),
        ({"state_weight": [[1.0, 2.0], [2.0, 1.0]]}, pl.InputError,
         r"state_weight: expected a positive semidefinite"),
        ({"state_weight": [1.0, -1.0]}, pl.InputError, r"state_weight: expected a non-negative diagonal"),
        ({"input_weight": [0.0]}, pl.InputError, r"input_weight: expected positive entries"),
        ({"input_weight": None, "input_weights": [[1.0], [-1.0], [1.0]]}, pl.InputError,
         r"input_weights: expected positive"),
        ({"horizon": 0}, pl.InputError, r"horizon: expected an integer >= 1, found 0"),
        ({"horizon": 2.5}, pl.InputError, r"horizon: expected an integer >= 1, found 2.5"),
        ({"horizon": "3"}, pl.InputError, r"horizon: expected an integer"),
        ({"horizon": True}, pl.InputError, r"horizon: expected an integer"),
        ({"mu_schedule": [[0.5]] * 3}, pl.InputError, r"mu/mu_schedule: expected exactly one of the two, found both"),
        ({"mu": None}, pl.InputError, r"mu/mu_schedule: expected exactly one of the two, found neither"),
        ({"state_weights": [[1, 1]] * 3}, pl.InputError, r"state_weight/state_weights: .*found both"),
        ({"input_weight": None}, pl.InputError, r"input_weight/input_weights: .*found neither"),
        ({"A": [[1.0, "a"], [0.0, 1.0]]}, pl.InputError, r"A: expected a number, found the string 'a'"),
        ({"x0": [True, 0.0]}, pl.InputError, r"x0: expected a number, found a boolean"),
        ({"A": [[1.0, 0.0], [1.0]]}, pl.InputError, r"A: expected a rectangular array"),
        ({"state_weight": None, "state_weights": [[1.0, 1.0]] * 2}, pl.DimensionError,
         r"state_weights: expected 3 entries"),
        ({"noise_cov": [[1.0, 0.0], [0.0, -1.0]]}, pl.InputError, r"noise_cov: expected a positive semidefinite"),
        ({"initial_weight": [[1.0]]}, pl.DimensionError, r"initial_weight: expected shape"),
        ({"name": 3}, pl.InputError, r"name: expected a string"),
    ],
)
def test_bad_input_names_field(changes, error, match):
    with pytest.raises(error, match=match):
        make(**changes)


def test_bad_input_is_value_error():
    with pytest.raises(ValueError, match="mu"):
        make(mu=[2.0])


def test_system_is_immutable_and_copies():
    s = make()
    with pytest.raises(AttributeError, match="immutable"):
        s.horizon = 4
    with pytest.raises(ValueError, match="read-only"):
        s.A[0, 0] = 5.0
    t = s.with_mu([0.9])
    assert s.mu[0] == 0.5
    assert t.mu[0] == 0.9
    u = s.with_mu([[0.1], [0.2], [0.3]])
    assert not u.is_stationary
    with pytest.raises(ValueError, match="non-stationary"):
        _ = u.mu
    assert np.array_equal(s.with_x0([0.0, 2.0]).x0, [0.0, 2.0])


def test_full_and_time_varying_weights_are_stored_per_step():
    s = make(state_weight=None, state_weights=[[1.0, 2.0], [[2.0, 0.5], [0.5, 1.0]], [0.0, 0.0]],
             input_weight=None, input_weights=[[1.0], [2.0], [3.0]])
    assert s.state_weights.shape == (3, 2, 2)
    assert np.array_equal(s.state_weights[0], np.diag([1.0, 2.0]))
    assert np.array_equal(s.input_weights[:, 0], [1.0, 2.0, 3.0])


def test_round_trip_through_dict(two_actuator):
    again = system_from_dict(two_actuator.to_dict())
    for key in ("A", "B", "state_weights", "input_weights", "mu_schedule", "x0", "initial_weight", "noise_cov"):
        assert np.array_equal(getattr(again, key), getattr(two_actuator, key))


TOML = """
name = "t"
[plant]
A = [[1.0, 0.1], [0.0, 1.0]]
B = [[0.0], [1.0]]
[cost]
horizon = 3
state_weight = [1.0, 1.0]
input_weight = [1.0]
[channel]
mu = [0.5]
[state]
x0 = [1.0, 0.0]
"""


def write(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def test_load_good_file(tmp_path):
    s = pl.load_system(write(tmp_path, TOML))
    assert (s.name, s.n, s.m, s.horizon) == ("t", 2, 1, 3)


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("[state]\nx0 = [1.0, 0.0]", "", r"state: missing section"),
        ("x0 = [1.0, 0.0]", "", r"state.x0: missing field"),
        ("horizon = 3", "horizon = 0", r"cost.horizon: expected an integer >= 1"),
        ("horizon = 3", 'horizon = "three"', r"cost.horizon: expected an integer"),
        ("mu = [0.5]", "mu = [1.5]", r"channel.mu: expected probabilities"),
        ("mu = [0.5]", "mu = [0.5]\nmu_schedule = [[0.5], [0.5], [0.5]]", r"channel.mu/mu_schedule: .*found both"),
        ("mu = [0.5]", "", r"channel.mu/mu_schedule: .*found neither"),
        ("B = [[0.0], [1.0]]", "B = [[0.0], [1.0], [2.0]]", r"plant.B: expected shape \(2, m\)"),
        ("A = [[1.0, 0.1], [0.0, 1.0]]", "A = [[1.0, 0.1]]", r"plant.A: expected shape"),
        ("state_weight = [1.0, 1.0]", "state_weight = [1.0, 1.0]\nstate_weigth = [1.0]",
         r"cost.state_weigth: unknown key"),
        ("state_weight = [1.0, 1.0]", "state_weights = [[1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]",
         r"cost.state_weights\[1\]: expected a non-negative"),
        ("x0 = [1.0, 0.0]", 'x0 = [1.0, "a"]', r"state.x0: expected a number, found the string"),
        ("x0 = [1.0, 0.0]", "x0 = [nan, 0.0]", r"state.x0: expected finite numbers"),
        ("[plant]", "[plantt]\n[plant]", r"plantt: unknown section"),
    ],
)
def test_load_bad_file_names_toml_path(tmp_path, old, new, match):
    assert old in TOML
    with pytest.raises(pl.InputError, match=match):
        pl.load_system(write(tmp_path, TOML.replace(old, new)))


def test_missing_and_non_toml_files(tmp_path):
    with pytest.raises(pl.InputError, match=r"file: no such file"):
        pl.load_system(tmp_path / "absent.toml")
    with pytest.raises(pl.InputError, match=r"file: .* is not valid TOML"):
        pl.load_system(write(tmp_path, "this is = = not toml"))


def _weights_one_by_one(items, n):
    """The reference: psd_weight a step at a time (what System did before the stacked check)."""
    from packetloss_cvx.model.validation import psd_weight
    return np.stack([psd_weight(w, f"state_weights[{t}]", n) for t, w in enumerate(items)])


def _error_of(build):
    try:
        build()
    except ValueError as err:
        return type(err), str(err)
    return None


@pytest.mark.parametrize("seed", range(6))
def test_stacked_weight_check_gives_the_step_by_step_floats_and_first_error(seed):
    """validation.psd_weights against psd_weight step by step: the same floats bit for bit where a step is stored as
    given or symmetrised (diagonals, full matrices, asymmetry within the tolerance), the same values to rounding
    (ROUNDING_ORDER_RTOL) where eigenvalues a rounding below 0 are repaired (an eigen-decomposition and a product,
    stacked against one at a time), and the same first error (type and text) wherever one or two steps are bad,
    in any order."""
    from packetloss_cvx.model.validation import psd_weights
    rng = np.random.default_rng(seed)
    n, N = int(rng.integers(1, 5)), int(rng.integers(2, 30))

    def good(kind):
        F = rng.normal(size=(n, n))
        if kind == "diag":
            return rng.uniform(0.0, 2.0, n)
        W = F @ F.T
        if kind == "asymmetric":                         # within SYMMETRY_RTOL: accepted, symmetrised
            W = W + 1e-14 * np.linalg.norm(W, 2) * np.triu(np.ones((n, n)), 1)
        if kind == "rank-deficient":                     # eigenvalues a rounding below 0: repaired
            v = F[:, :1]
            W = v @ v.T * 1e3
        return W

    kinds = rng.choice(["diag", "full", "full", "asymmetric", "rank-deficient"], N)
    items = [good(k) for k in kinds]
    as_lists = [w.tolist() for w in items]
    for given in (items, as_lists):
        got, want = psd_weights(given, "state_weights", n), _weights_one_by_one(given, n)
        for t, kind in enumerate(kinds):
            if kind == "rank-deficient":
                np.testing.assert_allclose(got[t], want[t], rtol=0, atol=ROUNDING_ORDER_RTOL * np.abs(want[t]).max())
            else:
                assert np.array_equal(got[t], want[t]), (t, kind)
    bad = {"not psd": -np.eye(n) - 1e-3, "nan": np.full((n, n), np.nan), "shape": np.ones((n + 1, n + 1)),
           "negative diagonal": -np.ones(n), "asymmetric": np.triu(np.ones((n, n)), 1) + np.eye(n) if n > 1 else
           np.array([[-1.0]]), "string": "W"}
    for name, value in bad.items():
        for t in {0, N // 2, N - 1}:
            wrong = list(items)
            wrong[t] = value
            for second in (None, (t + 1) % N):
                if second is not None:
                    wrong[second] = bad["not psd"]
                expected = _error_of(lambda w=wrong: _weights_one_by_one(w, n))
                assert expected is not None, name
                assert _error_of(lambda w=wrong: psd_weights(w, "state_weights", n)) == expected, (name, t, second)


@pytest.mark.parametrize("seed", range(3))
def test_weights_as_nested_lists_give_the_step_by_step_floats_and_first_error(seed):
    """Steps given as nested lists (a TOML file's) are converted as one stack: the same floats bit for bit as
    psd_weight step by step, and where a step is bad (an entry that is not a finite number or beyond the double
    range, a wrong or ragged shape, an indefinite or asymmetric matrix) the same first error, naming that step."""
    from packetloss_cvx.model.validation import psd_weights
    rng = np.random.default_rng(100 + seed)
    n, N = int(rng.integers(1, 5)), int(rng.integers(2, 30))
    F = rng.normal(size=(N, n, n))
    full = [(f @ f.T).tolist() for f in F]
    diagonal = [rng.uniform(0.0, 2.0, n).tolist() for _ in range(N)]
    for items in (full, diagonal):
        assert np.array_equal(psd_weights(items, "state_weights", n), _weights_one_by_one(items, n))
    bad = {"nan": [[float("nan")] * n] * n, "huge integer": [[10**400] * n] * n, "string": [["W"] * n] * n,
           "boolean": [[True] * n] * n, "shape": np.ones((n + 1, n + 1)).tolist(), "ragged": [[1.0] * n, [1.0]],
           "not psd": (-np.eye(n) - 1e-3).tolist(), "negative diagonal": [-1.0] * n,
           "asymmetric": (np.triu(np.ones((n, n)), 1) + np.eye(n) if n > 1 else -np.eye(1)).tolist()}
    for name, value in bad.items():
        for t in {0, N // 2, N - 1}:
            wrong = list(full)
            wrong[t] = value
            expected = _error_of(lambda w=wrong: _weights_one_by_one(w, n))
            assert expected is not None, name
            assert f"state_weights[{t}]" in expected[1], name
            assert _error_of(lambda w=wrong: psd_weights(w, "state_weights", n)) == expected, (name, t)


def test_weights_as_arrays_of_one_shape_give_the_step_by_step_floats_and_first_error():
    """Plain arrays of one shape are checked as one stack: the same floats as psd_weight step by step (integer
    and float arrays mixed), and a boolean, complex or non-finite step refused with that step's own error."""
    from packetloss_cvx.model.validation import psd_weights
    rng = np.random.default_rng(7)
    n, N = 3, 12
    F = rng.normal(size=(N, n, n))
    items = [f @ f.T for f in F]
    items[2] = np.eye(n, dtype=np.int64) * 3
    assert np.array_equal(psd_weights(items, "state_weights", n), _weights_one_by_one(items, n))
    for value in (np.eye(n, dtype=bool), np.eye(n) + 0j, np.full((n, n), np.inf), -np.eye(n)):
        wrong = list(items)
        wrong[5] = value
        expected = _error_of(lambda w=wrong: _weights_one_by_one(w, n))
        assert expected is not None
        assert "state_weights[5]" in expected[1]
        assert _error_of(lambda w=wrong: psd_weights(w, "state_weights", n)) == expected


# ---------------------------------------------------------------- the weights' bands, pinned on both sides

@pytest.mark.parametrize("field", ["state_weight", "noise_cov"])
@pytest.mark.parametrize("scale", [1e-30, 1.0, 1e30])
@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_asymmetry_of_3_times_symmetry_rtol_is_refused_and_of_0_3_kept(field, scale, factor, kept):
    """W = diag(2, 1) + e (e1 e2' - e2 e1') has ||W - W'||_2 = 2 e and ||W||_2 = 2 + O(e^2) (by hand): e = factor
    SYMMETRY_RTOL is refused at 3, symmetrised at 0.3, at every scale of W (the band is relative)."""
    from packetloss_cvx.tolerances import SYMMETRY_RTOL

    e = factor * SYMMETRY_RTOL
    W = scale * np.array([[2.0, e], [-e, 1.0]])
    if kept:
        s = pl.System(**{**GOOD, field: W.tolist()})
        got = s.state_weights[0] if field == "state_weight" else s.noise_cov
        assert np.array_equal(got, got.T)
        assert np.allclose(got, scale * np.diag([2.0, 1.0]), rtol=0.0, atol=1e-15 * scale)
    else:
        with pytest.raises(pl.InputError, match=f"{field}: expected a symmetric matrix"):
            pl.System(**{**GOOD, field: W.tolist()})


@pytest.mark.parametrize("field", ["state_weight", "noise_cov", "initial_weight"])
@pytest.mark.parametrize("scale", [1e-30, 1.0, 1e30])
@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_eigenvalue_of_minus_3_times_psd_rtol_is_refused_and_of_minus_0_3_set_to_zero(field, scale, factor, kept):
    """diag(1, -factor PSD_RTOL) times scale: its least eigenvalue is exactly -factor PSD_RTOL ||W||. At 3 it is
    refused naming the field, at 0.3 accepted as a rounding of a PSD weight and set to zero."""
    from packetloss_cvx.tolerances import PSD_RTOL

    W = scale * np.diag([1.0, -factor * PSD_RTOL])
    if kept:
        s = pl.System(**{**GOOD, field: W.tolist()})
        got = {"state_weight": s.state_weights[0], "noise_cov": s.noise_cov, "initial_weight": s.initial_weight}[field]
        assert np.linalg.eigvalsh(got).min() >= 0.0
        assert np.allclose(got, scale * np.diag([1.0, 0.0]), rtol=0.0, atol=1e-15 * scale)
    else:
        with pytest.raises(pl.InputError, match=f"{field}: expected a positive semidefinite matrix"):
            pl.System(**{**GOOD, field: W.tolist()})


BASE = {"A": [[1.0, 0.0], [0.0, 1.0]], "B": [[1.0], [0.5]], "horizon": 5, "state_weight": [1, 1],
        "input_weight": [1], "mu": [0.5], "x0": [1, 0]}


def _deep(levels: int):
    value = 1.0
    for _ in range(levels):
        value = [value]
    return value


@pytest.mark.parametrize(("change", "field", "match"), [
    ({"horizon": 1_000_000_000}, "horizon", "what fits in memory"),
    ({"horizon": 9223372036854775807}, "horizon", "what fits in memory"),
    ({"horizon": 10**23}, "horizon", "what fits in memory"),
    ({"horizon": -(10**5000)}, "horizon", "about 5001 digits"),
    ({"A": [[10**400, 0], [0, 1]]}, "A", "double range"),
    ({"x0": [10**400, 0]}, "x0", "double range"),
    ({"mu": [10**400]}, "mu", "double range"),
    ({"A": _deep(5000)}, "A", "levels of nested lists"),
    ({"A": np.zeros((0, 0)), "B": np.zeros((0, 1)), "x0": [], "state_weight": []}, "A", "n >= 1"),
    ({"B": [[], []], "input_weight": [], "mu": []}, "B", "m >= 1"),
])
def test_system_refuses_with_the_field_named(change, field, match):
    with pytest.raises(pl.InputError, match=match) as info:
        pl.System(**{**BASE, **change})
    assert info.value.field == field
    assert isinstance(info.value, ValueError)


def test_load_system_refuses_a_nul_in_the_path():
    with pytest.raises(pl.InputError, match="NUL") as info:
        pl.load_system("a\x00b")
    assert info.value.field == "file"


@pytest.mark.parametrize("field", ["state_weight", "noise_cov", "initial_weight"])
def test_indefinite_matrices_are_refused_relative_to_their_size(field):
    """-99 beside 1e12 passed the former absolute-floor test: the minimum was unbounded below and
    expected_cost(U = 1e6) returned -5.4e15; with noise_cov a cost of -594 came back."""
    bad = [[1e12, 0.0], [0.0, -99.0]]
    with pytest.raises(pl.InputError, match="positive semidefinite") as info:
        pl.System(**{**BASE, field: bad})
    assert info.value.field == field


def test_tiny_weights_are_judged_relative_to_themselves():
    with pytest.raises(pl.InputError, match="positive semidefinite"):
        pl.System(**{**BASE, "state_weight": [[1e-15, 0.0], [0.0, -1e-16]]})
    # rounding-level negatives are accepted and set to zero: the weight is exactly PSD
    s = pl.System(**{**BASE, "state_weight": [[1.0, 1.0], [1.0, 1.0 - 1e-15]]})
    assert np.linalg.eigvalsh(s.state_weights[0]).min() >= 0.0
    assert np.allclose(s.state_weights[0], [[1.0, 1.0], [1.0, 1.0]], atol=1e-14)


def test_devices_and_pipes_are_not_read(tmp_path):
    """/dev/zero read without limit (st_size is 0); a FIFO hung until killed."""
    import os

    with pytest.raises(pl.InputError, match="not a regular file"):
        pl.load_system("/dev/zero")
    fifo = tmp_path / "f.toml"
    os.mkfifo(fifo)
    with pytest.raises(pl.InputError, match="not a regular file"):
        pl.load_system(fifo)


def test_save_system_round_trips_any_name(tmp_path):
    """json.dumps wrote surrogate pairs for characters beyond U+FFFF, which TOML forbids."""
    data = pl.load_example("two_actuator").to_dict()
    data["name"] = 'pump \U0001f600 \x7f tab\t "q" \\ \u00e9'
    system = system_from_dict(data)
    assert pl.load_system(pl.save_system(system, tmp_path / "s.toml")).name == data["name"]
    with pytest.raises(pl.InputError) as info:
        pl.save_system(system, tmp_path)
    assert info.value.field == "path"


@pytest.mark.parametrize("call", [
    lambda s: pl.closed_form({}, "tcp"),
    lambda s: pl.expected_cost(None, [[0.0]], "tcp"),
    lambda s: pl.solve_qp("two_actuator", "tcp"),
    lambda s: pl.solve_qp(s, "tcp", reference="x"),
    lambda s: pl.solve_qp(s, "tcp", reference=pl.closed_form(pl.load_example("pendulum"), "tcp")),
    lambda s: pl.save_system({}, "x.toml"),
])
def test_api_misuse_is_a_typed_error(call):
    with pytest.raises(pl.InputError, match="system|reference"):
        call(pl.load_example("two_actuator"))


def test_rows_as_arrays_and_masked_arrays():
    rows = [np.array([1.0, 0.0]), np.array([0.0, 1.0])]
    assert pl.System(**{**BASE, "A": rows}).A.tolist() == [[1.0, 0.0], [0.0, 1.0]]
    with pytest.raises(pl.InputError, match="masked"):
        pl.System(**{**BASE, "x0": np.ma.array([1.0, 0.0], mask=[True, False])})


@pytest.mark.parametrize(("call", "field"), [
    # each raised an untyped error (TypeError, AttributeError) or was accepted with a meaningless value
    (lambda s, tmp: __import__("packetloss_cvx.montecarlo", fromlist=["simulate"]).simulate(
        s, 10, closed_loop="no", progress=False), "closed_loop"),
    (lambda s, tmp: pl.audit(systems="pendulum", random=0, progress=False), "systems"),
    (lambda s, tmp: pl.audit(systems=[s, "pendulum"], random=0, progress=False), "systems"),
    (lambda s, tmp: __import__("packetloss_cvx.allocation.delivery", fromlist=["power_model"]).power_model(
        "exponential", 0, scale=[1]), "m"),
    (lambda s, tmp: __import__("packetloss_cvx.allocation.delivery", fromlist=["power_model"]).power_model(
        "exponential", "2", scale=[1]), "m"),
])
def test_api_arguments_of_the_wrong_type_are_typed_input_errors(call, field, tmp_path):
    with pytest.raises(pl.InputError) as info:
        call(pl.load_example("two_actuator"), tmp_path)
    assert info.value.field == field


def test_save_system_overwrites_only_when_told_so_by_a_bool(tmp_path):
    """``overwrite="no"`` (any truthy value) replaced the file; only ``True`` does."""
    system = pl.load_example("two_actuator")
    path = pl.save_system(system, tmp_path / "s.toml")
    path.write_text("# the user's own file\n")
    for value in ("no", "False", 1, [True]):
        with pytest.raises(pl.InputError, match="^overwrite: expected True or False"):
            pl.save_system(system, path, overwrite=value)
    assert path.read_text() == "# the user's own file\n"
    pl.save_system(system, path, overwrite=True)
    assert pl.load_system(path).name == system.name


def test_a_name_too_long_for_the_system_is_bad_input():
    with pytest.raises(pl.InputError, match="file name too long"):
        pl.load_system("a" * 100_000)
