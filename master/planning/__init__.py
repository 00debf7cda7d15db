"""Planning a run: the checked plan (ports, joints, causal connections, what each FMU
reads and writes) and the gluing topology, before any FMU is instantiated; it names what
:mod:`dsim.master.running` runs."""
