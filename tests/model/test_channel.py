"""Gilbert–Elliott channels: validation naming each field, predicted schedules against matrix
powers of the transition matrix, TOML round trips, and the System that carries a channel."""

import tomllib

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import dumps_system, system_from_dict

BASE = {
    "plant": {"A": [[1.0, 0.1], [0.0, 1.0]], "B": [[0.0, 1.0], [1.0, 0.0]]},
    "cost": {"horizon": 6, "state_weight": [1.0, 1.0], "input_weight": [1.0, 1.0]},
    "state": {"x0": [1.0, 0.0]},
}


def with_channel(channel):
    return system_from_dict({**BASE, "channel": channel})


def ge(**changes):
    return {"model": "gilbert-elliott", "p": [0.1, 0.3], "r": [0.4, 0.2], **changes}


def marginals(p, r, hg, hb, b0, N):
    """Independent reference: the row vector (P(good), P(bad)) times powers of the transition matrix."""
    P = np.array([[1 - p, p], [r, 1 - r]])
    pi = np.array([b0, 1 - b0])
    out = []
    for _ in range(N):
        out.append(pi @ np.array([hg, hb]))
        pi = pi @ P
    return np.array(out)


@pytest.mark.parametrize("belief", [None, [0.9, 0.2], "state"])
def test_schedule_is_the_chain_marginal(belief):
    extra = {} if belief is None else ({"state": ["bad", "good"]} if belief == "state" else {"belief": belief})
    s = with_channel(ge(h_good=[0.95, 1.0], h_bad=[0.1, 0.0], **extra))
    ch = s.channel
    for i in range(2):
        b0 = ch.initial_belief[i, 0]
        ref = marginals(ch.p[i], ch.r[i], ch.h_good[i], ch.h_bad[i], b0, 6)
        np.testing.assert_allclose(s.mu_schedule[:, i], ref, rtol=1e-14, atol=1e-15)
    if belief is None:   # the stationary start: a constant schedule at the long-run rate
        np.testing.assert_allclose(s.mu_schedule, np.broadcast_to(ch.mean_rate, (6, 2)), rtol=1e-14)
        np.testing.assert_allclose(ch.stationary[:, 0], [0.4 / 0.5, 0.2 / 0.5], rtol=1e-15)
    if belief == "state":
        np.testing.assert_array_equal(ch.initial_belief, [[0.0, 1.0], [1.0, 0.0]])


def test_memoryless_chain_is_bernoulli_with_mu_r():
    s = with_channel({"model": "gilbert-elliott", "p": [0.3, 0.75], "r": [0.7, 0.25]})
    np.testing.assert_allclose(s.mu_schedule, np.broadcast_to([0.7, 0.25], (6, 2)), rtol=1e-15)
    np.testing.assert_array_equal(s.channel.correlation, [0.0, 0.0])


@pytest.mark.parametrize("extra", [{}, {"belief": [0.25, 1.0]}, {"state": ["good", "bad"]},
                                   {"h_good": [0.9, 0.8], "h_bad": [0.2, 0.05]}])
def test_toml_round_trip(extra, tmp_path):
    s = with_channel(ge(**extra))
    text = dumps_system(s)
    back = system_from_dict(tomllib.loads(text))
    assert back.channel == s.channel
    np.testing.assert_array_equal(back.mu_schedule, s.mu_schedule)
    path = pl.save_system(s, tmp_path / "ge.toml")
    assert pl.load_system(path).channel == s.channel
    assert ('state = ["good", "bad"]' in text) == ("state" in extra)


