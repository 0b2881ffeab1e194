"""The typed cache of a System (model.CacheKey): every key of the package holds to what it says.

A key names the fields of the system its value depends on. References, independent of the cache: the
same quantity built on a freshly constructed System (an empty cache, every field validated again),
where the fields a key says it does not depend on are changed; and identity (``is``) for what is shared.
"""

import importlib
import pkgutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import packetloss_cvx
from packetloss_cvx.allocation import tcp
from packetloss_cvx.lq import augmented, recursion, structure
from packetloss_cvx.lq import prediction as prediction_module
from packetloss_cvx.model import chain
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.model.system import SYSTEM_FIELDS, CacheKey, StructureStore, System, SystemStore

#: each key of the package -> how its value is read through the public path that keeps it
READERS = {
    prediction_module.CORE_KEY: lambda s: tuple(getattr(prediction_module.prediction(s), name) for name in
                                                ("Phi", "Gamma", "Psi", "Omega_p", "Omega_g", "Omega_gp", "Omega_d")),
    prediction_module.OMEGA_KEY: lambda s: (prediction_module.prediction(s).Omega,),
    prediction_module.NOISE_TERM_KEY: lambda s: (prediction_module.prediction(s).noise_term,),
    structure.STRUCTURE_KEY: lambda s: (*recursion.udp_variance_weights(s), recursion.condition_estimate(s),
                                        recursion.weight_head(s)),
    chain.MOMENTS_KEY: lambda s: chain.stacked_moments(s),
    augmented.LIFT_KEY: lambda s: (lambda lift: (*lift.Lam, *lift.g, *lift.gamma, lift.offsets, lift.size))(
        augmented.chain_lift(s)),
    tcp.PROGRAMS_KEY: lambda s: (tcp.TCPProgram.of(s, "min_cost", 0).constants,),
}


def package_keys() -> dict[CacheKey, str]:
    """Every CacheKey defined at module level anywhere in the package -> where."""
    found = {}
    for info in pkgutil.walk_packages(packetloss_cvx.__path__, "packetloss_cvx."):
        if info.name.endswith("__main__"):
            continue
        for name, value in vars(importlib.import_module(info.name)).items():
            if isinstance(value, CacheKey):
                found.setdefault(value, f"{info.name}.{name}")
    return found


def fields(s: System) -> dict:
    out = {"A": s.A, "B": s.B, "horizon": s.horizon, "state_weights": s.state_weights,
           "input_weights": s.input_weights, "x0": s.x0, "initial_weight": s.initial_weight,
           "noise_cov": s.noise_cov, "name": s.name, "dt": s.dt, "sensor": s.sensor}
    return {**out, "channel": s.channel} if s.channel is not None else {**out, "mu_schedule": s.mu_schedule}


def changed(s: System, field: str, rng: np.random.Generator) -> System:
    """A freshly constructed System (empty cache) equal to ``s`` except in ``field``."""
    f = fields(s)
    n, m = s.n, s.m
    if field == "channel":
        f.pop("mu_schedule", None)
        f["channel"] = GilbertElliott(p=rng.uniform(0.05, 0.5, m), r=rng.uniform(0.05, 0.5, m))
    elif field == "mu_schedule":
        f.pop("channel", None)
        f["mu_schedule"] = rng.uniform(0, 1, (s.horizon, m))
    else:
        f[field] = {"A": lambda: 1.1 * s.A, "B": lambda: 0.9 * s.B, "state_weights": lambda: 2.0 * s.state_weights,
                    "input_weights": lambda: 3.0 * s.input_weights, "x0": lambda: s.x0 + 1.0,
                    "initial_weight": lambda: s.initial_weight + np.eye(n),
                    "noise_cov": lambda: s.noise_cov + 0.5 * np.eye(n), "name": lambda: "another",
                    "dt": lambda: 0.25 if s.dt is None else 2 * s.dt,
                    "sensor": lambda: Sensor(C=np.eye(n)[:1], gamma=[0.7], noise_cov=[[0.1]]),
                    "input_labels": lambda: [f"u{i}" for i in range(m)],
                    "state_labels": lambda: [f"x{i}" for i in range(n)]}[field]()
    return System(**f)


