"""Checks of scenes and results: dsim validate, dsim compare, dsim regress and the
OpenBLAS kernel study that sets the regression bands' floor (docs/ci.md)."""
