"""The delivery-versus-power models (allocation/delivery.py): mu(P), its inverse and slope against the
formulas by hand, concavity, the unit of power, bad input, the [power] table of a system file."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx import load_system
from packetloss_cvx.allocation.delivery import load_power, power_model
from packetloss_cvx.errors import InputError

MODELS = {
    "exponential": dict(scale=[1.5]),
    "rayleigh": dict(scale=[0.7]),
    "table": dict(table=[[0.0, 0.0], [1.0, 0.3], [2.0, 0.5], [5.0, 0.9]]),          # concave
    "table-s": dict(table=[[0.0, 0.0], [1.0, 0.05], [2.0, 0.6], [4.0, 0.9]]),       # not concave
}


def model_of(name, m=1):
    kw = MODELS[name]
    if "scale" in kw:
        return power_model(name, m, scale=kw["scale"] * m)
    return power_model("table", m, table=kw["table"])


def test_model_formulas_against_hand_values():
    e = power_model("exponential", 2, scale=[1.0, 2.0])
    assert np.allclose(e.mu(np.array([1.0, 2.0])), 1 - np.exp(-1.0))
    r = power_model("rayleigh", 1, scale=2.0)
    assert np.allclose(r.mu(np.array([4.0])), np.exp(-0.5))
    assert r.mu(np.array([0.0]))[0] == 0.0
    t = power_model("table", 2, table=[[0, 0, 0.1], [2, 0.5, 0.3], [4, 0.6, 0.9]])
    assert np.allclose(t.mu(np.array([1.0, 3.0])), [0.25, 0.6])
    assert np.allclose(t.mu(np.array([9.0, 9.0])), [0.6, 0.9])
    assert np.allclose(t.power(np.array([0.25, 0.6])), [1.0, 3.0])
    assert np.isinf(t.power(np.array([0.7, 0.5]))[0])
    assert np.allclose(e.slope(np.array([0.0, 2.0])), [1.0, np.exp(-1.0) / 2])      # d/dP (1 - exp(-P/c))
    assert np.allclose(r.slope(np.array([2.0])), 2 / 4 * np.exp(-1.0))            # c/P^2 exp(-c/P)


def test_model_inverse_and_concavity():
    for name in ("exponential", "rayleigh", "table", "table-s"):
        model = model_of(name)
        for mu in (0.2, 0.45, 0.85):
            assert np.isclose(model.mu(model.power(np.array([mu])))[0], mu, rtol=1e-12)
    assert model_of("exponential").concave_from()[0] == 0
    assert model_of("table").concave_from()[0] == 0
    assert np.isinf(model_of("table-s").concave_from()[0])
    assert model_of("rayleigh").concave_from()[0] == 0.35
    # rayleigh's second derivative changes sign at c/2 (finite differences)
    r, h = model_of("rayleigh"), 1e-4
    second = [(r.mu(np.array([p + h])) - 2 * r.mu(np.array([p])) + r.mu(np.array([p - h])))[0] for p in (0.3, 0.4)]
    assert second[0] > 0 > second[1]


@pytest.mark.parametrize(("kw", "match"), [
    (dict(model="exponential", scale=[0.0]), "power.scale: expected positive"),
    (dict(model="rayleigh", scale=[-1.0]), "power.scale: expected positive"),
    (dict(model="exponential", scale=[float("nan")]), "power.scale: expected finite"),
    (dict(model="table", table=[[0, 0], [1, 0.5], [2, 0.4]]), "must not fall"),
    (dict(model="table", table=[[0, 0], [1, 1.5]]), r"must lie in \[0, 1\]"),
    (dict(model="table", table=[[0, -0.1], [1, 0.5]]), r"must lie in \[0, 1\]"),
    (dict(model="table", table=[[0, 0], [0, 0.5]]), "powers must increase"),
    (dict(model="table", table=[[1, 0], [2, 0.5]]), "first row's power must be 0"),
    (dict(model="shannon", scale=[1.0]), "power.model: expected one of"),
])
def test_model_refuses_bad_input(kw, match):
    model = kw.pop("model")
    with pytest.raises(InputError, match=match):
        power_model(model, 1, **kw)


def test_power_table_in_a_system_file(tmp_path):
    (tmp_path / "curve.csv").write_text("power,mu\n0,0\n1,0.4\n3,0.9\n")
    base = (load_system("two_actuator"),)
    from packetloss_cvx.model.files import dumps_system
    text = dumps_system(base[0])
    (tmp_path / "a.toml").write_text(text + '\n[power]\nmodel = "table"\ntable = "curve.csv"\n')
    (tmp_path / "b.toml").write_text(text + '\n[power]\nmodel = "exponential"\nscale = [1.0, 2.0]\n')
    (tmp_path / "c.toml").write_text(text + '\n[power]\nmodel = "exponential"\nscale = [1.0, -2.0]\n')
    assert np.allclose(load_power(tmp_path / "a.toml", 2).mu(np.array([2.0, 0.5])), [0.65, 0.2])
    assert np.allclose(load_power(tmp_path / "b.toml", 2).scale, [1.0, 2.0])
    assert load_system(tmp_path / "b.toml").m == 2             # the system loader passes [power] by
    with pytest.raises(InputError, match="power.scale"):
        load_power(tmp_path / "c.toml", 2)


def test_unit_of_power_is_the_models_own():
    """The conic program's variable is P / unit: c per channel, a table's least power reaching half its last mu
    (hand values: 0.45 on (1, 0.3)-(2, 0.5) is at P = 1.75; a channel at its last mu from P = 0 takes the last
    power)."""
    assert power_model("exponential", 2, scale=[1e-12, 3.0]).unit().tolist() == [1e-12, 3.0]
    assert power_model("rayleigh", 1, scale=7.0).unit().tolist() == [7.0]
    assert np.allclose(model_of("table", 2).unit(), [1.75, 1.75], rtol=1e-15)
    flat = power_model("table", 2, table=[[0.0, 0.0, 0.6], [4.0, 0.8, 0.6]])
    assert np.allclose(flat.unit(), [2.0, 4.0], rtol=1e-15)


def test_rayleigh_majorant_lies_above_the_curve_and_touches_it_at_the_tangents():
    """f(P) = exp(-c/P) on a fine grid (hand formula): the majorant is >= f everywhere on [0, 300 c], equal to it
    at each tangent power p c (p >= 1), concave, and refuses another model."""
    from packetloss_cvx.allocation.delivery import rayleigh_majorant

    c = np.array([0.7, 2.0])
    model = power_model("rayleigh", 2, scale=c)
    at = np.array([0.4, 1.0, 1.7, 3.0, 12.0])                      # 0.4 is raised to 1: below it f is convex
    major = rayleigh_majorant(model, at)
    assert np.all(major.concave_from() == 0)
    for i in range(2):
        P = np.linspace(0.0, 300 * c[i], 300001)
        f = np.exp(-c[i] / np.maximum(P, 1e-300))
        g = major.mu(np.outer(P, np.eye(2)[i]))[:, i]
        assert np.all(g >= f - 1e-15)
        touch = np.array([1.0, 1.7, 3.0, 12.0]) * c[i]
        assert np.allclose(major.mu(np.outer(touch, np.eye(2)[i]))[:, i], np.exp(-1 / np.array([1.0, 1.7, 3.0, 12.0])),
                           rtol=1e-12)
    with pytest.raises(InputError, match="rayleigh majorant"):
        rayleigh_majorant(power_model("exponential", 1, scale=1.0), at)
