"""Markov channels (Gilbert–Elliott and k-state) end to end: prediction from the chain, the exact expected cost
under correlated losses and its minimisers (augmented recursion, dense closed form and QP), Markov jump
linear systems, and burstiness sweeps. One job per module; the channel descriptions themselves are
:mod:`packetloss_cvx.channel` and :mod:`packetloss_cvx.markov_channel`.

    chain.py       beliefs, the HMM filter, plug-in schedules, R = E[v v'] in O(N^2 m)
    exact_cost.py  E[cost] of a plan under correlated losses, its closed-form minimiser (method: recursion | dense)
    augmented.py   that cost as an LQ problem on the augmented state: O(N) recursion and forward referee
    qp.py          the same minimisation as a cvxpy + Clarabel QP, cross-checked
    compare.py     plug-in laws against the exact minimiser, per protocol; bursty twins of a system (all or one channel)
    mjls.py        the loop as a Markov jump linear system: mean-square radius, coupled Riccati gains
    sweep.py       burstiness sweeps at fixed average delivery rates; the (mean rate × burstiness) map of a channel

``exact_qp`` is imported on first use (PEP 562): the QP module imports cvxpy (slow to import), which the closed-form
paths that use this package (``solve --no-qp``, ``simulate``, the audit's closed-form claims) never need.
"""

import importlib
from typing import TYPE_CHECKING, Any

from .chain import (
    attach_channel,
    chain_matrices,
    channel_covariance,
    filter_belief,
    plugin_schedule,
    plugin_system,
    second_moments,
    stacked_moments,
)
from .compare import bursty_twin, channel_twin, gilbert_family, markov_solution
from .exact_cost import correlation_term, exact_closed_form, exact_cost, exact_hessian
from .mjls import coupled_riccati, mean_square_radius, mode_chain, second_moment_operator
from .sweep import burstiness_map, burstiness_sweep

if TYPE_CHECKING:
    from .qp import exact_qp

__all__ = [
    "attach_channel", "burstiness_map", "burstiness_sweep", "bursty_twin", "chain_matrices", "channel_covariance",
    "channel_twin", "correlation_term", "coupled_riccati",
    "exact_closed_form", "exact_cost", "exact_hessian", "exact_qp", "filter_belief", "gilbert_family",
    "markov_solution",
    "mean_square_radius", "mode_chain", "plugin_schedule", "plugin_system", "second_moment_operator",
    "second_moments", "stacked_moments",
]


def __getattr__(name: str) -> Any:
    """``exact_qp`` from :mod:`.qp` on first use (PEP 562)."""
    if name != "exact_qp":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = globals()[name] = importlib.import_module(f"{__name__}.qp").exact_qp
    return value
