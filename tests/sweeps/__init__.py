"""Tests of master/sweeps: sweeps, designs of experiments, sensitivity."""
