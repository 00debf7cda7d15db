"""A one-dimensional chain of masses, springs and dampers (seed section 5.3.1).

Masses ``m[i]`` (kg) at positions ``x[i]`` (m, measured from the unloaded
configuration) are tied to ground and to their right neighbour by springs and
dampers whose laws may be nonlinear as in the seed's eq. 5.36, made odd-symmetric::

    spring force  = (k0 + k1 |d|) d        d  = elongation (m)
    damper force  = (c0 + c1 |dd|) dd      dd = elongation rate (m/s)

The seed writes k0 + k1 d and c0 + c1 dd; taken literally the damper pushes
energy in whenever dd < -c0/c1 (1e-3 m/s in section 5.3.1) and the spring loses
all stiffness at d = -k0/k1, and the monolithic model of section 5.3.1 then
fails at t = 2.88 s.  With absolute values both laws are monotone, so every
force has exactly one extension: see docs/method.md.

Each mass carries an external load ``F0 + Fa sin(omega t + phase)`` (N). Its ground
spring and damper may sit on a moving base instead of fixed ground: the base makes a
half-sine bump ``bump sin(pi (t - bump_start) / bump_duration)`` (m) for ``bump_start <= t
<= bump_start + bump_duration`` and stays at 0 otherwise (a shaker post), and the ground
laws act on the mass's motion relative to it. The chain is integrated with the trapezoidal rule (Newmark average acceleration),
solved for the end-of-step accelerations by Newton's method when a law is
nonlinear.  Ports ``P`` and ``Q`` sit on chosen masses and take interface forces.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from ..interface import InterfaceCore
from ..newton import NewtonCount, at_roundoff, failure_message

#: Largest chain one FMU carries: FMI 2.0 fixes the variable list at build time.
MAX_MASSES = 4


def _vec(value: float) -> np.ndarray:
    return np.full(MAX_MASSES, float(value))


@dataclass
class ChainParameters:
    """Every model quantity of the chain (SI units), one entry per mass.

    ``k_ground[i]``/``c_ground[i]`` tie mass i to ground; ``k[i]``/``c[i]`` tie mass
    i to mass i+1 (the last entry of a chain is unused).  ``*_1`` are the
    nonlinear coefficients of eq. 5.36.  Ports are 1-based mass indices.
    """

    n: int = 1
    m: np.ndarray = field(default_factory=lambda: _vec(1.0))
    k_ground: np.ndarray = field(default_factory=lambda: _vec(0.0))
    k1_ground: np.ndarray = field(default_factory=lambda: _vec(0.0))
    c_ground: np.ndarray = field(default_factory=lambda: _vec(0.0))
    c1_ground: np.ndarray = field(default_factory=lambda: _vec(0.0))
    k: np.ndarray = field(default_factory=lambda: _vec(0.0))
    k1: np.ndarray = field(default_factory=lambda: _vec(0.0))
    c: np.ndarray = field(default_factory=lambda: _vec(0.0))
    c1: np.ndarray = field(default_factory=lambda: _vec(0.0))
    F0: np.ndarray = field(default_factory=lambda: _vec(0.0))
    Fa: np.ndarray = field(default_factory=lambda: _vec(0.0))
    omega: np.ndarray = field(default_factory=lambda: _vec(0.0))
    phase: np.ndarray = field(default_factory=lambda: _vec(0.0))
    x0: np.ndarray = field(default_factory=lambda: _vec(0.0))
    v0: np.ndarray = field(default_factory=lambda: _vec(0.0))
    bump: np.ndarray = field(default_factory=lambda: _vec(0.0))
    bump_start: np.ndarray = field(default_factory=lambda: _vec(0.0))
    bump_duration: np.ndarray = field(default_factory=lambda: _vec(0.0))
    port_P: int = 1
    port_Q: int = 1

    @classmethod
    def array_names(cls) -> list[str]:
        """Names of the per-mass parameter arrays."""
        return [f.name for f in fields(cls) if f.name not in ("n", "port_P", "port_Q")]

    def validate(self) -> None:
        """Raise ValueError naming the first inconsistent parameter."""
        if not 1 <= self.n <= MAX_MASSES:
            raise ValueError(f"n = {self.n}: a chain has 1 to {MAX_MASSES} masses")
        for port, index in (("P", self.port_P), ("Q", self.port_Q)):
            if not 1 <= index <= self.n:
                raise ValueError(f"port {port} on mass {index}, but the chain has {self.n}")
        if np.any(self.m[: self.n] <= 0):
            raise ValueError("every mass m[i] must be positive")
        if np.any(self.bump_duration[: self.n] < 0):
            raise ValueError("every bump_duration[i] must be >= 0 (0: no bump)")


def _law(k0, k1, d):
    """Force (k0 + k1 |d|) d and its derivative k0 + 2 k1 |d| (eq. 5.36, odd)."""
    magnitude = np.abs(d)
    return (k0 + k1 * magnitude) * d, k0 + 2.0 * k1 * magnitude


class SpringMassChain(InterfaceCore):
    """The chain of :class:`ChainParameters`, glueable at ports P and Q (dof x)."""

    interface = (("P", "x"), ("Q", "x"))

    def __init__(self, params: ChainParameters, newton_tolerance: float = 1e-13,
                 max_newton: int = 50):
        params.validate()
        self.p = params
        n = params.n
        self.n = n
        self.newton_tolerance = newton_tolerance
        self.max_newton = max_newton
        self.nonlinear = bool(
            np.any(params.k1_ground[:n]) or np.any(params.c1_ground[:n])
            or np.any(params.k1[: n - 1]) or np.any(params.c1[: n - 1]))
        self.time = 0.0
        self.x = params.x0[:n].copy()
        self.v = params.v0[:n].copy()
        self.a = np.zeros(n)
        self.port_forces = np.zeros(2)
        self.newton_iterations = 0
        #: converged steps, and those that ended at the residual's round-off floor
        self.newton = NewtonCount()
        self._ports = np.array([params.port_P - 1, params.port_Q - 1])
        self.moving_base = bool(np.any(params.bump[:n]) and np.any(params.bump_duration[:n]))
        if not self.nonlinear:  # the internal force is K x + C v: keep K and C
            _, self._stiffness, self._damping = self.internal_force(np.zeros(n), np.zeros(n))
        self._solver = None  # (step size, inverse of M + h/2 C + h^2/4 K) of a linear chain

    # --- forces -------------------------------------------------------------
    def base(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Base position (m) and velocity (m/s) under each mass at time t."""
        p, n = self.p, self.n
        y, yd = np.zeros(n), np.zeros(n)
        if not self.moving_base:
            return y, yd
        duration = p.bump_duration[:n]
        elapsed = t - p.bump_start[:n]
        phase = np.pi * elapsed / np.where(duration > 0, duration, 1.0)
        # the base velocity jumps at both ends: the closed interval, with slack for a
        # communication time that lands on an end in floating point (t = 1.1 may be
        # 1.1000000000000008), makes every master sample the same side
        slack = 1e-9 * max(1.0, abs(t))
        active = (duration > 0) & (elapsed >= -slack) & (elapsed <= duration + slack)
        y[active] = p.bump[:n][active] * np.sin(phase[active])
        yd[active] = (p.bump[:n] * np.pi / np.where(duration > 0, duration, 1.0)
                      * np.cos(phase))[active]
        return y, yd

    def external_force(self, t: float) -> np.ndarray:
        """Loads at time t (N): constant part plus sine, plus interface forces."""
        p, n = self.p, self.n
        f = p.F0[:n] + p.Fa[:n] * np.sin(p.omega[:n] * t + p.phase[:n])
        forces = self.port_forces
        f[self._ports[0]] += forces[0]  # one at a time: P and Q may sit on one mass
        f[self._ports[1]] += forces[1]
        return f

    def internal_force(self, x: np.ndarray, v: np.ndarray, base=None):
        """Spring and damper forces on the masses (N) and their tangents
        d f/d x, d f/d v (N/m, N.s/m) as dense n x n arrays; ``base`` = (y, yd), the
        ground's position and velocity (default at rest)."""
        p, n = self.p, self.n
        y, yd = base if base is not None else (0.0, 0.0)
        fs, ks = _law(p.k_ground[:n], p.k1_ground[:n], x - y)
        fd, cs = _law(p.c_ground[:n], p.c1_ground[:n], v - yd)
        f = fs + fd
        K = np.diag(ks)
        C = np.diag(cs)
        if n > 1:
            d = x[1:] - x[:-1]
            dd = v[1:] - v[:-1]
            fk, kt = _law(p.k[: n - 1], p.k1[: n - 1], d)
            fc, ct = _law(p.c[: n - 1], p.c1[: n - 1], dd)
            link = fk + fc
            f[:-1] -= link
            f[1:] += link
            for T, t in ((K, kt), (C, ct)):
                idx = np.arange(n - 1)
                T[idx, idx] += t
                T[idx + 1, idx + 1] += t
                T[idx, idx + 1] -= t
                T[idx + 1, idx] -= t
        return f, K, C

    # --- InterfaceCore ------------------------------------------------------
    def initialize(self, start_time: float) -> None:
        self.time = float(start_time)
        f, _, _ = self.internal_force(self.x, self.v, self.base(self.time))
        self.a = (self.external_force(self.time) - f) / self.p.m[: self.n]

    def set_interface_forces(self, forces: np.ndarray) -> None:
        self.port_forces = np.array(forces, dtype=float).reshape(2)

    def step(self, time: float, step_size: float) -> None:
        """Trapezoidal rule: x1 = x + h v + h^2/4 (a + a1), v1 = v + h/2 (a + a1),
        with M a1 + f_int(x1, v1) = f_ext(t + h) solved for a1."""
        h = step_size
        m = self.p.m[: self.n]
        t1 = time + h
        f_ext = self.external_force(t1)
        base = self.base(t1)
        x_pred = self.x + h * self.v + 0.25 * h * h * self.a
        v_pred = self.v + 0.5 * h * self.a
        if not self.nonlinear:
            if self.moving_base:  # linear ground laws: the base acts as a force
                f_ext = f_ext + self.p.k_ground[:self.n] * base[0] \
                    + self.p.c_ground[:self.n] * base[1]
            self._linear_step(x_pred, v_pred, f_ext, h)
            self.time = t1
            return
        a1 = self.a.copy()
        for iteration in range(1, self.max_newton + 1):
            x1 = x_pred + 0.25 * h * h * a1
            v1 = v_pred + 0.5 * h * a1
            f_int, K, C = self.internal_force(x1, v1, base)
            residual = m * a1 + f_int - f_ext
            jacobian = np.diag(m) + 0.5 * h * C + 0.25 * h * h * K
            delta = np.linalg.solve(jacobian, residual)
            # relative to the accelerations the force terms alone would give: a1 may cross
            # zero while a stiff spring or damper makes large terms that cancel (their
            # round-off then exceeds 1e-13 |a1|)
            terms = np.abs(K) @ np.abs(x1) + np.abs(C) @ np.abs(v1) + np.abs(f_ext)
            scale = max(np.max(np.abs(a1 - delta)), np.max(terms / m), 1.0)
            if np.max(np.abs(delta)) <= self.newton_tolerance * scale:
                a1, how = a1 - delta, "increment"
                break
            if at_roundoff(residual, np.abs(m * a1) + terms + np.abs(f_int)):
                how = "round-off"  # the residual can get no smaller (dsim.fmus.newton)
                break
            a1 = a1 - delta
        else:
            raise ArithmeticError(failure_message("spring-mass Newton", t1, self.max_newton,
                                                  delta, jacobian))
        self.newton.ended(how)
        self.newton_iterations = iteration
        self.x = x_pred + 0.25 * h * h * a1
        self.v = v_pred + 0.5 * h * a1
        self.a = a1
        self.time = t1

    def _linear_step(self, x_pred, v_pred, f_ext, h) -> None:
        """The trapezoidal step of a linear chain: one solve, with the inverse of the
        constant matrix M + h/2 C + h^2/4 K kept per step size (n is at most four, and
        numpy's per-call cost, not arithmetic, is what a step of so small a chain costs)."""
        if self._solver is None or self._solver[0] != h:
            jacobian = np.diag(self.p.m[: self.n]) + 0.5 * h * self._damping \
                + 0.25 * h * h * self._stiffness
            self._solver = (h, np.linalg.inv(jacobian))
        a1 = self._solver[1] @ (f_ext - self._stiffness @ x_pred - self._damping @ v_pred)
        self.newton_iterations = 1
        self.x = x_pred + 0.25 * h * h * a1
        self.v = v_pred + 0.5 * h * a1
        self.a = a1

    def interface_kinematics(self):
        idx = self._ports
        return self.x[idx], self.v[idx], self.a[idx]

    def get_state(self) -> dict:
        return {"time": self.time, "x": self.x.copy(), "v": self.v.copy(),
                "a": self.a.copy(), "port_forces": self.port_forces.copy()}

    def set_state(self, state: dict) -> None:
        self.time = float(state["time"])
        self.x = np.array(state["x"], dtype=float)
        self.v = np.array(state["v"], dtype=float)
        self.a = np.array(state["a"], dtype=float)
        self.port_forces = np.array(state["port_forces"], dtype=float)

    def history(self, steps: int, step_size: float) -> np.ndarray:
        """Initialise at t = 0 and take ``steps`` steps of ``step_size`` (s), t = n h:
        the positions of every mass (m) after 0, 1, ... steps, one row each."""
        self.initialize(0.0)
        rows = [self.x.copy()]
        for n in range(steps):
            self.step(n * step_size, step_size)
            rows.append(self.x.copy())
        return np.array(rows)

    def outputs(self) -> dict[str, float]:
        out = {}
        for i in range(MAX_MASSES):
            inside = i < self.n
            out[f"x[{i + 1}]"] = float(self.x[i]) if inside else 0.0
            out[f"v[{i + 1}]"] = float(self.v[i]) if inside else 0.0
            out[f"a[{i + 1}]"] = float(self.a[i]) if inside else 0.0
        return out
