"""Found by the third hostile review (2026-11-22), tried as a new user from a fresh install.

References are independent of the code under test: a hand-built Markov-jump second-moment operator
(Costa, Fragoso, Marques 2005, Thm 3.9) for Gilbert channels, hand shapes and messages for bad input.
"""

import itertools
import json

import numpy as np
import pytest

import packetloss_cvx as pl
import packetloss_cvx.markov
from packetloss_cvx.cli import main
from packetloss_cvx.errors import InputError
from packetloss_cvx.markov import bursty_twin
from packetloss_cvx.simulation import closed_loop, critical_mu, dp_riccati, finite_horizon_costs


def _gilbert_radius(A: np.ndarray, B: np.ndarray, K: np.ndarray, p: np.ndarray, r: np.ndarray) -> float:
    """Mean-square radius of x+ = (A - B V K) x behind independent Gilbert channels (h_good 1, h_bad 0):
    the mode is the joint state, v_i = [channel i good]; block (b, a) of the operator is T_ab kron(A_a, A_a)."""
    modes = list(itertools.product((1, 0), repeat=B.shape[1]))     # 1 = good
    n = A.shape[0]
    op = np.zeros((len(modes) * n * n, len(modes) * n * n))
    for ia, a in enumerate(modes):
        Aa = A - B @ np.diag(a) @ K
        for ib, b in enumerate(modes):
            T = np.prod([(1 - p[i] if b[i] else p[i]) if a[i] else (r[i] if b[i] else 1 - r[i])
                         for i in range(len(a))])
            op[ib * n * n:(ib + 1) * n * n, ia * n * n:(ia + 1) * n * n] = T * np.kron(Aa, Aa)
    return float(max(abs(np.linalg.eigvals(op))))


def test_bernoulli_closed_loop_is_refused_behind_a_gilbert_elliott_chain():
    """closed_loop() on a bursty system used to answer with the Bernoulli radius 0.47 ("stable") where the
    loop behind the chain has radius 1.06 (not mean-square stable)."""
    system = bursty_twin(pl.load_example("two_actuator"), 0.95)
    gain = pl.closed_form(system, "tcp").gain
    ch = system.channel
    assert _gilbert_radius(system.A, system.B, gain, np.asarray(ch.p), np.asarray(ch.r)) > 1.02
    twin = closed_loop(system, gain, "tcp", mu=system.mu_schedule[0])      # the Bernoulli twin, asked for
    assert twin.stable
    assert twin.spectral_radius < 0.5
    for call in (lambda: closed_loop(system, gain, "tcp"), lambda: dp_riccati(system),
                 lambda: critical_mu(system, "tcp"), lambda: finite_horizon_costs(system, gain, 5)):
        with pytest.raises(InputError) as err:
            call()
        assert err.value.field == "channel"


def test_simulate_never_calls_a_bursty_loop_stable_that_is_not(tmp_path, capsys):
    system = bursty_twin(pl.load_example("two_actuator"), 0.95)
    path = pl.save_system(system, tmp_path / "bursty.toml")
    code = main(["simulate", str(path), "--closed-loop", "--samples", "50", "--steps", "5", "--json", "-q"])
    out, err = capsys.readouterr()
    if code == 0:   # a Markov-aware simulate may answer; it must not call the loop stable
        data = json.loads(out)
        assert all(not entry["closed_loop"]["stable"] for entry in data.values() if "closed_loop" in entry)
    else:
        assert code == 2
        assert len(err.strip().splitlines()) == 1
        assert "channel" in err


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


