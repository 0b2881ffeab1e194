"""The example systems shipped with the package: the TOML files beside this module.

Standard library only, so that the command line's grammar (its FILE help, its shell completion) can
list them without importing NumPy; [`packetloss_cvx.model.files.load_example`][packetloss_cvx.model.files.load_example]
loads one.
"""

from __future__ import annotations

from importlib import resources

__all__ = ["names"]


def names() -> list[str]:
    """The examples' names, sorted (the file names without ``.toml``). O(files in the folder).

    Examples
    --------
    >>> {"pendulum", "pendulum_bursty", "two_actuator"} <= set(names())
    True
    """
    folder = resources.files(__package__)
    return sorted(item.name.removesuffix(".toml") for item in folder.iterdir() if item.name.endswith(".toml"))
