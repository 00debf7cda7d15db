"""The FMI boundary of the running layer: one adapter per FMI version and interface,
each a :class:`~dsim.master.running.subsystem.Subsystem` (save and restore state, set
forces, step, read kinematics, read outputs, write inputs), chosen by
:func:`open_subsystem` from a picklable :class:`SubsystemSpec`.  The couplings, the
backends (in-process, isolated, Ray) and the recording see only the Subsystem.

==================  ==============================  ===========================
FMI version         co-simulation                   Model Exchange
==================  ==============================  ===========================
1.0                 :mod:`.cs1` (no state save)     refused (not run)
2.0                 :mod:`.cs2`                     :mod:`.model_exchange`
3.0                 :mod:`.cs3`                     :mod:`.model_exchange`
==================  ==============================  ===========================
"""
from __future__ import annotations

from dsim.master.reading.fmi_description import describe
from dsim.master.running.fmi.cs1 import CoSimulation1Subsystem
from dsim.master.running.fmi.cs2 import CoSimulation2Subsystem
from dsim.master.running.fmi.cs3 import CoSimulation3Subsystem
from dsim.master.running.fmi.model_exchange import ModelExchangeSubsystem
from dsim.master.running.fmi.spec import SubsystemSpec
from dsim.master.running.subsystem import Subsystem
from dsim.master.running.tables import TableSubsystem

__all__ = ["SubsystemSpec", "open_subsystem", "serialization_problem"]


def open_subsystem(spec: SubsystemSpec) -> Subsystem:
    """Instantiate the FMU of ``spec`` in its FMI version and interface, in
    initialization mode with its parameters set."""
    major = spec.fmi_version.split(".")[0]
    if spec.table is not None:  # a table component: no FMU (dsim.master.running.tables)
        return TableSubsystem(spec)
    if spec.interface == "ModelExchange":
        subsystem = ModelExchangeSubsystem(spec)
    elif major == "1":
        subsystem = CoSimulation1Subsystem(spec)
    elif major == "3":
        subsystem = CoSimulation3Subsystem(spec)
    else:
        subsystem = CoSimulation2Subsystem(spec)
    subsystem.substeps = spec.substeps
    return subsystem


def serialization_problem(spec: SubsystemSpec) -> str | None:
    """Why the state of ``spec``'s subsystem cannot be written to a file and read back
    by another instance (a checkpoint, a worker started again elsewhere), or None."""
    if spec.table is not None:  # a table's state is its time
        return None
    if spec.interface == "CoSimulation" and spec.fmi_version.startswith("1"):
        return (f"component '{spec.name}' is an FMI 1.0 FMU, which cannot save its "
                "state")
    found = describe(spec.path)
    interface = found.modelExchange if spec.interface == "ModelExchange" \
        else found.coSimulation
    if not (interface and interface.canGetAndSetFMUstate and interface.canSerializeFMUstate):
        return (f"component '{spec.name}': its FMU cannot serialize its state "
                "(canSerializeFMUstate is false)")
    return None
