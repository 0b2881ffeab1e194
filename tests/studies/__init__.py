"""Tests of design sweeps, burstiness maps, Dask."""
