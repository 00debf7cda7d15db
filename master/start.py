"""A consistent start: joint forces at the start time that make the glued
accelerations compatible (``glue:Master start="consistent"``).

A mechanism that starts moving with loaded joints (a crank turning at full speed
from t = 0 needs centripetal joint forces at once) is inconsistent with zero
start forces: the first steps then carry a jump.  Before the FMUs leave
initialization mode, where FMI 2.0 lets a master read calculated outputs after
writing inputs, the master sets the flexible joints' forces from their law and
solves the fixed joints' acceleration compatibility a_b - a_a = 0 for theirs, by
Newton with the accelerations' sensitivity to the forces measured by
perturbation (no step is taken).  It needs FMUs whose port accelerations follow
their force inputs in initialization mode, as dsim's own do.
"""
from __future__ import annotations

import numpy as np

from master.errors import InputError, SimulationError


def consistent_start_forces(backend, layout, joints, max_iterations: int = 5):
    """Start forces F0 (N, N.m, one per glued dof), already written to the FMUs, and
    the port kinematics the FMUs reported for them (to check after initialization)."""
    forces = np.zeros(layout.size)
    differences, _ = layout.differences(backend.kinematics())
    flexible = joints.flexible
    law_force, _, _ = joints.law(differences[0], differences[1])
    forces[flexible] = -law_force[flexible]
    fixed = ~flexible
    jacobian = None
    for _ in range(max_iterations + 1):
        local = layout.local_forces(forces)
        backend.set_forces(local)
        kinematics = backend.kinematics()
        differences, magnitudes = layout.differences(kinematics)
        residual = differences[2][fixed]
        if np.all(np.abs(residual) <= 1e-10 * np.maximum(magnitudes[2][fixed], 1.0)):
            return forces, kinematics
        if jacobian is None:
            sensitivities = backend.start_flexibility(
                local, [1e-3 * np.maximum(1.0, np.abs(f)) for f in local])
            full = sum((c.T @ s @ c for c, s in zip(layout.incidence, sensitivities)
                        if c.shape[0]), np.zeros((layout.size, layout.size)))
            jacobian = np.asarray(full)[np.ix_(fixed, fixed)]
            if np.linalg.matrix_rank(jacobian) < jacobian.shape[0]:
                raise SimulationError("start='consistent': the start accelerations do not "
                                      "determine the fixed joints' forces (a singular "
                                      "configuration at the start time)", time=0.0, step=0)
        forces[fixed] -= np.linalg.solve(jacobian, residual)
    raise SimulationError("start='consistent': the start forces did not converge in "
                          f"{max_iterations} Newton iterations", time=0.0, step=0)


def check_start(backend, expected) -> None:
    """After initialization mode: every FMU must report the accelerations it reported
    in it.  One that computes its outputs only when it leaves initialization mode
    (FMI 2.0 allows it) has been given start forces computed from stale outputs."""
    for subsystem, before, after in zip(backend.subsystems, expected, backend.kinematics()):
        a_before, a_after = before[2], after[2]
        if a_before is None or a_after is None or not len(a_after):
            continue
        scale = max(1.0, float(np.max(np.abs(a_after))))
        if np.max(np.abs(a_after - a_before)) > 1e-8 * scale:
            raise InputError(
                f"start='consistent': component '{subsystem.name}' reports other port "
                "accelerations after initialization mode than in it (it computes its "
                "outputs only when it leaves initialization mode), so the start forces "
                "cannot be made consistent for it (use start='rest')")
