"""Tests of the validated model: systems, channels and chains, sensors, files, validation."""
