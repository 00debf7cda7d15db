"""Tests of master/planning: parameters, start forces, moving least squares."""
