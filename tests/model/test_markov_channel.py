"""General finite-state Markov channels (markov_channel.MarkovChannel, ``[channel] model = "markov"``):
validation naming each field, schedules and covariances against enumeration of every state path, the
HMM filter against Bayes' rule by hand, the exact cost of a plan against enumeration of every loss
pattern, TOML and pickle round trips, and the two-state twin of a Gilbert–Elliott file end to end."""

import copy
import itertools
import json
import math
import pickle
import tomllib

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.model.chain import channel_covariance, filter_belief, second_moments, stacked_moments
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.files import dumps_system, system_from_dict
from packetloss_cvx.tolerances import (
    CHAIN_FORM_RTOL,
    KERNEL_ZERO_ATOL,
    PATH_AGREEMENT_RTOL,
    ROW_SUM_ATOL,
    SELF_CHECK_RTOL,
)

BASE = {
    "plant": {"A": [[1.0, 0.1], [0.0, 1.0]], "B": [[0.0, 1.0], [1.0, 0.0]]},
    "cost": {"horizon": 4, "state_weight": [1.0, 1.0], "input_weight": [1.0, 1.0]},
    "state": {"x0": [1.0, 0.0]},
}
T3 = [[0.7, 0.2, 0.1], [0.1, 0.5, 0.4], [0.3, 0.3, 0.4]]
T2 = [[0.9, 0.1], [0.6, 0.4]]


def chain(**changes):
    return {"model": "markov", "transition": [T3, T2], "delivery": [[1.0, 0.6, 0.0], [0.95, 0.1]], **changes}


def with_channel(channel):
    return system_from_dict({**BASE, "channel": channel})


def path_moments(T, d, b, N):
    """Independent reference: E[v_t] and E[v_s v_t] summed over every state path of length N."""
    T, d, b = np.asarray(T), np.asarray(d), np.asarray(b)
    mean, second = np.zeros(N), np.zeros((N, N))
    for path in itertools.product(range(len(d)), repeat=N):
        prob = b[path[0]] * np.prod([T[path[t], path[t + 1]] for t in range(N - 1)])
        h = d[list(path)]
        mean += prob * h
        second += prob * (np.outer(h, h) - np.diag(h * h) + np.diag(h))      # v^2 = v
    return mean, second


