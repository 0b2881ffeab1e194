"""Derived systems and the per-structure cache (docs/design.md §4, "Derived systems";
docs/performance.md, "Section 17").

``System.with_channel`` (the fast path of markov.attach_channel) against the full validation of the
TOML round trip it replaces; the prediction matrices and Lyapunov weights kept on a system against the
same quantities built from a freshly validated copy (an empty cache); the cache's scope (copies that
keep the structure share it, copies that change it do not) and lifetime (it dies with the system).
"""

import gc
import weakref

import numpy as np
import pytest
import scipy.linalg

from packetloss_cvx.errors import DimensionError, InputError, ProbabilityError
from packetloss_cvx.lq.prediction import prediction
from packetloss_cvx.lq.recursion import condition_estimate, udp_variance_weights
from packetloss_cvx.model.chain import attach_channel, stacked_moments
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import load_example, system_from_dict
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.model.system import STRUCTURE_FIELDS, CacheKey, StructureStore, System, SystemStore
from packetloss_cvx.model.twins import bursty_twin

FIELDS = ("A", "B", "horizon", "state_weights", "input_weights", "mu_schedule", "x0", "initial_weight", "noise_cov",
          "name")
PREDICTION = ("Phi", "Gamma", "Psi", "Vbar", "Omega_p", "Omega_g", "Omega_gp", "Omega_d")


def fresh(system: System) -> System:
    """The same system validated from scratch (the reference: an empty cache, every field checked)."""
    return system_from_dict(system.to_dict())


def random_channel(rng: np.random.Generator, m: int) -> GilbertElliott:
    kind = rng.integers(3)
    kwargs = {"p": rng.uniform(0, 0.9, m), "r": rng.uniform(0.05, 1, m)}
    if kind == 1:
        kwargs["belief"] = rng.uniform(0, 1, m)
    elif kind == 2:
        kwargs.update(h_good=rng.uniform(0.5, 1, m), h_bad=rng.uniform(0, 0.5, m), state=["good", "bad"] * m)
        kwargs["state"] = kwargs["state"][:m]
    return GilbertElliott(**kwargs)


@pytest.mark.parametrize("seed", range(12))
def test_with_channel_equals_the_validated_round_trip(seed):
    rng = np.random.default_rng(seed)
    s = random_system(rng)
    chan = random_channel(rng, s.m)
    fast = attach_channel(s, chan)
    slow = system_from_dict({**s.to_dict(), "channel": chan.to_dict()})     # the path attach_channel took before
    for key in FIELDS:
        assert np.array_equal(getattr(fast, key), getattr(slow, key)), key
    assert fast.channel == slow.channel
    assert fast.to_dict() == slow.to_dict()
    assert s.channel is None                                                # the original is unchanged
    assert s.mu_schedule is not fast.mu_schedule


def test_with_channel_from_a_toml_table_validates_it_and_names_the_field():
    s = load_example("two_actuator")
    table = {"model": "gilbert-elliott", "p": [0.1, 0.2], "r": [0.3, 0.4]}
    assert s.with_channel(table).channel == GilbertElliott(p=[0.1, 0.2], r=[0.3, 0.4])
    with pytest.raises(ProbabilityError, match=r"^channel\.p: expected probabilities in \[0, 1\], found 1.5"):
        s.with_channel({**table, "p": [1.5, 0.2]})
    with pytest.raises(DimensionError, match=r"^channel\.p: expected 2 channels"):
        s.with_channel(GilbertElliott(p=[0.1], r=[0.3]))
    with pytest.raises(InputError, match=r"^channel\.model"):
        s.with_channel({"p": [0.1, 0.2], "r": [0.3, 0.4]})
    with pytest.raises(InputError, match="^channel: expected a GilbertElliott"):
        attach_channel(s, table)
    # the same errors as the full validation of a system file with that channel
    with pytest.raises(ProbabilityError, match=r"^channel\.p: expected probabilities in \[0, 1\], found 1.5"):
        system_from_dict({**s.to_dict(), "channel": {**table, "p": [1.5, 0.2]}})


@pytest.mark.parametrize("seed", range(8))
def test_cached_prediction_equals_a_fresh_one(seed):
    rng = np.random.default_rng(100 + seed)
    s = random_system(rng)
    first = prediction(s)
    copies = [s.with_mu(rng.uniform(0, 1, s.m)), s.with_x0(rng.normal(size=s.n)),
              bursty_twin(s, 0.7), s.with_mu(rng.uniform(0, 1, (s.horizon, s.m)))]
    for copy in copies:
        cached, reference = prediction(copy), prediction(fresh(copy))
        assert cached.Omega_g is first.Omega_g                 # shared: built once for the structure
        for key in PREDICTION:
            assert np.array_equal(getattr(cached, key), getattr(reference, key)), key
            assert not getattr(cached, key).flags.writeable, key
        assert np.array_equal(cached.Vbar, copy.mu_schedule.ravel())
        assert cached.Omega is first.Omega
        assert np.array_equal(cached.Omega, scipy.linalg.block_diag(*copy.state_weights))
        assert cached.noise_term == reference.noise_term
        d, noise = udp_variance_weights(copy)
        d_ref, noise_ref = udp_variance_weights(fresh(copy))
        assert np.array_equal(d, d_ref)
        assert noise == noise_ref
        assert not d.flags.writeable
        reference = (float(np.sum(d_ref)) + copy.input_weights.max()) / copy.input_weights.min()
        assert condition_estimate(copy) == condition_estimate(copy, (d, noise)) == reference


