"""What happens when an FMI call fails, the same for every adapter: the error names
the component, the call, its status and what the instance logged; while the instance
is being initialised with the scene's parameters it is bad input (InputError, exit 2)
and the instance is freed at once; after Fatal no call may follow."""
from __future__ import annotations

from dsim.master.errors import InputError, SimulationError, StepFailure, Terminated
from dsim.master.running.fmi import python_path
from dsim.master.running.fmi.messages import logged_error


class Checkpoint:
    """Mixed into an adapter that has ``name``, ``path``, ``fmu`` (fmpy's object),
    ``time``, ``fatal``, ``_initializing`` and ``_location``."""

    #: the counter's name of a step (a Discard from it may pass when the step is cut)
    DO_STEP = "fmi2DoStep"
    #: the time (s) this FMU reached when it ended the simulation itself, its step
    #: complete: the next step raises :class:`Terminated` (the run keeps this step)
    ended_at = None
    #: the start time, when the FMU ended the simulation as it left initialization
    #: (a restore never goes back before that end)
    _ended_at_start = None
    #: the calls that end initialization, where an FMU may say it ended the simulation
    #: (fmi2Discard, its status fmi2Terminated)
    END_OF_INITIALIZATION = ("fmi2ExitInitializationMode", "fmiInitializeSlave")
    #: what this instance's instantiation added to ``sys.path`` (an FMU that embeds
    #: Python), held until it is freed (:mod:`~dsim.master.running.fmi.python_path`)
    _python_path: tuple = ()

    def _instantiating(self, instantiate):
        """Call ``instantiate`` (fmpy's), holding what it adds to ``sys.path``, also
        when it fails (the instance is then released)."""
        before = python_path.watch()
        try:
            return instantiate()
        finally:
            self._python_path = python_path.adopt(before)

    def _gone(self) -> None:
        """The instance is freed or may not be called any more: its ``sys.path``
        entries go when no other instance holds them."""
        held, self._python_path = self._python_path, ()
        python_path.release(held)

    def _termination(self) -> float | None:
        """After a discarded step: the time the FMU reached if it says it has ended the
        simulation (FMI 2.0: fmi2GetBooleanStatus(fmi2Terminated)), else None."""
        return None

    def _ended(self, reached: float, end: float | None) -> None:
        """The FMU ended the simulation at ``reached`` (s) in a step to ``end``: a
        complete step (up to round-off) is kept and the next one raises; a partial one
        raises now (the run ends at the step's start, the last point every component
        reached together)."""
        if end is not None and reached >= end - 1e-9 * max(1.0, abs(end)):
            self.ended_at = reached
            return
        self._raise_ended(reached)

    def _raise_ended(self, reached: float | None = None):
        reached = self.ended_at if reached is None else reached
        raise Terminated(f"component '{self.name}' ended the simulation at t = {reached:.9g} s",
                         time=reached, component=self.name)

    def _fail(self, label: str, detail: str, status: int = 3, end: float | None = None):
        """Raise the error of a call that returned ``status`` (Discard or worse):
        InputError while initialising, when the instance is freed at once.  A step
        (to ``end``, s) the FMU discarded because it ended the simulation is no error
        (:meth:`_ended`)."""
        reason = logged_error(self.name)
        if status == 2 and label in self.END_OF_INITIALIZATION and self._ended_in(label):
            return
        if status == 4:
            # FMI allows no further call after Fatal, not even a free (and pythonfmu 0.7
            # has released the instance's Python objects when it returns it: its
            # fmi2FreeInstance would release them twice)
            self.fatal = True
        if self._initializing:
            self._release()
            raise InputError(f"{self._location}: FMU {self.path.name} cannot be "
                             f"initialised with these parameters: "
                             f"{reason or f'{label} failed: {detail}'}")
        if label == self.DO_STEP and status == 2:
            try:  # an FMU that ends the run itself discards the step and says why
                reached = self._termination()
            except Exception:  # no answer: a discarded step like any other
                reached = None
            if reached is not None:
                return self._ended(reached, end)
        # a discarded step may pass when it is smaller: the coupling restores the
        # step's start and cuts it where it can
        error = StepFailure if label == self.DO_STEP and status == 2 else SimulationError
        raise error(f"component '{self.name}': {label} failed: {detail}"
                    + (f" ({reason})" if reason else ""), time=self.time)

    def _ended_in(self, label: str) -> bool:
        """After ``label`` (the call that ends initialization) returned Discard: whether
        the FMU says it ended the simulation there (its status terminated); the run then
        ends normally at the start time, its first row kept (the first step raises
        :class:`Terminated`)."""
        try:
            reached = self._termination()
        except Exception:  # no answer: the Discard is an initialization failure
            return False
        if reached is None:
            return False
        self.ended_at = self._ended_at_start = self.spec.start_time
        return True

    def _release(self) -> None:
        """Free the instance that failed in initialization (fmpy then closes the
        library), or only close the library when instantiation made none; nothing
        after Fatal.  This object may live on (a traceback holds it): the instance is
        marked gone so that no call can reach it."""
        if self.fmu is None:
            return
        if not self.fatal:
            try:
                if self.fmu.component:
                    self.fmu.freeInstance()
                else:
                    self.fmu.freeLibrary()
            except Exception:  # the refusal being reported matters more than a leak
                pass
        self.fmu.component = None
        self._gone()
