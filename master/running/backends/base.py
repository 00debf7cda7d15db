"""The backend protocol: what the couplings and the execution need from the
subsystems, in batches over all of them (or over a subset)."""
from __future__ import annotations

from abc import ABC, abstractmethod

#: the settings a backend takes (not the master's: dsim.master.settings names them all),
#: with the backends that take each
BACKEND_OPTIONS = {"address": "only the ray backend takes it (--backend ray)",
                   "call_timeout": "only the ray and isolated backends take it (--backend "
                                   "ray, --isolate): an FMU in dsim's own process cannot be "
                                   "stopped"}
#: settings every backend takes that its run's process uses: ``restarts`` (lost
#: workers of the ray and isolated backends started again; with checkpoints, the
#: process of ``dsim run`` started again by its supervisor from the last one)
RUN_OPTIONS = ("restarts",)


class Backend(ABC):
    """The subsystems of one run, wherever they live.

    Lists of per-subsystem values (forces, kinematics, outputs, inputs) follow the
    backend's order of subsystems; :meth:`subset` gives a backend over some of them
    in the order asked, sharing the same subsystems.
    """

    #: registry name
    name = ""
    #: whether the subsystems live in other processes (their counters need a call)
    remote = False

    @classmethod
    def problems(cls, **options) -> list[str]:
        """What is wrong with running on this backend with ``options`` (the run
        options that are not master settings, such as ``address``), one line each."""
        return [f"setting {key}: {BACKEND_OPTIONS[key]}"
                for key, value in options.items() if value is not None
                and key in BACKEND_OPTIONS]

    @classmethod
    def ahead(cls, settings: dict) -> None:
        """Start what a run on this backend waits for (a cluster, its workers) while
        the scene is read and planned; ``settings``: the run's keywords.  Nothing here."""

    @classmethod
    def release_ahead(cls) -> None:
        """Let go what :meth:`ahead` started and no run took.  Nothing here."""

    @classmethod
    def log_line(cls) -> str | None:
        """After a failure: one line saying where this backend's own processes wrote
        what they said meanwhile, or None (the default: it has no such processes)."""
        return None

    @classmethod
    @abstractmethod
    def from_specs(cls, specs, progress=None, **options) -> "Backend":
        """Create every subsystem of a run from its
        :class:`~dsim.master.running.fmi.SubsystemSpec` (instantiated, in initialization mode);
        ``progress(done, total)``, if given, is told how many are instantiated as they
        are, and ``progress(0, 0, what)`` what else takes long before (starting Ray)."""

    @abstractmethod
    def subset(self, indices) -> "Backend":
        """A backend over the subsystems at ``indices``."""

    @abstractmethod
    def __len__(self) -> int:
        """Number of subsystems."""

    @property
    @abstractmethod
    def names(self) -> list[str]:
        """Subsystem names, in order."""

    @abstractmethod
    def begin_step(self) -> None:
        """Every subsystem saves its state as the macro step's start."""

    @abstractmethod
    def trial_step(self, forces, time: float, step_size: float) -> list:
        """Each subsystem steps from its saved state with its forces; their kinematics."""

    @abstractmethod
    def advance(self, forces, time: float, step_size: float) -> list:
        """Each subsystem steps with its forces, no rollback; their kinematics."""

    @abstractmethod
    def step(self, time: float, step_size: float, inputs=()) -> list:
        """Each subsystem writes its causal inputs (``inputs``: (subsystem index,
        values) pairs), takes one plain step (no forces, no state saved) and reads
        its outputs; the outputs of every subsystem."""

    def causal_kernel(self, transfer, outputs):
        """What takes a macro step of every subsystem here when none is in a joint, made
        once (``transfer``: the causal connections into them; ``outputs``: each one's
        outputs now): a callable ``(outputs, time, step_size) -> outputs``, flat arrays
        as :meth:`step` would give them joined; None (the default): :meth:`step` it is."""
        return None

    @abstractmethod
    def hold_inputs(self, ramps) -> None:
        """Each subsystem's connected inputs ramping as ``ramps`` say ((start, end,
        step_size) per subsystem), written again after every restore
        (:meth:`Subsystem.hold_inputs`)."""
        raise NotImplementedError

    def trial_exchange(self, time: float, step_size: float, ramps) -> list:
        """Every subsystem stepped from its saved state with its connected inputs
        ramping as ``ramps`` say ((start, end) or (None, None) per subsystem); the
        outputs of each (:meth:`Subsystem.trial_exchange`)."""
        raise NotImplementedError

    def flexibility(self, forces, time: float, step_size: float, deltas, bases) -> list:
        """Each subsystem's interface flexibility [Gu, Gv, Ga] by perturbation."""

    #: whether :meth:`snapshot`, :meth:`rollback` and :meth:`discard` work here (the
    #: error-controlled macro step needs them)
    snapshots = False

    def snapshot(self) -> list:
        """Every subsystem's current state, kept beside the macro step's saved one
        (:meth:`Subsystem.snapshot`): a handle for :meth:`rollback` and :meth:`discard`."""
        raise NotImplementedError(f"the {self.name} backend keeps no snapshot")

    def rollback(self, snapshot) -> None:
        """Every subsystem back to its state in ``snapshot`` (which is kept)."""
        raise NotImplementedError(f"the {self.name} backend keeps no snapshot")

    def discard(self, snapshot) -> None:
        """Release ``snapshot``."""
        raise NotImplementedError(f"the {self.name} backend keeps no snapshot")

    @abstractmethod
    def set_forces(self, forces) -> None:
        """Write each subsystem's glued-dof forces (no step)."""

    @abstractmethod
    def start_flexibility(self, forces, deltas) -> list:
        """Each subsystem's d a / d f at the start time (no step)."""

    @abstractmethod
    def kinematics(self) -> list:
        """Current interface kinematics of every subsystem."""

    @abstractmethod
    def read_outputs(self) -> list:
        """Every subsystem's read values (a float array each)."""

    @abstractmethod
    def write_inputs(self, inputs, start: bool = False) -> None:
        """Write causal inputs: ``inputs`` is a list of (subsystem index, values); with
        ``start``, what connections feed at initialization (fixed parameters too)."""

    def set_values(self, entries) -> None:
        """Set variables between steps (a scenario's event: an input no connection
        feeds, a tunable parameter): ``entries`` is a list of (subsystem index, names,
        values) (:meth:`Subsystem.set_values`)."""
        raise NotImplementedError(f"the {self.name} backend cannot set values")

    @abstractmethod
    def read_texts(self) -> list:
        """Every subsystem's String values read after a step (a list of str each)."""

    @abstractmethod
    def write_texts(self, inputs) -> None:
        """Write String inputs: (subsystem index, list of str) pairs."""

    @abstractmethod
    def finish_initialization(self) -> None:
        """Every subsystem leaves initialization mode."""

    @abstractmethod
    def save_states(self) -> list[dict]:
        """Each subsystem's state now as plain data, its own FMI calls not counted
        (:meth:`~dsim.master.running.subsystem.Subsystem.current_checkpoint`): a
        checkpoint on disk."""
        raise NotImplementedError(f"the {self.name} backend writes no checkpoint")

    def load_states(self, states, counters) -> None:
        """Bring each subsystem (out of initialization mode) to its entry of
        :meth:`save_states`, and its counts to its entry of ``counters`` (what
        :meth:`counters` gave then)."""
        raise NotImplementedError(f"the {self.name} backend resumes no checkpoint")

    def counters(self) -> list[dict]:
        """Per subsystem: FMI function -> [calls, seconds]."""

    # --- what a backend of workers elsewhere says; nothing here by default -----------
    #: whether a worker can keep the run waiting (:meth:`waiting` has something to say)
    has_workers = False

    def notes(self) -> list[str]:
        """What a user should know before the run (a placement that cannot hold)."""
        return []

    def waiting(self) -> str | None:
        """Which worker the run has waited on long, for a progress line (None: none)."""
        return None

    def watch_head(self, on_lost) -> None:
        """Call ``on_lost(what)`` when what the workers need is lost (a Ray head);
        nothing to watch where every subsystem runs in this process."""

    def losses(self) -> list[dict]:
        """Every worker lost in the run and how the run went on."""
        return []

    def places(self) -> list:
        """Per subsystem: where it ran ({"node": ..., "pid": ...}), or None (here)."""
        return [None] * len(self)

    @abstractmethod
    def close(self) -> list[Exception]:
        """Terminate every subsystem, even if some fail; the errors they raised."""

    def abandon(self) -> None:
        """The process ends at once (a second signal) while a subsystem may be stuck:
        end what this backend started elsewhere, without waiting for any subsystem
        (processes on this machine are killed by the caller)."""


def terminate_all(subsystems) -> list[Exception]:
    """Terminate every subsystem, even if some fail; the errors they raised."""
    errors = []
    for subsystem in subsystems:
        try:
            subsystem.terminate()
        except Exception as error:  # gather: every subsystem must be released
            errors.append(error)
    return errors
