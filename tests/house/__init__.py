"""Tests of the house: imports, documentation examples, defined names."""
