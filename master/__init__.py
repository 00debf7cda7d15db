"""dsim's co-simulation master: SSP in, T-T glued FMUs, results out."""
__version__ = "0.1.0"
