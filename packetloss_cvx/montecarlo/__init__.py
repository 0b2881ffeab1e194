"""Sampling the stated model: deliveries and noise (``channels``, ``markov_channels``), realised costs of plans
and laws (``sampling``), the vectorised Monte Carlo of the closed loop (``simulate``, ``markov``,
``markov_loop``), the loop when the actuator zeroes, holds or plays the buffered plan on a loss (``actuator``) and
its runs in chunks under a budget (``runs``).
"""

from .channels import sample_deliveries, sample_noise
from .sampling import closed_loop_costs, sample_plan_costs
from .simulate import simulate

__all__ = ["closed_loop_costs", "sample_deliveries", "sample_noise", "sample_plan_costs", "simulate"]
