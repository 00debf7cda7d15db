"""Every subsystem in this process, called one after the other."""
from __future__ import annotations


class InProcessBackend:
    """The batched calls of the gluing algorithm, run sequentially here.

    A backend owns the subsystems and answers for all of them at once, so a
    parallel backend can run them side by side without the algorithm knowing.
    """

    name = "in-process"

    def __init__(self, subsystems):
        self.subsystems = list(subsystems)

    def begin_step(self) -> None:
        """Every subsystem saves its state as the macro step's start."""
        for subsystem in self.subsystems:
            subsystem.begin_step()

    def trial_step(self, forces, time, step_size):
        """Each subsystem steps from the saved state with its forces."""
        return [s.trial_step(f, time, step_size) for s, f in zip(self.subsystems, forces)]

    def flexibility(self, forces, time, step_size, deltas, bases):
        """Each subsystem's interface flexibility [Gu, Gv, Ga] by perturbation."""
        return [s.flexibility(f, time, step_size, d, b)
                for s, f, d, b in zip(self.subsystems, forces, deltas, bases)]

    def set_forces(self, forces) -> None:
        """Write each subsystem's glued-dof forces (no step)."""
        for subsystem, f in zip(self.subsystems, forces):
            subsystem.set_forces(f)

    def start_flexibility(self, forces, deltas):
        """Each subsystem's d a / d f at the start time (no step)."""
        return [s.start_flexibility(f, d) for s, f, d in zip(self.subsystems, forces, deltas)]

    def finish_initialization(self) -> None:
        """Every subsystem leaves initialization mode."""
        for subsystem in self.subsystems:
            subsystem.finish_initialization()

    def kinematics(self):
        """Current interface kinematics of every subsystem."""
        return [s.kinematics() for s in self.subsystems]

    def outputs(self):
        """Recorded outputs of every subsystem (list per subsystem)."""
        return [s.outputs() for s in self.subsystems]

    def close(self) -> None:
        """Terminate every subsystem, even if one of them fails."""
        errors = []
        for subsystem in self.subsystems:
            try:
                subsystem.terminate()
            except Exception as error:  # gather, then report the first
                errors.append(error)
        if errors:
            raise errors[0]