@pytest.mark.parametrize(
    ("channel", "error", "match"),
    [
        (ge(p=[0.1, 1.2]), pl.ProbabilityError, r"channel\.p: expected probabilities in \[0, 1\], found 1\.2"),
        (ge(r=[0.4, -0.1]), pl.ProbabilityError, r"channel\.r: expected probabilities"),
        (ge(r=[0.4]), pl.DimensionError, r"channel\.r: expected shape \(2,\)"),
        (ge(p=[0.1], r=[0.4]), pl.DimensionError, r"channel\.p: expected 2 channels"),
        (ge(h_good=[0.9, float("nan")]), pl.ProbabilityError, r"channel\.h_good: expected probabilities"),
        (ge(h_bad=[0.0, "x"]), pl.InputError, r"channel\.h_bad: expected numbers"),
        (ge(belief=[True, 0.5]), pl.InputError, r"channel\.belief: expected numbers in \[0, 1\], found bool"),
        (ge(belief=[0.5, 2.0]), pl.ProbabilityError, r"channel\.belief: expected probabilities"),
        (ge(state=["good", "ugly"]), pl.InputError, r'channel\.state: expected "good" or "bad"'),
        (ge(state=["good"]), pl.DimensionError, r"channel\.state: expected 2 states"),
        (ge(state=[1, 0]), pl.InputError, r'channel\.state: expected a list of "good" / "bad"'),
        (ge(state=["good", "bad"], belief=[0.5, 0.5]), pl.InputError, r"channel\.state/belief: expected at most one"),
        (ge(p=[0.0, 0.3], r=[0.0, 0.2]), pl.InputError, r"channel\.p: channel 0 has p \+ r = 0"),
        (ge(model="markov"), pl.InputError, r'channel\.p: unknown key for model "markov"'),
        (ge(model="hmm"), pl.InputError, r'channel\.model: expected "gilbert-elliott" or "markov"'),
        ({"p": [0.1, 0.3], "r": [0.4, 0.2]}, pl.InputError, r"channel\.model: .*found nothing"),
        ({"model": "gilbert-elliott", "p": [0.1, 0.3]}, pl.InputError, r"channel\.r: missing field"),
        ({**ge(), "mu": [0.5, 0.5]}, pl.InputError, r"channel: expected either a Gilbert-Elliott channel"),
        ({**ge(), "lag": 1}, pl.InputError, r"channel\.lag: unknown key"),
    ],
)
def test_bad_channel_names_its_field(channel, error, match):
    with pytest.raises(error, match=match):
        with_channel(channel)


def test_frozen_chain_with_a_belief_is_accepted():
    s = with_channel(ge(p=[0.0, 0.3], r=[0.0, 0.2], belief=[0.3, 0.5]))
    np.testing.assert_allclose(s.mu_schedule[:, 0], 0.3)


def test_channel_is_immutable_and_with_mu_drops_it():
    s = with_channel(ge())
    with pytest.raises(AttributeError):
        s.channel.p = np.zeros(2)
    with pytest.raises(ValueError, match="read-only"):
        s.channel.p[0] = 0.5
    assert s.with_mu([0.5, 0.5]).channel is None
    assert s.with_x0([0.0, 1.0]).channel == s.channel


def test_python_api_takes_a_channel_object():
    ch = GilbertElliott(p=[0.1, 0.3], r=[0.4, 0.2], belief=[1.0, 0.0])
    s = pl.System(A=BASE["plant"]["A"], B=BASE["plant"]["B"], horizon=4, state_weight=[1, 1],
                  input_weight=[1, 1], x0=[1, 0], channel=ch)
    assert s.channel is ch
    np.testing.assert_allclose(s.mu_schedule[1], [0.9, 0.2])
    with pytest.raises(pl.InputError, match=r"p: expected numbers in \[0, 1\], found list"):
        GilbertElliott(p=[[0.1]], r=[0.4])


def test_state_and_belief_together_name_the_field_once(tmp_path, capsys):
    path = tmp_path / "both.toml"
    source = (pl.save_system(pl.load_example("pendulum_bursty"), tmp_path / "ge.toml")).read_text()
    path.write_text(source.replace('model = "gilbert-elliott"', 'model = "gilbert-elliott"\nstate = ["good"]\n'
                                                                 'belief = [0.3]'))
    with pytest.raises(InputError) as err:
        pl.load_system(path)
    assert err.value.field == "channel.state/belief"
    assert main(["solve", str(path)]) == 2
    assert capsys.readouterr().err.startswith("packetloss-cvx: error: channel.state/belief: ")
