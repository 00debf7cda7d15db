"""Subsystem models of dsim: physics cores (no FMI) and their pythonfmu wrappers."""
