"""Tests of the FMUs dsim builds (physics cores, FMUs alone) and of the C test FMUs."""