@pytest.mark.parametrize(
    ("channel", "error", "match"),
    [
        (chain(transition=[T3, [[0.9, 0.2], [0.6, 0.4]]]), pl.ProbabilityError,
         r"channel\.transition\[1\]: expected rows summing to 1 \(within 1e-09\); row 0 sums to 1\.1"),
        (chain(transition=[T3, [[1.1, -0.1], [0.6, 0.4]]]), pl.ProbabilityError,
         r"channel\.transition\[1\]: expected probabilities in \[0, 1\], found 1\.1"),
        (chain(transition=[T3, [[0.9, 0.1]]]), pl.DimensionError, r"channel\.transition\[1\]: expected a square"),
        (chain(transition=[T3, [[0.9, "x"], [0.6, 0.4]]]), pl.InputError,
         r"channel\.transition\[1\]: expected numbers"),
        (chain(transition=[T3, [[True, 0.0], [0.6, 0.4]]]), pl.InputError, r"channel\.transition\[1\]: expected num"),
        (chain(transition=[T3, [[0.9, 0.1], [0.6]]]), pl.InputError, r"channel\.transition\[1\]: expected a rectang"),
        (chain(transition=T2), pl.DimensionError, r"channel\.transition\[0\]: expected a square"),
        (chain(delivery=[[1.0, 0.6], [0.95, 0.1]]), pl.DimensionError,
         r"channel\.delivery\[0\]: expected shape \(3,\) \(one probability per state of transition\[0\]\)"),
        (chain(delivery=[[1.0, 0.6, 0.0]]), pl.DimensionError, r"channel\.delivery: expected 2 entries"),
        (chain(delivery=[[1.0, 0.6, 1.5], [0.95, 0.1]]), pl.ProbabilityError,
         r"channel\.delivery\[0\]: expected probabilities in \[0, 1\], found 1\.5"),
        (chain(state=[3, 0]), pl.InputError, r"channel\.state\[0\]: expected a state index 0\.\.2, found 3"),
        (chain(state=[0, 1.0]), pl.InputError, r"channel\.state\[1\]: expected a state index 0\.\.1"),
        (chain(state=[0]), pl.DimensionError, r"channel\.state: expected 2 entries"),
        (chain(belief=[[0.5, 0.5, 0.5], [1.0, 0.0]]), pl.ProbabilityError,
         r"channel\.belief\[0\]: expected probabilities summing to 1"),
        (chain(belief=[[0.5, 0.5], [1.0, 0.0]]), pl.DimensionError, r"channel\.belief\[0\]: expected shape \(3,\)"),
        (chain(state=[0, 0], belief=[[1.0, 0.0, 0.0], [1.0, 0.0]]), pl.InputError,
         r"channel\.state/belief: expected at most one"),
        (chain(transition=[[[1.0, 0.0, 0.0], [0.0, 0.5, 0.5], [0.0, 0.5, 0.5]], T2]), pl.InputError,
         r"channel\.transition\[0\]: the chain has more than one stationary distribution .* give state or belief"),
        (chain(lag=1), pl.InputError, r"channel\.lag: unknown key"),
        ({"model": "markov", "delivery": [[1.0]]}, pl.InputError, r"channel\.transition: missing field"),
        ({"model": "markov", "transition": [[[1.0]]]}, pl.InputError, r"channel\.delivery: missing field"),
        (chain(transition=[T3]), pl.DimensionError, r"channel\.delivery: expected 1 entries"),
        ({"model": "markov", "transition": [[[1.0]]], "delivery": [[1.0]]}, pl.DimensionError,
         r"channel\.transition: expected 2 channels \(one per actuator"),
        ({"model": "Markov", "transition": [[[1.0]]], "delivery": [[1.0]]}, pl.InputError,
         r"channel\.model: expected \"gilbert-elliott\" or \"markov\""),
    ],
)
def test_bad_chain_names_its_field(channel, error, match):
    with pytest.raises(error, match=match):
        with_channel(channel)


def test_rows_within_the_stated_tolerance_are_accepted_and_rescaled():
    T = [[0.7, 0.2, 0.1 + 0.5 * ROW_SUM_ATOL], [0.1, 0.5, 0.4], [0.3, 0.3, 0.4]]
    ch = MarkovChannel(transition=[T], delivery=[[1.0, 0.5, 0.0]])
    np.testing.assert_allclose(ch.transition[0].sum(axis=1), 1.0, rtol=0, atol=1e-15)
    with pytest.raises(pl.ProbabilityError, match="transition"):
        MarkovChannel(transition=[[[0.7, 0.2, 0.1 + 3 * ROW_SUM_ATOL], *T[1:]]], delivery=[[1.0, 0.5, 0.0]])


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_a_belief_off_one_by_3_row_sum_atols_is_refused_and_by_0_3_rescaled(factor, kept):
    """A belief (or initial distribution) is a probability vector summing to 1 within ROW_SUM_ATOL, as a row is."""
    belief = [0.3, 0.7 + factor * ROW_SUM_ATOL]
    if kept:
        ch = MarkovChannel(transition=[T2], delivery=[[1.0, 0.0]], belief=[belief])
        np.testing.assert_allclose(ch.belief[0], np.array(belief) / sum(belief), rtol=1e-15)
        assert abs(ch.belief[0].sum() - 1.0) <= 2e-16
    else:
        with pytest.raises(pl.ProbabilityError, match=r"belief\[0\]: expected probabilities summing to 1"):
            MarkovChannel(transition=[T2], delivery=[[1.0, 0.0]], belief=[belief])


