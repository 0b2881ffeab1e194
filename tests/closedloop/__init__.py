"""Tests of the closed loop: second moments, radii, the DP / coupled Riccati, regions and certificates."""
