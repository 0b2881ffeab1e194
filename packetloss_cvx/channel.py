"""Gilbert–Elliott channels: bursty two-state links, a constructor of the one channel type.

Channel i is a two-state Markov chain S_{i,t} in {good, bad} with

    p_i = P(S_{t+1} = bad | S_t = good),   r_i = P(S_{t+1} = good | S_t = bad),

and a packet sent at step t arrives with probability ``h_good_i`` in the good state and
``h_bad_i`` in the bad one (the Gilbert channel: ``h_good = 1, h_bad = 0``). :func:`GilbertElliott`
builds it as a :class:`~packetloss_cvx.markov_channel.MarkovChannel` (state 0 = good,
``T = [[1 - p, p], [r, 1 - r]]``, ``d = (h_good, h_bad)``), which reads its parameters back
(``p``, ``r``, ``h_good``, ``h_bad``) and writes its TOML table back as given.

TOML (docs/design.md §4 and "Bursty links"): ``[channel] model = "gilbert-elliott"`` with per-channel arrays
``p``, ``r``, optional ``h_good`` (default 1), ``h_bad`` (default 0), and at most one of
``state = ["good", "bad"]`` or ``belief = [0.9, 0.2]`` (P(good)).
"""

from .markov_channel import GE_MODEL as MODEL
from .markov_channel import GilbertElliott

__all__ = ["MODEL", "GilbertElliott"]
