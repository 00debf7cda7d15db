"""Tests of master/reading: SSP files, FMU archives, units."""
