"""check_numbers' shortcut for rows of Python floats against the item-by-item walk it skips (kept here as
the reference): the same acceptance and the same error on random nestings of floats, ints, huge ints,
booleans, strings, None, NumPy scalars and arrays."""

import numbers
from typing import Any

import numpy as np
import pytest

from packetloss_cvx.errors import InputError
from packetloss_cvx.model.validation import MAX_ENTRIES, MAX_NESTING, check_numbers, digits, numeric_array


def walk(value: Any, field: str) -> None:
    """check_numbers before the shortcut, verbatim."""
    stack: list[tuple[Any, int]] = [(value, 0)]
    count = 0
    while stack:
        item, depth = stack.pop()
        if isinstance(item, bool):
            raise InputError(field, "expected a number, found a boolean")
        if isinstance(item, numbers.Real):
            count += 1
            if count > MAX_ENTRIES:
                raise InputError(field, f"expected at most {MAX_ENTRIES} numbers")
            if isinstance(item, numbers.Integral):
                try:
                    float(item)
                except OverflowError:
                    size = digits(int(item))
                    raise InputError(field, f"expected numbers within the double range (|x| < 1.8e308), found an "
                                            f"integer of about {size} digits") from None
            continue
        if isinstance(item, np.ndarray):            # a row given as an array inside a list
            if item.dtype.kind not in "iuf" or depth + item.ndim > MAX_NESTING:
                raise InputError(field, f"expected numbers, found an array of {item.dtype} and shape {item.shape}")
            count += item.size
            continue
        if isinstance(item, str):
            raise InputError(field, f"expected a number, found the string {item[:40]!r}")
        if isinstance(item, (list, tuple)):
            if depth >= MAX_NESTING:
                raise InputError(field, f"expected at most {MAX_NESTING} levels of nested lists, found more")
            stack.extend((sub, depth + 1) for sub in item)
            continue
        raise InputError(field, f"expected a number or a list of numbers, found {type(item).__name__}")


def outcome(fn, value):
    try:
        fn(value, "x")
    except InputError as err:
        return str(err)
    return "ok"


def random_value(rng, depth=0):
    if depth < 4 and rng.random() < 0.6:
        return [random_value(rng, depth + 1) for _ in range(rng.integers(0, 4))]
    kinds = [lambda: float(rng.normal()), lambda: float(rng.normal()), lambda: int(rng.integers(-5, 5)),
             lambda: 10**400, lambda: True, lambda: "2", lambda: None, lambda: np.float64(1.5),
             lambda: np.ones(2), lambda: np.array(["a"])]
    return kinds[int(rng.integers(len(kinds)))]()


@pytest.mark.parametrize("seed", range(5))
def test_shortcut_accepts_and_refuses_as_the_walk(seed):
    rng = np.random.default_rng(seed)
    for _ in range(400):
        value = random_value(rng)
        assert outcome(check_numbers, value) == outcome(walk, value), value


def test_rows_of_floats_still_count_and_nest():
    assert numeric_array([[1.0, 2.0], [3.0, 4.0]], "A").tolist() == [[1.0, 2.0], [3.0, 4.0]]
    with pytest.raises(InputError, match="levels of nested lists"):
        check_numbers([[[[1.0]]]], "A")
    with pytest.raises(InputError, match="expected a number, found a boolean"):
        check_numbers([[1.0, True]], "A")
