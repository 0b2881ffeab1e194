"""Simulation of the stated model: its random variables (channels, noise) and sampled costs of
plans and of receding-horizon laws in closed loop.

``channels`` holds the delivery and noise samplers; ``sampling`` the realised costs.
"""

from .channels import sample_deliveries, sample_noise
from .sampling import closed_loop_costs, sample_plan_costs

__all__ = ["closed_loop_costs", "sample_deliveries", "sample_noise", "sample_plan_costs"]