@pytest.mark.parametrize(("factor", "unique"), [(3.0, True), (0.3, False)])
def test_a_stationary_start_needs_the_smallest_singular_value_above_stationary_gap(factor, unique):
    """A 3-state chain that lumps to the two-state chain with p = r = e (state 0 against states 1 and 2, which mix
    at once): the smallest singular value of [T' - I; 1'] is 2 e (p + r, the tolerance's own measurement; checked
    here by an SVD), put at factor STATIONARY_GAP. At 3 the stationary start is defined, (1/2, 1/4, 1/4) by hand; at
    0.3 the chain is taken as having two closed classes and a stationary start is refused naming the field."""
    from packetloss_cvx.tolerances import STATIONARY_GAP

    e = factor * STATIONARY_GAP / 2
    T = np.array([[1 - e, e / 2, e / 2], [e, (1 - e) / 2, (1 - e) / 2], [e, (1 - e) / 2, (1 - e) / 2]])
    smallest = np.linalg.svd(np.vstack([T.T - np.eye(3), np.ones((1, 3))]), compute_uv=False)[-1]
    assert smallest == pytest.approx(factor * STATIONARY_GAP, rel=1e-3)
    if unique:
        ch = MarkovChannel(transition=[T.tolist()], delivery=[[1.0, 0.5, 0.0]])
        # least squares on a system whose smallest singular value is 6e-12: accurate to about eps / 6e-12 = 4e-5
        # (measured 2.7e-5), which is what a chain that needs 1e11 steps to forget its start allows
        np.testing.assert_allclose(ch.stationary[0], [0.5, 0.25, 0.25], rtol=1e-4)
    else:
        with pytest.raises(pl.InputError, match=r"transition\[0\]: the chain has more than one stationary"):
            MarkovChannel(transition=[T.tolist()], delivery=[[1.0, 0.5, 0.0]])


def test_a_bad_chain_file_exits_2_with_one_line(capsys, tmp_path):
    text = dumps_system(with_channel(chain())).replace("0.95, 0.1", "0.95, 1.1")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code = main(["solve", str(path)])
    out, err = capsys.readouterr()
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert "channel.delivery[1]: expected probabilities in [0, 1], found 1.1" in err


