"""Designs of experiments: sweeps over settings and model parameters, their designs,
KPIs, sensitivity indices, tables, plots, folders, points and Ray runs (docs/doe.md)."""