def same_values(a: tuple, b: tuple) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def shared(a: tuple, b: tuple) -> bool:
    return all(x is y for x, y in zip(a, b, strict=True))


def test_every_key_of_the_package_is_read_here_and_names_fields_of_system():
    keys = package_keys()
    assert set(keys) == set(READERS), sorted(keys.values())     # a new key needs a reader above
    assert len({key.name for key in keys}) == len(keys)
    assert set(SYSTEM_FIELDS) == {name for name in System.__slots__ if not name.startswith("_")}
    for key in keys:
        assert key.depends_on <= set(SYSTEM_FIELDS), key
    assert all(key.structural for key in keys if key not in (chain.MOMENTS_KEY, augmented.LIFT_KEY))
    assert not chain.MOMENTS_KEY.structural
    assert not augmented.LIFT_KEY.structural


def test_a_key_is_a_declared_object_not_a_string():
    s = random_system(np.random.default_rng(0))
    with pytest.raises(TypeError, match="CacheKey"):
        StructureStore("prediction.core")
    with pytest.raises(TypeError, match="CacheKey"):
        SystemStore("chain.stacked_moments")
    with pytest.raises(TypeError, match="depends on more than the structure"):
        StructureStore(CacheKey("test.mu", ("mu_schedule",)))                   # would be shared by with_mu copies
    with pytest.raises(ValueError, match="depends_on"):
        CacheKey("test.typo", ("mu",))                                          # not a field of System
    a, b = CacheKey("test.same", ("A",)), CacheKey("test.same", ("A",))
    assert StructureStore(a).put(s, 1) == 1
    assert StructureStore(b).get(s) is None                                     # another store: its own values


@pytest.mark.parametrize("seed", range(4))
def test_a_value_depends_only_on_the_fields_its_key_names(seed):
    """Change one field at a time in a fresh system: a field the key does not name leaves the value equal
    (bit for bit); a field it names and that a copy of the system replaces is never shared with the copy."""
    rng = np.random.default_rng(seed)
    s = random_system(rng, noise=True)
    for key, read in READERS.items():
        kept = read(s)
        for field in SYSTEM_FIELDS:
            if field == "horizon":
                continue                                   # every value's shape depends on it
            other = changed(s, field, rng)
            if field not in key.depends_on:
                assert same_values(read(other), kept), (key, field)
        if key.structural:
            assert not shared(read(changed(s, "A", rng)), kept)     # another structure: its own values
        else:
            assert not shared(read(s.with_mu(rng.uniform(0, 1, s.m))), kept)
            assert not shared(read(s.with_channel(GilbertElliott(p=[0.2] * s.m, r=[0.3] * s.m))), kept)


COPIES = {
    "with_mu": lambda s, rng: s.with_mu(rng.uniform(0, 1, s.m)),
    "with_mu schedule": lambda s, rng: s.with_mu(rng.uniform(0, 1, (s.horizon, s.m))),
    "with_x0": lambda s, rng: s.with_x0(rng.normal(size=s.n)),
    "with_channel": lambda s, rng: s.with_channel(GilbertElliott(p=rng.uniform(0.05, 0.9, s.m),
                                                                 r=rng.uniform(0.05, 1, s.m))),
}


@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), copy=st.sampled_from(sorted(COPIES)), noise=st.booleans())
def test_a_cached_value_equals_a_freshly_built_one_on_every_copy(seed, copy, noise):
    """with_mu / with_x0 / with_channel copies share the structural values of the system they copy (built
    once) and those values equal what a freshly constructed system (empty cache) builds."""
    rng = np.random.default_rng(seed)
    s = random_system(rng, noise=noise)
    originals = {key: read(s) for key, read in READERS.items()}
    twin = COPIES[copy](s, rng)
    fresh = System(**fields(twin))
    for key, read in READERS.items():
        value = read(twin)
        assert same_values(value, read(fresh)), (key, copy)
        assert all(not getattr(x, "flags", None) or not x.flags.writeable for x in value), key
        if key.structural:
            assert shared(value, originals[key]), (key, copy)
