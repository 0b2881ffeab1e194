"""Simulation of the stated model and the closed loop: its random variables (channels, noise),
sampled costs of plans and of receding-horizon laws, mean-square stability, exact closed-loop
costs from second moments, and the dynamic-programming optimum (modified Riccati equation).

``channels`` holds the delivery and noise samplers; ``sampling`` the realised costs;
``stability`` the second-moment operator and its spectral radius; ``moments`` exact costs of
linear laws; ``riccati`` the DP optimum; ``region`` the stabilisable set (``region_lmi`` its LMI form);
``critical`` critical channels; ``law_stability`` the verdict on a Solution's law over its channel; ``montecarlo`` the
vectorised Monte Carlo (``simulate``); ``interop`` python-control.
"""

from .channels import sample_deliveries, sample_noise
from .critical import critical_mu, critical_point, law_membership, stable_at
from .interop import closed_loop_statespace
from .law_stability import loop_stability, with_stability
from .moments import closed_loop, finite_horizon_costs, law_cost_to_go, stationary_second_moment
from .montecarlo import simulate
from .region import membership
from .riccati import dp_finite_horizon, dp_riccati, modified_riccati_step
from .sampling import closed_loop_costs, sample_plan_costs
from .stability import is_mean_square_stable, mean_square_radius, second_moment_map, second_moment_matrix

__all__ = [
    "closed_loop", "closed_loop_costs", "closed_loop_statespace", "critical_mu", "critical_point", "dp_finite_horizon",
    "dp_riccati", "law_membership", "loop_stability", "membership",
    "finite_horizon_costs", "is_mean_square_stable", "law_cost_to_go", "mean_square_radius", "modified_riccati_step",
    "sample_deliveries", "sample_noise", "sample_plan_costs", "second_moment_map", "second_moment_matrix",
    "simulate", "stable_at", "stationary_second_moment", "with_stability",
]
