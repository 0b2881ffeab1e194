"""The acknowledgement link priced: the TCP-like protocol needs a perfect acknowledgement
link, which the paper's communication cost leaves out (its conclusion). For one alpha, the cheapest
TCP-like design plus the link's price against the cheapest UDP-like design, in either currency: beta'mu
([`allocate`][packetloss_cvx.allocation.api.allocate]) or total transmit power
([`.power.least_power`][packetloss_cvx.allocation.power.least_power]).

Theorem 2 (`J*_udp` >= `J*_tcp`) makes every UDP-like design a TCP-like one of no greater cost, so the
break-even price ``udp_total - tcp_total`` is >= 0 (to the certified gaps): the UDP-like design wins when the
acknowledgement link costs more than that.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import InfeasibleError, InputError
from ..model.system import System
from ..results import ProtocolChoice
from .api import allocate
from .delivery import PowerModel
from .grammar import check_number
from .power import least_power

__all__ = ["ack_break_even", "best_protocol", "break_even_of"]


def _design(system: System, protocol: str, alpha: float, beta: Any, model: PowerModel | None,
            options: dict[str, Any]):
    if model is None:
        return allocate(system, protocol, alpha, beta, **options)
    return least_power(system, protocol, model, alpha, **options)


def best_protocol(system: System, alpha: float, beta: Any = None, ack_price: float = 0.0,
                  model: PowerModel | None = None, **options: Any) -> ProtocolChoice:
    """The cheaper of the TCP-like design plus ``ack_price`` and the UDP-like design, both for ``alpha``.

    Parameters
    ----------
    system : System
    alpha : float
        The bound on J* both designs meet.
    beta : array_like or None
        Prices of mu (the paper's beta'mu); None with ``model``.
    ack_price : float
        The acknowledgement link's price, >= 0, in the designs' currency (beta'mu, or power with ``model``).
    model : PowerModel or None
        Buy power instead of mu ([`.power`][packetloss_cvx.allocation.power]); then the totals are total powers.
    options
        Passed to [`allocate`][packetloss_cvx.allocation.api.allocate] or
        [`.power.least_power`][packetloss_cvx.allocation.power.least_power] (bounds, constraints, gap, max_boxes,
        time_limit, progress; max_power with a model).

    Returns
    -------
    ProtocolChoice
        Both designs, their totals (``tcp_total`` includes the link), the choice (UDP-like on a tie: no
        link to build), ``certified`` (the chosen total is at most the other's proven lower bound) and
        ``break_even``: the link price above which the UDP-like design wins.

    Raises
    ------
    InfeasibleError
        No TCP-like design meets alpha, hence no UDP-like one (Theorem 2).

    Notes
    -----
    One TCP-like and one UDP-like problem (see their costs).

    Examples
    --------
    Two decoupled copies of x' = x + v u (N = 1), alpha = 1.5, beta = (1, 2). UDP-like: sum (1 - mu_i/2) <= 1.5
    is mu1 + mu2 >= 1, cheapest at (1, 0): 1. TCP-like: sum 1/(1 + mu_i) <= 1.5, KKT 1 + mu1 = sqrt(2) (1 + mu2),
    so 1 + mu2 = (1 + 1/sqrt(2)) / 1.5 and beta'mu = 0.8856. An acknowledgement link of 0.2 tips it to UDP-like:

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> c = best_protocol(t, 1.5, [1.0, 2.0], ack_price=0.2)
    >>> y = (1 + 1 / np.sqrt(2)) / 1.5
    >>> c.choice, c.certified, bool(np.isclose(c.break_even, 1 - (np.sqrt(2) * y - 1 + 2 * (y - 1)), atol=1e-3))
    ('udp', True, True)
    """
    alpha = check_number(alpha, "alpha")
    price = check_number(ack_price, "ack_price")
    if price < 0:
        raise InputError("ack_price", f"expected a price >= 0, found {price:g}")
    if (beta is None) == (model is None):
        raise InputError("beta", "give the prices beta of mu or a power model, not both or neither")
    try:
        tcp = _design(system, "tcp", alpha, beta, model, options)
    except InfeasibleError as err:
        raise InfeasibleError(f"no TCP-like design meets alpha = {alpha:g}, hence no UDP-like one (Theorem 2): "
                              f"{err}", err.min_cost) from None
    try:
        udp = _design(system, "udp", alpha, beta, model, options)
    except InfeasibleError:
        udp = None

    def total(design) -> tuple[float, float]:
        if model is None:
            return design.communication_cost, design.lower_bound
        return design.total_power, design.lower_bound

    design, t_lower = total(tcp)
    t_value, t_lower = design + price, t_lower + price
    u_value, u_lower = total(udp) if udp is not None else (np.inf, np.inf)
    choice = "udp" if u_value <= t_value else "tcp"
    certified = bool(u_value <= t_lower) if choice == "udp" else bool(t_value <= u_lower)
    # the break-even from the designs alone: (design + price) - price loses the design's digits to a dear link
    return ProtocolChoice(alpha=alpha, currency="beta'mu" if model is None else "power", ack_price=price,
                          tcp=tcp, udp=udp, tcp_total=t_value, udp_total=u_value, choice=choice,
                          certified=certified, break_even=u_value - design)


def ack_break_even(system: System, alphas: Sequence[float], beta: Any = None, model: PowerModel | None = None,
                   **options: Any) -> dict[str, np.ndarray]:
    """The study over alpha: for each alpha the cheapest TCP-like and UDP-like totals and the break-even
    acknowledgement price (UDP-like wins above it; inf where no UDP-like design meets alpha, nan where no
    TCP-like one does). O(len(alphas)) pairs of designs.

    Examples
    --------
    One step of x' = x + v u from x0 = 1: TCP-like 1/(1 + mu) <= alpha costs 1/alpha - 1, UDP-like 1 - mu/2 <= alpha
    costs 2 (1 - alpha):

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> study = ack_break_even(s, [0.8, 0.9], [1.0], gap=1e-7)
    >>> bool(np.allclose(study["break_even"], [0.4 - 0.25, 0.2 - 1 / 9], atol=1e-6))
    True
    """
    rows = []
    for alpha in alphas:
        try:
            c = best_protocol(system, alpha, beta, 0.0, model, **options)
            rows.append((float(alpha), c.tcp_total, c.udp_total, c.break_even))
        except InfeasibleError:
            rows.append((float(alpha), np.nan, np.nan, np.nan))
    data = np.array(rows, dtype=float).reshape(-1, 4)
    return {"alpha": data[:, 0], "tcp_total": data[:, 1], "udp_total": data[:, 2], "break_even": data[:, 3]}


def break_even_of(tcp_rows: Sequence[dict], udp_rows: Sequence[dict]) -> dict[str, list]:
    """The break-even acknowledgement prices from two Pareto curves already computed at the same alphas
    ([`pareto_curve`][packetloss_cvx.studies.allocation.pareto_curve] rows, as ``reproduce`` holds them): ``udp - tcp``
    of the communication costs, None where either design is missing. O(rows), no solve.

    Examples
    --------
    >>> break_even_of([{"alpha": 1.0, "communication_cost": 0.5}, {"alpha": 2.0, "communication_cost": 0.1}],
    ...               [{"alpha": 1.0, "communication_cost": 0.75}, {"alpha": 2.0, "communication_cost": None}])
    {'alpha': [1.0, 2.0], 'break_even': [0.25, None]}
    """
    alphas, prices = [], []
    for t, u in zip(tcp_rows, udp_rows, strict=True):
        if t["alpha"] != u["alpha"]:
            raise InputError("udp_rows", f"the curves' alphas differ: {t['alpha']} and {u['alpha']}")
        alphas.append(float(t["alpha"]))
        missing = t["communication_cost"] is None or u["communication_cost"] is None
        prices.append(None if missing else float(u["communication_cost"]) - float(t["communication_cost"]))
    return {"alpha": alphas, "break_even": prices}
