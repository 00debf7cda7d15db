"""Tests of master/running: couplings, steps, FMU kinds, the engine."""
