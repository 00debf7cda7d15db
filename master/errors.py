"""The two ways a run goes wrong, with the exit codes of the results contract."""
from __future__ import annotations


class InputError(Exception):
    """Bad input or usage (exit code 2): every problem is one line naming the
    file, the element and what is wrong."""

    exit_code = 2

    def __init__(self, problems):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = list(problems)
        #: what was found besides the problems (nothing wrong, worth saying)
        self.warnings: list[str] = []
        super().__init__("\n".join(self.problems))

    def __reduce__(self):
        # whole across processes (a Ray worker's error reaches the driver by pickle)
        return type(self), (self.problems,), {"warnings": self.warnings}


class SimulationError(Exception):
    """The simulation itself failed (exit code 1): divergence, a joint that does
    not converge, an FMU that reports an error.  ``time`` and ``step`` say where."""

    exit_code = 1

    def __init__(self, message: str, time: float | None = None, step: int | None = None):
        self.time = time
        self.step = step
        self.message = message
        where = f"step {step} (t = {time:.6g} s): " if step is not None else ""
        super().__init__(where + message)

    def __reduce__(self):
        # whole across processes: message, time and step, not the formatted text
        return type(self), (self.message, self.time, self.step)

    def located(self, step: int, time: float) -> "SimulationError":
        """This error, naming ``step`` and ``time`` unless it names a step already."""
        if self.step is not None:
            return self
        return SimulationError(self.message, time=time, step=step)


class StepFailure(SimulationError):
    """A macro step that did not pass (Newton out of iterations, a non-finite or
    growing residual, an FMU that discarded its step): a smaller step may pass where
    every subsystem accepts one.  ``iterations``: the Newton iterations the failed
    attempt took."""

    def __init__(self, message: str, time=None, step=None, iterations: int = 0):
        super().__init__(message, time, step)
        self.iterations = iterations


class Terminated(SimulationError):
    """An FMU ended the simulation itself (FMI 2.0: a discarded step whose
    fmi2GetBooleanStatus(fmi2Terminated) is true; FMI 3.0: fmi3DoStep's
    terminateSimulation): not a failure.  The run ends normally (exit code 0) at the
    last communication point every component reached together, every row kept;
    ``component`` ended it, having reached ``time`` (s)."""

    exit_code = 0

    def __init__(self, message: str, time=None, step=None, component: str = ""):
        super().__init__(message, time, step)
        self.component = component

    def __reduce__(self):
        return type(self), (self.message, self.time, self.step, self.component)

    def located(self, step: int, time: float) -> "Terminated":
        return self
