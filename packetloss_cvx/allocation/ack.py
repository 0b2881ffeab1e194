"""The acknowledgement link priced: the TCP-like protocol needs a perfect acknowledgement
link, which the paper's communication cost leaves out (its conclusion). For one alpha, the cheapest
TCP-like design plus the link's price against the cheapest UDP-like design, in either currency: beta'mu
([`allocate`][packetloss_cvx.allocation.api.allocate]) or total transmit power
([`.power.least_power`][packetloss_cvx.allocation.power.least_power]).

Theorem 2 (`J*_udp` >= `J*_tcp`) makes every UDP-like design a TCP-like one of no greater cost, so the
break-even price ``udp_total - tcp_total`` is >= 0 (to the certified gaps): the UDP-like design wins when the
acknowledgement link costs more than that.

The price on two cost bases (`ACK_BASES`), side by side. "paper": the TCP-like design on the paper's `J*_tcp`, a
first-moment lower bound that no controller attains; "attainable": the TCP-like design on the cost its best law
attains over the horizon (``allocate(..., target="attainable")``, the finite-horizon DP with acknowledgements). The
UDP-like design is the same on both: its `J*_udp` is the exact expected cost of its plan, attained already. A
designer prices the link on the attainable basis: on the paper's, the TCP-like design looks cheaper than any loop
that meets alpha can be, and the break-even price is too high (two to eight times, on the two-actuator system).
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

__all__ = ["ACK_BASES", "ack_break_even", "attainable_break_even", "best_protocol", "break_even_of"]

#: the cost bases the TCP-like design of the acknowledgement price is made on (module docstring)
ACK_BASES = ("paper", "attainable")


def _design(system: System, protocol: str, alpha: float, beta: Any, model: PowerModel | None,
            options: dict[str, Any]):
    if model is None:
        return allocate(system, protocol, alpha, beta, **options)
    return least_power(system, protocol, model, alpha, **options)


def _attainable_design(system: System, alpha: float, beta: Any, model: PowerModel | None,
                       options: dict[str, Any]) -> tuple[Any, str]:
    """The TCP-like design on the attainable cost and why it is None (``(None, reason)``)."""
    if model is None:
        try:
            return allocate(system, "tcp", alpha, beta, target="attainable", **options), ""
        except InfeasibleError as err:
            return None, f"no TCP-like law attains alpha = {alpha:g} ({err})"
        except InputError as err:          # behind a chain, with lossy sensor links: not designed (attainable.py)
            return None, f"not computed: {err.detail}"
    return None, ("not computed when buying power (the attainable design buys mu: allocate(..., "
                  "target='attainable'))")


def best_protocol(system: System, alpha: float, beta: Any = None, ack_price: float = 0.0,
                  model: PowerModel | None = None, attainable: bool = True, **options: Any) -> ProtocolChoice:
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
    attainable : bool
        Also design the TCP-like protocol on the attainable cost (``allocate(..., target="attainable")``, one
        monotone branch and bound: about 0.1-3 s at m = 2) and price the link on that basis; False: the paper's
        basis only (``tcp_attainable`` None).
    options
        Passed to [`allocate`][packetloss_cvx.allocation.api.allocate] or
        [`.power.least_power`][packetloss_cvx.allocation.power.least_power] (bounds, constraints, gap, max_boxes,
        time_limit, progress; max_power with a model).

    Returns
    -------
    ProtocolChoice
        Both designs, their totals (``tcp_total`` includes the link), the choice (UDP-like on a tie: no
        link to build), ``certified`` (the chosen total is at most the other's proven lower bound) and
        ``break_even``: the link price above which the UDP-like design wins, all on the paper's basis; beside
        them the attainable basis: ``tcp_attainable`` (the TCP-like design on the attainable cost, None with
        ``attainable_note``), ``tcp_total_attainable``, ``choice_attainable`` and ``break_even_attainable``
        (nan where not computed).

    Raises
    ------
    InfeasibleError
        No TCP-like design meets alpha, hence no UDP-like one (Theorem 2).

    Notes
    -----
    One TCP-like and one UDP-like problem (see their costs), and with ``attainable`` the TCP-like design on the
    attainable cost.

    Examples
    --------
    Two decoupled copies of x' = x + v u (N = 1), alpha = 1.5, beta = (1, 2). UDP-like: sum (1 - mu_i/2) <= 1.5
    is mu1 + mu2 >= 1, cheapest at (1, 0): 1. TCP-like: sum 1/(1 + mu_i) <= 1.5, KKT 1 + mu1 = sqrt(2) (1 + mu2),
    so 1 + mu2 = (1 + 1/sqrt(2)) / 1.5 and beta'mu = 0.8856. An acknowledgement link of 0.2 tips it to UDP-like:

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> c = best_protocol(t, 1.5, [1.0, 2.0], ack_price=0.2, attainable=False)
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
    fields: dict[str, Any] = {}
    if attainable:
        dp, why = _attainable_design(system, alpha, beta, model, options)
        if dp is not None:
            a_value = dp.communication_cost + price
            fields = {"tcp_attainable": dp, "tcp_total_attainable": a_value,
                      "choice_attainable": "udp" if u_value <= a_value else "tcp",
                      "break_even_attainable": u_value - dp.communication_cost}
        else:
            fields = {"attainable_note": why}
    else:
        fields = {"attainable_note": "not computed (attainable=False)"}
    return ProtocolChoice(alpha=alpha, currency="beta'mu" if model is None else "power", ack_price=price,
                          tcp=tcp, udp=udp, tcp_total=t_value, udp_total=u_value, choice=choice,
                          certified=certified, break_even=u_value - design, **fields)


def ack_break_even(system: System, alphas: Sequence[float], beta: Any = None, model: PowerModel | None = None,
                   attainable: bool = True, **options: Any) -> dict[str, np.ndarray]:
    """The study over alpha: for each alpha the cheapest TCP-like and UDP-like totals and the break-even
    acknowledgement price (UDP-like wins above it; inf where no UDP-like design meets alpha, nan where no
    TCP-like one does), on both bases (`ACK_BASES`): ``tcp_total`` and ``break_even`` on the paper's,
    ``tcp_total_attainable`` and ``break_even_attainable`` on the attainable one (nan where not computed:
    ``attainable`` False, power, a chain). O(len(alphas)) triples of designs.

    Examples
    --------
    One step of x' = x + v u from x0 = 1: TCP-like 1/(1 + mu) <= alpha costs 1/alpha - 1, UDP-like 1 - mu/2 <= alpha
    costs 2 (1 - alpha):

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> study = ack_break_even(s, [0.8, 0.9], [1.0], gap=1e-7)
    >>> bool(np.allclose(study["break_even"], [0.4 - 0.25, 0.2 - 1 / 9], atol=1e-6))
    True

    Over one step an acknowledgement has nothing to inform: the TCP-like law attains 1 - mu/2, the UDP-like cost
    (`.attainable.tcp_attainable_cost`), so on the attainable basis the link is worth nothing:

    >>> bool(np.allclose(study["break_even_attainable"], 0.0, atol=1e-6))
    True
    """
    rows = []
    for alpha in alphas:
        try:
            c = best_protocol(system, alpha, beta, 0.0, model, attainable, **options)
            rows.append((float(alpha), c.tcp_total, c.udp_total, c.break_even, c.tcp_total_attainable,
                         c.break_even_attainable))
        except InfeasibleError:
            rows.append((float(alpha), np.nan, np.nan, np.nan, np.nan, np.nan))
    data = np.array(rows, dtype=float).reshape(-1, 6)
    return {"alpha": data[:, 0], "tcp_total": data[:, 1], "udp_total": data[:, 2], "break_even": data[:, 3],
            "tcp_total_attainable": data[:, 4], "break_even_attainable": data[:, 5]}


def attainable_break_even(system: System, alphas: Sequence[float], beta: Any, udp_rows: Sequence[dict],
                          **options: Any) -> dict[str, list]:
    """The break-even acknowledgement prices on the attainable basis at ``alphas``, against UDP-like designs already
    computed ([`pareto_curve`][packetloss_cvx.studies.allocation.pareto_curve] rows, as ``reproduce`` holds them;
    each alpha must be among theirs): ``udp - tcp`` with the TCP-like design ``allocate(system, "tcp", alpha, beta,
    target="attainable", **options)``; None where either design is missing. Returns ``{"alpha", "tcp_design"
    (its beta'mu), "mu" (its mu, a list), "break_even"}``. O(len(alphas)) attainable designs.

    Examples
    --------
    One step of x' = x + v u: the attainable TCP-like cost is 1 - mu/2, J*_udp's, so alpha = 0.8 costs mu = 0.4 on
    both protocols and the link is worth nothing:

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> out = attainable_break_even(s, [0.8], [1.0], [{"alpha": 0.8, "communication_cost": 0.4}], gap=1e-7)
    >>> bool(np.isclose(out["tcp_design"][0], 0.4, atol=1e-6) and np.isclose(out["break_even"][0], 0.0, atol=1e-6))
    True
    """
    by_alpha = {float(row["alpha"]): row for row in udp_rows}
    out: dict[str, list] = {"alpha": [], "tcp_design": [], "mu": [], "break_even": []}
    for alpha in alphas:
        udp = by_alpha.get(float(alpha))
        if udp is None:
            raise InputError("alphas", f"alpha = {alpha:g} is not among the UDP-like designs' alphas")
        try:
            design = allocate(system, "tcp", alpha, beta, target="attainable", **options)
            tcp, mu = design.communication_cost, design.mu.tolist()
        except InfeasibleError:
            tcp = mu = None
        out["alpha"].append(float(alpha))
        out["tcp_design"].append(tcp)
        out["mu"].append(mu)
        missing = tcp is None or udp["communication_cost"] is None
        out["break_even"].append(None if missing else float(udp["communication_cost"]) - tcp)
    return out


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
