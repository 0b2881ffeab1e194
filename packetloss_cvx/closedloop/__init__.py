"""The closed loop as a Markov jump linear system: the mode engine.

``modes`` (the engine: the second-moment map over M modes, its dense matrix and radius, finite-horizon stage
costs; a Bernoulli channel is its one-mode case), ``stability`` and ``mjls`` (the one-mode and the chain faces of
it; the coupled Riccati equation over modes), ``riccati_map`` (the homogeneous Riccati map's algebra over M modes,
its bounds and certificate cuts), ``riccati`` (the dynamic-programming optimum, one mode), ``moments`` (exact costs of
linear laws from second moments), ``actuator`` (zero, hold or the buffered plan on a loss: each strategy's loop as
the engine's jump linear system, its exact radius and costs), ``actuator_design`` (the optimal TCP-like law per
strategy: the coupled Riccati equation over the strategy's modes), ``actuator_region`` (the channels each
strategy can stabilise, exactly certified, and its critical mu), ``region`` and ``markov_region`` (the least radius
over laws, membership, certificates), ``certificates`` and ``chain_radius`` (verdicts that survive rounding),
``critical`` (critical channels), ``region_lmi`` (the LMI form), ``law_stability`` (the verdict on a Solution's law),
``tails`` (fourth moments: error bars of sampled costs), ``interop`` (the loop as a python-control system).
"""

from .actuator import actuator_costs, actuator_radius
from .actuator_design import actuator_dp, actuator_dp_finite
from .actuator_region import actuator_critical, actuator_membership
from .critical import critical_mu, critical_point, law_membership, stable_at
from .interop import closed_loop_statespace
from .law_stability import loop_stability, with_stability
from .moments import closed_loop, finite_horizon_costs, law_cost_to_go, stationary_second_moment
from .region import membership
from .riccati import dp_finite_horizon, dp_riccati, modified_riccati_step
from .stability import is_mean_square_stable, mean_square_radius, second_moment_map, second_moment_matrix

__all__ = [
    "actuator_costs", "actuator_critical", "actuator_dp", "actuator_dp_finite", "actuator_membership",
    "actuator_radius",
    "closed_loop", "closed_loop_statespace", "critical_mu", "critical_point", "dp_finite_horizon", "dp_riccati",
    "finite_horizon_costs", "is_mean_square_stable", "law_cost_to_go", "law_membership", "loop_stability",
    "mean_square_radius", "membership", "modified_riccati_step", "second_moment_map", "second_moment_matrix",
    "stable_at", "stationary_second_moment", "with_stability",
]
