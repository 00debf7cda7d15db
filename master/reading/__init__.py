"""Reading a scene: SSP files (.ssp, folder, .ssd), their parameter values, units and
the dsim annotation, FMU archives as untrusted input, into :mod:`dsim.master.scene`."""
