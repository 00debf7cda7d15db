"""Tests of master/checks: validate, regress, compare, regression bands."""
