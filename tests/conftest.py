from pathlib import Path

import pytest

import packetloss_cvx as pl

EXAMPLES = Path(__file__).resolve().parent.parent / "packetloss_cvx" / "examples"


@pytest.fixture(scope="session")
def two_actuator() -> pl.System:
    return pl.load_system(EXAMPLES / "two_actuator.toml")


@pytest.fixture(scope="session")
def pendulum() -> pl.System:
    return pl.load_system(EXAMPLES / "pendulum.toml")