@pytest.mark.parametrize("start", [None, {"state": [2, 0]}, {"belief": [[0.2, 0.5, 0.3], [0.25, 0.75]]}])
def test_schedule_and_covariance_match_every_state_path(start):
    s = with_channel(chain(**(start or {})))
    ch, N = s.channel, s.horizon
    C, R = channel_covariance(ch, N), second_moments(ch, N)
    for i, (T, d) in enumerate(zip(chain()["transition"], chain()["delivery"], strict=True)):
        b0 = ch.initial_belief[i, :len(d)]
        mean, second = path_moments(T, d, b0, N)
        np.testing.assert_allclose(s.mu_schedule[:, i], mean, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(R[i], second, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(C[i], second - np.outer(mean, mean), rtol=1e-12, atol=1e-15)
    if start is None:       # the stationary start: pi T = pi, mean rate pi . d, a constant schedule
        for i, T in enumerate(chain()["transition"]):
            k = len(T)
            np.testing.assert_allclose(ch.stationary[i, :k] @ np.array(T), ch.stationary[i, :k], atol=1e-15)
        np.testing.assert_allclose(s.mu_schedule, np.broadcast_to(ch.mean_rate, (N, 2)), rtol=1e-14)


def test_identical_rows_are_bernoulli_with_exact_zero_covariance():
    rows = [0.5, 0.3, 0.2]
    ch = MarkovChannel(transition=[[rows] * 3], delivery=[[1.0, 0.5, 0.0]])
    C = channel_covariance(ch, 5)[0]
    assert not ch.correlated
    np.testing.assert_array_equal(C - np.diag(np.diag(C)), np.zeros((5, 5)))
    np.testing.assert_allclose(ch.mean_rate, [0.5 + 0.15], rtol=1e-15)


def test_a_nilpotent_chain_is_correlated_although_its_other_eigenvalues_vanish():
    # T = 1 pi' + u w' with pi uniform, u = (1, -1, 0), w = (1, 1, -2) / 10: w'1 = 0, w'u = 0 and pi'u = 0, so
    # (T - 1 pi')^2 = 0: every eigenvalue but 1 is 0, T^j = 1 pi' from j = 2, yet steps 0 and 1 are correlated
    T = np.full((3, 3), 1 / 3) + np.outer([1.0, -1.0, 0.0], [0.1, 0.1, -0.2])
    ch = MarkovChannel(transition=[T.tolist()], delivery=[[1.0, 0.5, 0.0]])
    assert abs(ch.correlation[0]) < 1e-6
    assert ch.correlated
    mean, second = path_moments(ch.transition[0], [1.0, 0.5, 0.0], ch.stationary[0], 3)
    assert abs(second[0, 1] - mean[0] * mean[1]) > 1e-3
    np.testing.assert_allclose(channel_covariance(ch, 3)[0, 0, 1], second[0, 1] - mean[0] * mean[1], rtol=1e-12)


def test_filter_is_bayes_rule_then_the_chain():
    ch = MarkovChannel(transition=[T3], delivery=[[1.0, 0.6, 0.0]])
    prior = np.array([[0.2, 0.5, 0.3]])
    lost = np.array([0.2 * 0.0, 0.5 * 0.4, 0.3 * 1.0]) / (0.5 * 0.4 + 0.3)         # P(state | lost) by hand
    np.testing.assert_allclose(filter_belief(ch, prior, [False]), [lost @ np.array(T3)], rtol=1e-15)
    got = np.array([0.2, 0.5 * 0.6, 0.0]) / (0.2 + 0.3)
    np.testing.assert_allclose(filter_belief(ch, prior, [True]), [got @ np.array(T3)], rtol=1e-15)
    with pytest.raises(pl.InputError, match="delivered"):
        filter_belief(ch, prior, [True, False])
    with pytest.raises(pl.InputError, match="probability 0"):
        filter_belief(ch, np.array([[0.0, 0.0, 1.0]]), [True])


def test_exact_cost_matches_every_loss_pattern():
    """E[cost] of a plan under a 3-state and a 2-state chain, against the sum over every state path of both
    channels and every delivery pattern they allow (noise-free, so each pattern's cost is deterministic)."""
    s = with_channel(chain(belief=[[0.2, 0.5, 0.3], [0.25, 0.75]])).with_x0([1.0, -0.5])
    s = pl.System(A=s.A, B=s.B, horizon=3, state_weight=[1.0, 2.0], input_weight=[0.5, 1.0], x0=s.x0,
                  channel=s.channel)
    U = np.array([[0.3, -0.2], [-0.1, 0.4], [0.2, 0.1]])
    ch, N = s.channel, s.horizon
    total = 0.0
    per_channel = []
    for i, (T, d) in enumerate(zip(ch.transition, ch.delivery, strict=True)):
        outcomes = {}
        for path in itertools.product(range(len(d)), repeat=N):
            prob = ch.initial_belief[i, path[0]] * np.prod([T[path[t], path[t + 1]] for t in range(N - 1)])
            for v in itertools.product([0, 1], repeat=N):
                p = prob * np.prod([d[path[t]] if v[t] else 1 - d[path[t]] for t in range(N)])
                outcomes[v] = outcomes.get(v, 0.0) + p
        per_channel.append(outcomes)
    for v0, p0 in per_channel[0].items():
        for v1, p1 in per_channel[1].items():
            x, cost = s.x0.copy(), 0.0
            for t in range(N):
                applied = np.array([v0[t], v1[t]]) * U[t]
                cost += applied @ np.diag(s.input_weights[t]) @ applied
                x = s.A @ x + s.B @ applied
                cost += x @ s.state_weights[t] @ x
            total += p0 * p1 * cost
    assert exact_cost(s, U) == pytest.approx(total, rel=1e-12)
    sol = exact_closed_form(s)
    assert sol.cost == pytest.approx(exact_cost(s, sol.inputs), rel=1e-10)
    for k in range(3):                     # the minimiser: no perturbation of its plan costs less
        dU = np.random.default_rng(k).normal(size=U.shape) * 1e-3
        assert exact_cost(s, sol.inputs + dU) >= sol.cost * (1 - 1e-12)


def test_round_trips_equality_pickling_and_immutability():
    ch = with_channel(chain(belief=[[0.2, 0.5, 0.3], [0.25, 0.75]])).channel
    assert MarkovChannel.from_table(ch.to_dict()) == ch
    assert pickle.loads(pickle.dumps(ch)) == ch
    assert copy.deepcopy(ch) is ch
    assert ch != MarkovChannel.from_table(chain())
    assert ch != GilbertElliott(p=[0.1, 0.2], r=[0.3, 0.3])
    with pytest.raises(AttributeError, match="immutable"):
        ch.delivery = ()
    assert not ch.transition[0].flags.writeable
    assert repr(MarkovChannel.from_table(chain(state=[2, 1]))).endswith("state=[2, 1])")
    s = with_channel(chain(state=[2, 1]))
    again = system_from_dict(tomllib.loads(dumps_system(s)))
    assert again.channel == s.channel
    assert np.array_equal(again.mu_schedule, s.mu_schedule)
    Ts, ds, starts = zip(*s.channel.chain_matrices(), strict=True)
    assert [T.shape for T in Ts] == [(3, 3), (2, 2)]
    assert not any(a.flags.writeable for a in (*Ts, *ds, *starts))
    assert [b.tolist() for b in starts] == [[0.0, 0.0, 1.0], [0.0, 1.0]]


def test_gilbert_elliott_is_the_two_state_chain_with_its_closed_forms():
    """GilbertElliott(...) builds the one channel type: T = [[1 - p, p], [r, 1 - r]], d = (h_good, h_bad),
    pi0 = (b, 1 - b), its rates read back. Its schedule and covariance, computed by the k-state chain, agree with the
    two-state closed forms b_{t+1} = r + lambda b_t, mu = h_bad + (h_good - h_bad) b and
    Cov(v_t, v_s) = lambda^|t-s| b_u (1 - b_u) (h_good - h_bad)^2 (u = min(t, s)) within PATH_AGREEMENT_RTOL of each
    array's largest entry (two exact paths to one number); the chain typed as decimals agrees within CHAIN_FORM_RTOL."""
    p, r, hg, hb, b0 = [0.02, 0.3], [0.18, 0.1], [1.0, 0.9], [0.0, 0.2], [0.3, 0.6]
    ge = GilbertElliott(p=p, r=r, h_good=hg, h_bad=hb, belief=b0)
    assert type(ge) is MarkovChannel
    assert ge.sizes == (2, 2)
    for i in range(2):
        assert ge.transition[i].tolist() == [[1.0 - p[i], p[i]], [r[i], 1.0 - r[i]]]
        assert ge.delivery[i].tolist() == [hg[i], hb[i]]
        assert ge.initial_belief[i].tolist() == [b0[i], 1.0 - b0[i]]
    assert (ge.p.tolist(), ge.r.tolist(), ge.h_good.tolist(), ge.h_bad.tolist()) == (p, r, hg, hb)
    N = 40
    lam = 1.0 - np.array(p) - np.array(r)
    b = np.empty((N, 2))
    b[0] = b0
    for t in range(1, N):
        b[t] = np.array(r) + lam * b[t - 1]
    mu = np.array(hb) + (np.array(hg) - np.array(hb)) * b
    np.testing.assert_allclose(ge.correlation, lam, rtol=0, atol=PATH_AGREEMENT_RTOL)
    np.testing.assert_allclose(ge.delivery_schedule(N), mu, rtol=0, atol=PATH_AGREEMENT_RTOL * mu.max())
    C = channel_covariance(ge, N)
    lag = np.abs(np.subtract.outer(np.arange(N), np.arange(N)))
    first = np.minimum.outer(np.arange(N), np.arange(N))
    for i in range(2):
        ref = lam[i] ** lag * (b[:, i] * (1 - b[:, i]) * (hg[i] - hb[i]) ** 2)[first]
        ref[np.diag_indices(N)] = mu[:, i] * (1 - mu[:, i])
        np.testing.assert_allclose(C[i], ref, rtol=0, atol=PATH_AGREEMENT_RTOL * np.abs(ref).max())
    typed = MarkovChannel(transition=[[[0.98, 0.02], [0.18, 0.82]], [[0.7, 0.3], [0.1, 0.9]]],
                          delivery=[[1.0, 0.0], [0.9, 0.2]], belief=[[0.3, 0.7], [0.6, 0.4]])
    np.testing.assert_allclose(typed.delivery_schedule(N), ge.delivery_schedule(N), rtol=CHAIN_FORM_RTOL)
    np.testing.assert_allclose(channel_covariance(typed, N), C, rtol=0, atol=CHAIN_FORM_RTOL * np.abs(C).max())
    assert GilbertElliott(p=[0.02], r=[0.18]).stationary[0, 0] == 0.18 / (0.02 + 0.18)      # the closed form


def _numbers_agree(a, b, path=""):
    """Every number of two JSON documents agrees within CHAIN_FORM_RTOL relative (KERNEL_ZERO_ATOL absolute beside
    rounding-level values such as a relative loss of 1e-16); every string, flag and key is equal."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for key in a:
            _numbers_agree(a[key], b[key], f"{path}/{key}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            _numbers_agree(x, y, f"{path}[{k}]")
    elif isinstance(a, float) and isinstance(b, float) and not (math.isnan(a) and math.isnan(b)):
        assert abs(a - b) <= CHAIN_FORM_RTOL * max(abs(a), abs(b)) + KERNEL_ZERO_ATOL, (path, a, b)
    elif not (isinstance(a, float) and math.isnan(a)):
        assert a == b, path


@pytest.mark.parametrize("argv", [("solve", "--no-qp"), ("simulate", "--samples", "400", "--closed-loop", "--law",
                                                                    "all", "--steps", "15")])
def test_pendulum_bursty_typed_as_a_markov_table_gives_the_same_json(argv, capsys, tmp_path):
    """The file's Gilbert–Elliott table and the transition matrix a person types for it (T[1, 1] = 0.82, where
    1 - r is 0.8200000000000001): one chain to rounding, the same numbers within CHAIN_FORM_RTOL."""
    text = dumps_system(pl.load_example("pendulum_bursty"))
    assert 'model = "gilbert-elliott"\np = [0.02]\nr = [0.18]\nh_good = [1.0]\nh_bad = [0.0]\n' in text
    twin = text.replace('model = "gilbert-elliott"\np = [0.02]\nr = [0.18]\nh_good = [1.0]\nh_bad = [0.0]\n',
                        'model = "markov"\ntransition = [[[0.98, 0.02], [0.18, 0.82]]]\ndelivery = [[1.0, 0.0]]\n')
    path = tmp_path / "twin.toml"
    path.write_text(twin)
    docs = []
    for name in ("pendulum_bursty", str(path)):
        assert main([argv[0], name, "--json", "-q", *argv[1:]]) == 0
        docs.append(json.loads(capsys.readouterr().out))
    ge, mc = docs
    if argv[0] == "solve":       # the channel's own description differs, every number agrees
        assert mc["markov"].pop("channel")["model"] == "markov"
        assert ge["markov"].pop("channel")["model"] != "markov"
        assert mc["markov"].pop("belief") == [[0.9, 0.1]]
        assert ge["markov"].pop("belief") == [0.9]
        assert mc["markov"]["udp"]["relative_loss"] > 0.05
    else:
        assert (ge.pop("channel", "gilbert-elliott"), mc.pop("channel", "markov")) == ("gilbert-elliott", "markov")
    _numbers_agree(ge, mc)


def _differing(a, b, path=""):
    """The paths where two JSON documents hold different values (bits, not tolerances)."""
    if isinstance(a, dict):
        return [p for k in a for p in _differing(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list):
        return [p for k, (x, y) in enumerate(zip(a, b, strict=True)) for p in _differing(x, y, f"{path}[{k}]")]
    same = a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
    return [] if same else [path]


def test_a_chain_gives_the_same_bits_whichever_table_it_is_written_as(capsys, tmp_path):
    """The table a channel was read from (its ``form``) is presentation only: pendulum_bursty's Gilbert–Elliott chain
    written back as a "markov" table of the same arrays runs the same path, so solve --json and simulate --json give
    the same bits (the contract of one path run twice), and only the channel's own description differs."""
    ge = pl.load_example("pendulum_bursty")
    same = MarkovChannel(transition=ge.channel.transition, delivery=ge.channel.delivery)
    assert same.to_dict()["model"] == "markov"
    assert ge.channel.to_dict()["model"] == "gilbert-elliott"
    assert same.transition[0][1, 1] == 1.0 - 0.18 != 0.82
    assert same == ge.channel
    for method in ("recursion", "dense"):                  # both routes, whichever auto takes
        a, b = exact_closed_form(ge, method=method), exact_closed_form(ge.with_channel(same), method=method)
        assert a.cost == b.cost
        np.testing.assert_array_equal(a.inputs, b.inputs)
        assert exact_cost(ge, a.inputs) == exact_cost(ge.with_channel(same), a.inputs)
    path = tmp_path / "same.toml"
    path.write_text(dumps_system(ge.with_channel(same)))
    for argv in (("solve", "--no-qp"), ("simulate", "--samples", "300", "--closed-loop", "--law", "all", "--steps",
                                          "10")):
        docs = []
        for name in ("pendulum_bursty", str(path)):
            assert main([argv[0], name, "--json", "-q", *argv[1:]]) == 0
            docs.append(json.loads(capsys.readouterr().out))
        a, b = docs
        if argv[0] == "solve":
            assert a["markov"]["belief"] == [0.9]
            assert b["markov"]["belief"] == [[0.9, 0.1]]
            for doc in docs:
                doc["markov"].pop("channel")
                doc["markov"].pop("belief")
        assert _differing(a, b) == []


def test_periodic_and_reducible_chains_with_a_given_start():
    flip = MarkovChannel(transition=[[[0.0, 1.0], [1.0, 0.0]]], delivery=[[1.0, 0.0]], state=[0])
    assert not flip.belief_settles                                      # 1, 0, 1, 0, ... never settles
    assert flip.delivery_schedule(4)[:, 0].tolist() == [1.0, 0.0, 1.0, 0.0]
    assert MarkovChannel(transition=[[[0.0, 1.0], [1.0, 0.0]]], delivery=[[1.0, 0.0]],
                         belief=[[0.5, 0.5]]).belief_settles              # already the long-run distribution
    # two closed classes {0} and {1, 2}, started in the transient state 3: the long-run average by hand
    T = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.5, 0.5, 0.0], [0.0, 0.25, 0.75, 0.0], [0.5, 0.25, 0.0, 0.25]]
    ch = MarkovChannel(transition=[T], delivery=[[1.0, 0.5, 0.0, 0.0]], state=[3])
    # from 3: absorbed in {0} with probability 0.5 / 0.75 = 2/3, in {1, 2} with 1/3 (there 1/3, 2/3)
    np.testing.assert_allclose(ch.stationary, [[2 / 3, 1 / 9, 2 / 9, 0.0]], atol=1e-12)
    np.testing.assert_allclose(ch.mean_rate, [2 / 3 + 0.5 / 9], rtol=1e-12)