@pytest.mark.parametrize("call", [
    lambda s: pl.simulation.dp_finite_horizon(s, 10**9),
    lambda s: finite_horizon_costs(s, np.zeros((1, 1)), 10**9),
])
def test_a_billion_steps_is_refused_before_it_is_allocated(call):
    """dp_finite_horizon(system, 10**9) used to allocate 8 GB and loop for ever (killed after minutes)."""
    scalar = pl.System(A=[[2.0]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    with pytest.raises(InputError) as err:
        call(scalar)
    assert err.value.field == "steps"


def test_an_overflowing_gain_is_not_stable_and_not_a_linalg_crash():
    """A finite gain of 1e200 squared to inf in the second-moment operator: np.linalg raised LinAlgError
    (Kronecker path, n = 2) or 'SVD did not converge' with LAPACK noise on stderr (ARPACK path, n = 25).
    The operator is quadratic in (A, K), so the radius of the scaled loop times c^2 is exact: about 1e400."""
    from packetloss_cvx.simulation import is_mean_square_stable, mean_square_radius
    for n in (2, 25):
        A, B = np.diag([2.0] + [1.0] * (n - 1)), np.ones((n, 1))
        radius = mean_square_radius(A, B, np.full((1, n), 1e200), [0.5])
        assert radius > 1e300
        assert not is_mean_square_stable(radius)
    # the scalar reference: (a - mu k)^2 + mu (1 - mu) k^2
    expected = (2 - 0.5e120) ** 2 + 0.25e240
    assert mean_square_radius([[2.0]], [[1.0]], [[1e120]], [0.5]) == pytest.approx(expected, rel=1e-12)


def test_a_bursty_system_says_so_in_its_repr():
    """repr(load_example('pendulum_bursty')) was System('pendulum-bursty', ..., mu=[0.9]): a Bernoulli look-alike."""
    system = pl.load_example("pendulum_bursty")
    assert "GilbertElliott" in repr(system)
    assert "GilbertElliott" in system._repr_html_()
    assert "GilbertElliott" not in repr(system.with_mu([0.9]))   # with_mu drops the chain


def test_a_gilbert_elliott_repr_shows_what_was_given():
    from packetloss_cvx.channel import GilbertElliott
    assert repr(GilbertElliott(p=[0.1], r=[0.4])) == "GilbertElliott(m=1, p=[0.1], r=[0.4])"
    text = repr(GilbertElliott(p=[0.1], r=[0.4], state=["bad"]))
    assert text == "GilbertElliott(m=1, p=[0.1], r=[0.4], state=['bad'])"
    text = repr(GilbertElliott(p=[0.1], r=[0.4], h_good=0.9, h_bad=0.2, belief=[0.3]))
    assert text == "GilbertElliott(m=1, p=[0.1], r=[0.4], h_good=[0.9], h_bad=[0.2], belief=[0.3])"


@pytest.mark.parametrize(("argv", "field"), [
    (["solve", "two_actuator", "--out", "{tmp}/no-such-dir/out.json"], "--out"),
    (["solve", "two_actuator", "--out", "{tmp}"], "--out"),
    (["simulate", "two_actuator", "--closed-loop", "--save", "{tmp}/no-such-dir/runs.npz"], "--save"),
    (["simulate", "two_actuator", "--closed-loop", "--save", "{tmp}/runs.txt"], "--save"),
    (["simulate", "two_actuator", "--closed-loop", "--plot", "{tmp}/no-such-dir/loop.png"], "--plot"),
    (["simulate", "two_actuator", "--plot", "{tmp}/loop.png"], "--plot"),
])
def test_a_bad_output_path_is_refused_before_the_work(argv, field, tmp_path, capsys, monkeypatch):
    """These were refused only after the whole computation (a long audit or simulation lost to a typo)."""
    import importlib
    import sys
    for name in ("solve", "simulate"):
        monkeypatch.setitem(sys.modules, f"packetloss_cvx.cli.{name}", None)   # importing the command would fail
    importlib.invalidate_caches()
    code = main([a.replace("{tmp}", str(tmp_path)) for a in argv] + ["-q"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith(f"packetloss-cvx: error: {field}: ")
    assert len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())


def test_allocate_refuses_to_replace_a_gilbert_elliott_chain_silently(capsys):
    """allocate pendulum_bursty printed a Bernoulli mu* = 0.0049 for a file whose channel is a chain."""
    assert main(["allocate", "pendulum_bursty", "--protocol", "tcp", "--alpha", "20000", "--beta", "1"]) == 2
    assert capsys.readouterr().err.startswith("packetloss-cvx: error: channel: ")
    assert main(["allocate", "pendulum", "--protocol", "tcp", "--alpha", "20000", "--beta", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["status"] == "optimal"   # the same plant behind Bernoulli losses


def test_the_closed_loop_statespace_stays_discrete_time():
    """dt=0 returned a continuous-time StateSpace of the discrete-time matrix A - B M K (poles read as
    continuous-time ones: a stable loop looks unstable and the reverse); dt=-1 leaked control's ValueError."""
    control = pytest.importorskip("control")
    from packetloss_cvx.simulation import closed_loop_statespace
    s = pl.load_example("two_actuator")
    for dt in (0, None, -1.0, float("nan"), False, "0.1"):
        with pytest.raises(InputError) as err:
            closed_loop_statespace(s, np.eye(2), dt=dt)
        assert err.value.field == "dt"
    assert control.isdtime(closed_loop_statespace(s, np.eye(2), dt=0.1), strict=True)
    with pytest.raises(InputError) as err:   # was a TypeError: got multiple values for keyword argument 'A'
        pl.System.from_statespace(control.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], 1), A=[[2.0]], horizon=3,
                                  state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    assert err.value.field == "A"


@pytest.mark.parametrize(("call", "field"), [
    (lambda ch: pl.markov.plugin_schedule(ch, 10**9, "udp"), "horizon"),     # allocated 8 GB, then looped
    (lambda ch: pl.markov.channel_covariance(ch, 10**5), "horizon"),         # 80 GB
    (lambda ch: pl.markov.second_moments(ch, 0), "horizon"),                 # an empty array
    (lambda ch: pl.markov.channel_covariance(ch, -3), "horizon"),
    (lambda ch: pl.markov.filter_belief(ch, [1.5], [True]), "belief"),       # answered 0.98
    (lambda ch: pl.markov.filter_belief(ch, [0.5], [0.5]), "delivered"),     # half a packet, read as delivered
    (lambda ch: pl.markov.plugin_schedule(ch, 5, "tcp", acknowledged=[[2]]), "delivered"),
    (lambda ch: ch.beliefs(3, belief=[2.0]), "belief"),
])
def test_chain_functions_refuse_what_they_cannot_mean(call, field):
    channel = pl.load_example("pendulum_bursty").channel
    with pytest.raises(InputError) as err:
        call(channel)
    assert err.value.field == field


def test_the_gilbert_elliott_section_is_headed_once(capsys):
    """The text printed 'Gilbert-Elliott channel' as a heading and again as the next line's label."""
    assert main(["solve", "pendulum_bursty", "--no-qp"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sum(line.startswith("Gilbert-Elliott channel") for line in lines) == 1


def test_critical_mu_with_a_tolerance_below_double_spacing_ends():
    """tol=1e-20 bisected for ever: the bracket cannot shrink below the spacing of doubles near 0.75."""
    s = pl.System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    from packetloss_cvx.tolerances import MEAN_SQUARE_MARGIN
    t = critical_mu(s, [[2.0]], tol=1e-20)   # fixed k = a = 2: proved stable iff 4 (1 - mu) < 1 - margin
    assert t == pytest.approx(0.75 + MEAN_SQUARE_MARGIN / 4, abs=1e-15)


def test_every_packaged_example_is_named_in_the_help():
    """FILE's help listed pendulum and two_actuator, not pendulum_bursty (the one Gilbert-Elliott example)."""
    from packetloss_cvx.cli.parser import FILE_HELP
    from packetloss_cvx.io import example_names
    assert all(name in FILE_HELP for name in example_names())


def test_a_chain_beyond_the_mjls_size_is_not_stable_and_not_bad_input():
    """solve on a valid 7-channel Gilbert-Elliott file exited 2 ('expected at most 6 channels') from its
    stability line: the MJLS operator's 2^m modes are out of reach, the file is not bad input."""
    from packetloss_cvx.channel import GilbertElliott
    from packetloss_cvx.cli.solve import stability
    system = pl.System(A=[[0.9, 0.1], [0.0, 0.8]], B=np.ones((2, 7)), horizon=3, state_weight=[1.0, 1.0],
                       input_weight=[1.0] * 7, channel=GilbertElliott(p=[0.1] * 7, r=[0.3] * 7), x0=[1.0, 1.0])
    entry: dict = {}
    text = stability(system, np.zeros((7, 2)), entry)
    assert entry["stable"] is False
    assert entry["mean_square_spectral_radius"] is None
    assert "not computed" in text
