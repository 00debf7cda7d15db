"""The integrators that carry a Model Exchange FMU between communication points.

A Model Exchange FMU computes derivatives and event indicators; dsim integrates it.
Two families, chosen per component (``solver`` settings: ``method``, ``rtol``,
``atol``, ``max_step``):

- scipy's ``solve_ivp`` methods, ``DOP853`` the default (and ``RK45``, ``RK23``,
  ``Radau``, ``BDF``, ``LSODA``).  An integrator restarts at every communication point
  (the inputs change there, and a rollback may send it back): an explicit Runge-Kutta
  pair restarts at full order, where BDF restarts at order one.  Measured on the
  damped oscillator of the tests (macro step 0.01 s, 2 s, rtol 1e-8): DOP853 ends
  2e-15 from the closed form, CVODE 4.5e-6 (8.2e-8 at rtol 1e-10); on the bouncing
  ball (rtol 1e-10) DOP853/RK45 2e-15, CVODE 8.9e-8 (docs/third_party.md).  An
  indicator exactly on zero where a segment starts (the state an event just left)
  counts as being on the side it moves to; one that stays on zero (a ball at rest) is
  watched again from the next segment.
- ``cvode``: SUNDIALS CVODE as fmpy ships it (variable-order BDF, dense Newton), for
  stiff models, where an explicit method would need steps below its stability limit.
  Its root finder locates a state event to the solver's tolerance.

Both integrate one segment between events at a time: :meth:`Integrator.advance`
stops at the segment's end or at the first state event, with the FMU's time and
states at the point reached.  The adapter handles the event and calls
:meth:`Integrator.reset` (the states may have jumped).
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np

#: scipy.integrate.solve_ivp's methods
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA", "RK23")
METHODS = ("cvode",) + SCIPY_METHODS


@dataclass(frozen=True)
class SolverSettings:
    """How a Model Exchange component is integrated.  ``rtol`` relative tolerance;
    ``atol`` absolute tolerance in the states' units (None: rtol times each state's
    nominal value, as the FMU declares it); ``max_step`` the largest internal step in
    s (None: no limit but the communication step)."""

    method: str = "DOP853"
    rtol: float = 1e-8
    atol: float | None = None
    max_step: float | None = None

    @classmethod
    def of(cls, pairs) -> "SolverSettings":
        """Settings from (name, value) pairs (a spec's ``solver``)."""
        values = dict(pairs)
        return cls(method=values.get("method", cls.method),
                   rtol=float(values.get("rtol", cls.rtol)),
                   atol=None if values.get("atol") is None else float(values["atol"]),
                   max_step=None if values.get("max_step") is None
                   else float(values["max_step"]))


#: the names a solver setting may have, and what each checks
SOLVER_KEYS = ("method", "rtol", "atol", "max_step")


def solver_problem(name: str, value) -> str | None:
    """What is wrong with one solver setting, or None."""
    if name not in SOLVER_KEYS:
        return f"unknown solver setting '{name}' (known: {', '.join(SOLVER_KEYS)})"
    if name == "method":
        if value not in METHODS:
            return f"solver method '{value}' is not one of {', '.join(METHODS)}"
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return f"solver setting {name}={value!r} is not a number"
    if not (number > 0 and np.isfinite(number)):
        return f"solver setting {name}={value!r} must be a positive number"
    if name == "rtol" and number < 1e-14:
        return f"solver setting rtol={value!r} is below what double precision resolves (1e-14)"
    return None


def solver_summary(pairs) -> str:
    """One line for ``dsim info``: 'cvode, rtol 1e-08'."""
    settings = SolverSettings.of(pairs)
    text = f"{settings.method}, rtol {settings.rtol:g}"
    if settings.atol is not None:
        text += f", atol {settings.atol:g}"
    if settings.max_step is not None:
        text += f", max step {settings.max_step:g} s"
    return text


class Integrator:
    """Integrates an ODE view (``nx``, ``nz``, ``set_time``, ``get_x``, ``set_x``,
    ``get_dx``, ``get_z``, ``nominals``) one segment at a time."""

    def __init__(self, view, settings: SolverSettings):
        self.view = view
        self.settings = settings
        #: right-hand-side evaluations so far (the cost measure of benchmarks)
        self.evaluations = 0

    def reset(self, time: float) -> None:
        """Start anew at ``time`` from the view's current states."""

    def advance(self, time: float, stop: float) -> tuple[float, bool]:
        """Integrate from ``time`` towards ``stop``; (time reached, a state event
        stopped it).  The view holds the states at the time reached."""
        raise NotImplementedError


def make_integrator(view, settings: SolverSettings) -> Integrator:
    """The integrator of ``settings.method`` over ``view``."""
    if settings.method == "cvode":
        return CvodeIntegrator(view, settings)
    return ScipyIntegrator(view, settings)


class CvodeIntegrator(Integrator):
    """fmpy's CVODE (BDF) with a stop time at each segment's end, so that it never
    evaluates the model past the communication point."""

    def __init__(self, view, settings: SolverSettings):
        super().__init__(view, settings)
        # imported when CVODE is chosen: it loads SUNDIALS' native libraries
        from fmpy.sundials import CVodeSolver
        from fmpy.sundials.cvode import sundials_cvode

        # fmpy does not bind CVodeSetStopTime: bound here (SUNDIALS 7 signature)
        self._set_stop = sundials_cvode.CVodeSetStopTime
        self._set_stop.argtypes = [ctypes.c_void_p, ctypes.c_double]
        self._set_stop.restype = ctypes.c_int
        nx = view.nx

        def counted_set_time(t):
            self.evaluations += 1
            view.set_time(t)

        self.solver = CVodeSolver(
            nx=nx, nz=view.nz,
            get_x=lambda p, n: _into(p, n, view.get_x()),
            set_x=lambda p, n: view.set_x(np.ctypeslib.as_array(p, (n,)).copy()),
            get_dx=lambda p, n: _into(p, n, view.get_dx()),
            get_z=lambda p, n: _into(p, n, view.get_z()),
            get_nominals=lambda p, n: _into(p, n, self._tolerances()),
            set_time=counted_set_time, input=_NoInput(), startTime=view.time,
            maxStep=settings.max_step or float("inf"),
            relativeTolerance=settings.rtol, maxNumSteps=100000)

    def _tolerances(self) -> np.ndarray:
        """What fmpy's solver multiplies by rtol to make the absolute tolerances."""
        if self.settings.atol is not None:
            return np.full(self.view.nx, self.settings.atol / self.settings.rtol)
        return np.abs(self.view.nominals())

    def reset(self, time: float) -> None:
        self.solver.reset(time)

    def advance(self, time: float, stop: float) -> tuple[float, bool]:
        self._set_stop(self.solver.cvode_mem, stop)
        event, _, reached = self.solver.step(time, stop)
        # a root return is an event; a stop-time return (flag 1) is not
        return reached, bool(event) and reached < stop


class _NoInput:
    """fmpy's solver applies an input object in its root function; dsim's view sets
    its inputs with the time, so there is nothing to apply."""

    def apply(self, time):
        pass


def _into(pointer, n: int, values) -> None:
    np.ctypeslib.as_array(pointer, (n,))[:] = values


class ScipyIntegrator(Integrator):
    """scipy.integrate.solve_ivp over one segment, the event indicators as terminal
    events."""

    def advance(self, time: float, stop: float) -> tuple[float, bool]:
        view = self.view

        def rhs(t, x):
            self.evaluations += 1
            view.set_time(t)
            view.set_x(x)
            return view.get_dx().copy()

        events, sides = [], np.zeros(0)
        if view.nz:
            view.set_time(time)
            start = view.get_z().copy()
            ahead = self._side_ahead(time, stop) if np.any(start == 0) else None
            sides = np.where(start != 0, start, 0.0 if ahead is None else ahead)
            events = [_indicator(view, i, time, side) for i, side in enumerate(sides)]
        x0 = view.get_x().copy()
        atol = (self.settings.atol if self.settings.atol is not None
                else self.settings.rtol * np.abs(view.nominals()))
        # here, not at the top: scipy.integrate takes 0.4 s to import, and every Ray
        # worker imports this module, also those that run only co-simulation FMUs
        from scipy.integrate import solve_ivp

        solution = solve_ivp(rhs, (time, stop), x0, method=self.settings.method,
                             rtol=self.settings.rtol, atol=atol, events=events or None,
                             max_step=self.settings.max_step or np.inf,
                             dense_output=bool(events))
        if solution.status < 0:
            raise RuntimeError(solution.message)
        reached = float(solution.t[-1])
        view.set_time(reached)
        view.set_x(solution.y[:, -1])
        if solution.status == 1:
            reached = self._past_the_root(solution.sol, reached, stop, sides)
        return reached, solution.status == 1

    def _past_the_root(self, dense, reached: float, stop: float, sides) -> float:
        """The root finder may land a hair before the crossing, where the indicator
        has not changed sign yet and the FMU sees no event: step along the dense
        output, by a few ulps and doubling, until an indicator has crossed."""
        view = self.view
        delta = 4 * np.finfo(float).eps * max(1.0, abs(reached))
        for _ in range(64):
            z = view.get_z()
            if np.any((sides != 0) & (np.sign(z) != np.sign(sides))) or reached >= stop:
                break
            reached = min(stop, reached + delta)
            delta *= 2
            view.set_time(reached)
            view.set_x(dense(reached))
        return reached

    def _side_ahead(self, time: float, stop: float) -> np.ndarray:
        """The event indicators a hair after ``time`` along the derivatives (which
        side of zero an indicator that is on zero now moves to)."""
        view = self.view
        x0 = view.get_x().copy()
        dt = 1e-6 * (stop - time)
        view.set_time(time + dt)
        view.set_x(x0 + dt * view.get_dx())
        ahead = view.get_z().copy()
        view.set_time(time)
        view.set_x(x0)
        return ahead


def _indicator(view, index: int, time: float, side: float):
    """A terminal event function of indicator ``index`` over a segment that starts at
    ``time``.  An indicator exactly on zero there (the state an event just left)
    counts as being on ``side`` (the sign it moves to), so that only a crossing back
    is an event, not the start itself."""
    def event(t, x):
        if side == 0:  # resting on zero (a ball at rest): watched from the next segment
            return 1.0
        if t == time:
            return np.copysign(1e-300, side)
        view.set_time(t)
        view.set_x(x)
        return view.get_z()[index]
    event.terminal = True
    return event