def test_bernoulli_is_the_one_state_chain():
    """MarkovChannel.bernoulli(mu): one-state chains, T = [[1]], d = (mu_i,). Behind them two_actuator keeps its
    schedule and the stacked moments of its independent Bernoulli deliveries (C = diag(mu (1 - mu)), exact zeros
    off it), and the exact Markov minimum is the paper's Bernoulli closed form (the UDP-like one through another
    algorithm, within SELF_CHECK_RTOL; measured 4.0e-15)."""
    s = pl.load_example("two_actuator")
    ch = MarkovChannel.bernoulli(s.mu_schedule[0])
    assert ch.sizes == (1, 1)
    assert ch.to_dict() == {"model": "markov", "transition": [[[1.0]], [[1.0]]], "delivery": [[0.9], [0.5]]}
    behind = s.with_channel(ch)
    np.testing.assert_array_equal(behind.mu_schedule, s.mu_schedule)
    v, C = stacked_moments(behind)
    np.testing.assert_array_equal(C, np.diag(v * (1.0 - v)))
    for protocol in ("udp", "tcp"):
        assert exact_closed_form(behind, protocol).cost == pytest.approx(pl.closed_form(s, protocol).cost,
                                                                         rel=SELF_CHECK_RTOL)
    with pytest.raises(pl.ProbabilityError, match=r"^channel\.rate"):
        MarkovChannel.bernoulli([0.5, 1.5], prefix="channel.")
