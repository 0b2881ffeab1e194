"""Channel allocation `M*` (§VI): the cheapest delivery probabilities that keep `J*` <= alpha.

Modules: ``grammar`` (constraint grammar, argument checks, the polytope of constraints),
``boxes`` (LPs over sub-boxes with certified bounds, bisection), ``tcp`` (the exact
TCP-like SOCP), ``udp`` (monotonic branch and bound), ``api`` (allocate, min_cost,
best_cost_within_budget), ``brute_force`` (an independent two-channel reference for tests and the audit), ``chains``
(allocation
behind Markov chains: mean rates chosen, burstiness held, the exact cost under the chain).
"""

from ..results import Allocation, MinCost
from .api import allocate, best_cost_within_budget, min_cost
from .grammar import parse_constraint

__all__ = [
    "Allocation", "MinCost", "allocate", "best_cost_within_budget", "min_cost", "parse_constraint",
]
