"""What it takes to create one FMU subsystem, wherever it runs: a picklable spec."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dsim.master.reading.ports import PortDof


@dataclass(frozen=True)
class SubsystemSpec:
    """Everything needed to create one FMU subsystem, wherever it runs (picklable).

    ``reads`` names the variables read after every step (recorded outputs and
    causal connection sources), ``writes`` the inputs that causal connections set.
    """

    name: str
    path: Path
    port_dofs: tuple[PortDof, ...]
    parameters: dict
    reads: tuple[str, ...]
    writes: tuple[str, ...]
    start_time: float
    stop_time: float
    location: str = ""
    #: the kinematic kinds (u, v, a) the joints need from the first step on (before
    #: it, for the start forces and their check, every kind the FMU has is read)
    kinds: tuple[bool, bool, bool] = (True, True, True)
    #: the variables connections set at initialization (``writes`` and the fixed
    #: parameters connections feed)
    start_writes: tuple[str, ...] = ()
    #: String variables read after every step (recorded, or feeding a connection), and
    #: the String inputs connections set
    text_reads: tuple[str, ...] = ()
    text_writes: tuple[str, ...] = ()
    #: the Ray resource whose node runs the instance (``glue:Placement``; '' anywhere)
    placement: str = ""
    #: the String parameters whose value is the absolute path of a scene file (a
    #: remote backend ships the file and rewrites the value)
    files: tuple[str, ...] = ()

    #: the interface it runs (CoSimulation or ModelExchange) and its FMI version
    interface: str = "CoSimulation"
    fmi_version: str = "2.0"
    #: the Model Exchange integrator's settings as (name, value) pairs (method,
    #: rtol, atol, max_step: :mod:`dsim.master.running.fmi.integrator`)
    solver: tuple = ()
    #: communication steps of this FMU per macro step, its inputs held over them (a
    #: component exchanged once per step: ``--substeps``)
    substeps: int = 1
    #: over those substeps its Real inputs are extrapolated from the last two macro
    #: steps' values and given with their slope (fmi2SetRealInputDerivatives: an FMI
    #: 2.0 co-simulation FMU that declares canInterpolateInputs); else they are held
    input_derivatives: bool = False
    #: every log category of the FMU on and each message printed (``--fmu-log``);
    #: else only its warning and error categories, the last messages kept
    fmu_log: bool = False
    #: a table component (an SSP table, ``--input``): its data
    #: (:class:`~dsim.master.running.tables.TableData`), run in process with no FMU
    #: (``path`` is then the table's file, or the name of a table made in memory)
    table: object = None
    #: the inputs this FMU takes from a table, where it can follow them within a step
    #: (Model Exchange; co-simulation with canInterpolateInputs): their ramps over
    #: each step (:class:`~dsim.master.running.fmi.table_inputs.TableInputs`), or None
    table_inputs: object = None
