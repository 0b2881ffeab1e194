"""Plug-in laws against the exact minimiser under a Markov channel, per protocol, with the QP twin.

The plug-in law is the paper's law (Theorem 1, eq:opt-law-1 / eq:opt-law-2) with the chain's
predicted mu_t, which is the ``mu_schedule`` a System with a channel carries. Its loss is measured
in the protocol's exact expected cost ([`exact_cost`][packetloss_cvx.lq.markov_cost.exact_cost]). Importing this
module does not import cvxpy: the QP twin (`markov`) loads only where it is asked for.
"""

from __future__ import annotations

from ..lq.costs import closed_form
from ..lq.markov_cost import exact_closed_form, exact_cost
from ..model.protocols import check_protocol
from ..model.system import System, check_system
from ..results import MarkovSolution

__all__ = ["markov_solution"]


def markov_solution(system: System, protocol: str, qp: bool = True) -> MarkovSolution:
    """The exact minimiser of ``protocol``'s expected cost (with its QP twin when ``qp``), and how
    much the plug-in law loses against it.

    Time O(N (D^3 + m^3)), D = n (1 + m) (the augmented recursion), plus one Clarabel solve with ``qp``
    (O((N m)^3 + (N n)^2 N m): the QP twin is dense).

    Raises
    ------
    CrossCheckError
        The QP and the closed form disagree.
    NumericalError, ResourceError
        As [`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form] and `exact_qp`.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.1]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.1]))
    >>> res = markov_solution(s, "udp", qp=False)
    >>> bool(res.relative_loss > 0 and res.exact.cost <= res.plugin_cost)
    True
    """
    system = check_system(system)
    protocol = check_protocol(protocol)
    exact = exact_closed_form(system, protocol)
    twin = None
    if qp:
        from ..qp.markov import exact_qp  # cvxpy (1.5 s to import) only where a QP is asked for

        twin = exact_qp(system, protocol, reference=exact)
    plugin = closed_form(system.with_mu(system.mu_schedule), protocol)
    plugin_cost = exact_cost(system, plugin.inputs, protocol)
    loss = plugin_cost / exact.cost - 1.0 if exact.cost > 0 else 0.0
    return MarkovSolution(protocol=protocol, exact=exact, qp=twin, plugin_cost=plugin_cost, relative_loss=loss,
                          plan_expected_cost=exact_cost(system, plugin.inputs, "udp"))


