"""Tests of the Ray backends, cluster, spares and sweeps."""
