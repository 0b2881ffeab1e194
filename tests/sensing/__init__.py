"""Tests of lossy sensors: the intermittent Kalman filter, bounds, loops, Monte Carlo."""