def test_noise_term_is_shared_and_equals_the_trace():
    s = random_system(np.random.default_rng(7), noise=True)
    p = prediction(s)
    trace = float(np.trace(p.Omega_l @ p.Sigma_W))
    assert np.isclose(p.noise_term, trace, rtol=1e-12, atol=0)
    assert prediction(s.with_mu(np.full(s.m, 0.3))).noise_term == p.noise_term


def test_a_copy_with_another_structure_does_not_share_the_cache():
    s = load_example("pendulum")
    p = prediction(s)
    longer = System(A=s.A, B=s.B, horizon=s.horizon + 1, state_weights=list(s.state_weights) + [s.state_weights[-1]],
                    input_weight=s.input_weights[0], mu=s.mu_schedule[0], x0=s.x0)
    assert prediction(longer).Omega_g.shape != p.Omega_g.shape
    marker = StructureStore(CacheKey("test.marker", ("A",)))
    marker.put(s, 1)
    for copy in (s.with_mu(np.full(s.m, 0.5)), s.with_x0(np.ones(s.n))):
        assert marker.get(copy) == 1                     # the copies share the structure
    assert marker.get(longer) is None                    # another structure: nothing kept for it
    assert set(STRUCTURE_FIELDS) <= set(System.__slots__)


def test_large_values_are_not_kept():
    s = load_example("two_actuator")
    large = StructureStore(CacheKey("test.large", ("A", "B")))
    assert large.put(s, 1, nbytes=10**12) == 1
    assert large.get(s) is None


def test_the_cache_dies_with_its_systems():
    s = random_system(np.random.default_rng(3))
    copy = s.with_mu(np.full(s.m, 0.4))
    held = weakref.ref(prediction(copy).Omega_g)
    del s
    gc.collect()
    assert held() is not None                  # the copy shares the store and is alive
    del copy
    gc.collect()
    assert held() is None


def test_own_cache_is_not_shared_with_copies():
    s = random_system(np.random.default_rng(11))
    twin = bursty_twin(s, 0.6)
    v, C = stacked_moments(twin)
    assert stacked_moments(twin)[1] is C                     # kept on the twin
    assert not C.flags.writeable
    v_ref, C_ref = stacked_moments(fresh(twin))
    assert np.array_equal(v, v_ref)
    assert np.array_equal(C, C_ref)
    plain = twin.with_mu(twin.mu_schedule)                   # the same mu_t without the chain: independent losses
    assert np.array_equal(stacked_moments(plain)[1], np.diag(v * (1 - v)))
    value = SystemStore(CacheKey("test.value", ("x0",)))
    assert value.put(twin, 1) == 1
    assert value.get(twin) == 1
    assert value.get(twin.with_x0(np.zeros(twin.n))) is None               # a copy has its own store


def test_no_kept_array_has_a_writable_base():
    """A kept array is read-only and so is whatever it views: ``p.Gamma.base`` was the writable 4-d array it
    was filled through, so ``p.Gamma.base[...] = 0`` changed every later prediction of the system (and the
    Markov covariance C likewise)."""
    s = System(A=[[1.1, 0.2], [0.0, 0.8]], B=[[1.0], [0.5]], horizon=5, state_weight=[1.0, 2.0],
               input_weight=[1.0], mu=[0.6], x0=[1.0, -1.0])
    bursty = s.with_channel(GilbertElliott(p=[0.1], r=[0.3]))
    p = prediction(s)
    kept = [getattr(p, name) for name in ("Phi", "Gamma", "Psi", "Vbar", "Omega_p", "Omega_g", "Omega_gp", "Omega_d",
                                          "Omega")]
    kept += [udp_variance_weights(s)[0], *stacked_moments(bursty)]
    for arr in kept:
        base = arr
        while base is not None:
            assert not base.flags.writeable
            base = base.base if isinstance(base.base, np.ndarray) else None
    expected = np.array([[1.0, 0.0], [0.5, 0.0], [1.2, 1.0], [0.4, 0.5]])   # [[B, 0], [A B, B]] at N = 2
    short = System(A=[[1.1, 0.2], [0.0, 0.8]], B=[[1.0], [0.5]], horizon=2, state_weight=[1.0, 2.0],
                   input_weight=[1.0], mu=[0.6], x0=[1.0, -1.0])
    assert np.allclose(prediction(short).Gamma, expected, rtol=0, atol=1e-15)
