"""Start forces: the joint forces at the start time (``start=`` of the master).

* ``auto`` (default): every flexible joint starts with the force its law gives for
  the ports' relative position and velocity at the start time (a joint that starts
  stretched is preloaded, as in one model); fixed joints start at zero.
* ``consistent``: as ``auto``, and the fixed joints' forces solve the acceleration
  compatibility a_b - a_a = 0 (a mechanism moving at t = 0 has loaded joints at
  once), by Newton with the accelerations' sensitivity to the forces measured by
  perturbation, no step taken.
* ``rest``: every joint force starts at zero; a flexible joint that starts
  stretched is then inconsistent, and a warning names it.

The forces are written while the FMUs are in initialization mode, where FMI 2.0
lets a master read calculated outputs after writing inputs, so that each FMU's
start accelerations include them.  An FMU may compute its outputs only when it
leaves initialization mode (FMI 2.0 allows it): after initialization the master
reads the kinematics again, and a start that turns out inconsistent is an error
for ``consistent`` and a warning for ``auto``.
"""
from __future__ import annotations

import numpy as np

from dsim.master.errors import InputError, SimulationError

START_MODES = ("auto", "consistent", "rest")


def _law_forces(layout, joints, kinematics) -> np.ndarray:
    """Forces (N) of the flexible joints' laws at the ports' relative motion; 0 elsewhere."""
    differences, _ = layout.differences(kinematics, magnitudes=False)
    forces = np.zeros(layout.size)
    law, _, _ = joints.law(differences[0], differences[1])
    forces[joints.flexible] = -law[joints.flexible]
    return forces


def _solve_fixed(backend, layout, joints, forces, max_iterations: int = 5):
    """Fixed joints' forces from acceleration compatibility (Newton, forces written)."""
    fixed = ~joints.flexible
    jacobian = None
    for _ in range(max_iterations + 1):
        local = layout.local_forces(forces)
        backend.set_forces(local)
        differences, magnitudes = layout.differences(backend.kinematics())
        residual = differences[2][fixed]
        if np.all(np.abs(residual) <= 1e-10 * np.maximum(magnitudes[2][fixed], 1.0)):
            return forces
        if jacobian is None:
            sensitivities = backend.start_flexibility(
                local, [1e-3 * np.maximum(1.0, np.abs(f)) for f in local])
            jacobian = layout.project(sensitivities).toarray()[np.ix_(fixed, fixed)]
            if np.linalg.matrix_rank(jacobian) < jacobian.shape[0]:
                raise SimulationError("start='consistent': the start accelerations do not "
                                      "determine the fixed joints' forces (a singular "
                                      "configuration at the start time)", time=0.0, step=0)
        forces[fixed] -= np.linalg.solve(jacobian, residual)
    raise SimulationError("start='consistent': the start forces did not converge in "
                          f"{max_iterations} Newton iterations", time=0.0, step=0)


def _not_live(names, before, after, local) -> list[str]:
    """Subsystems given non-zero forces whose accelerations did not move at all: they
    compute their outputs only when they leave initialization mode, so the positions
    they report in it are not theirs yet either."""
    return [name for name, old, new, forces in zip(names, before, after, local)
            if np.any(forces) and old[2] is not None and np.array_equal(old[2], new[2])]


def start_forces(mode: str, backend, layout, joints):
    """In initialization mode: the start forces (N, N.m, one per glued dof), written
    to the glued subsystems of ``backend``, the kinematics they reported for them, and
    a warning (or None); (None, None, None) for ``rest``."""
    if mode == "rest" or not layout.size:
        return None, None, None
    before = backend.kinematics()
    forces = _law_forces(layout, joints, before)
    if mode == "consistent" and not joints.flexible.all():
        return _solve_fixed(backend, layout, joints, forces), backend.kinematics(), None
    local = layout.local_forces(forces)
    backend.set_forces(local)
    after = backend.kinematics()
    stale = _not_live(backend.names, before, after, local)
    if stale:  # the forces came from outputs that are not the FMU's yet: start at rest
        forces = np.zeros(layout.size)
        backend.set_forces(layout.local_forces(forces))
        return None, backend.kinematics(), (
            f"start='auto': component '{stale[0]}' computes its outputs only when it "
            "leaves initialization mode, so the flexible joints' start forces cannot "
            "come from its start positions: every joint starts at zero force")
    return forces, after, None


def _stretched(layout, joints, kinematics, forces, settings, step_size) -> list[str]:
    """Flexible joint dofs whose law force differs from ``forces`` by more than the
    interface tolerance allows (residual (F + law) / k_ref of the force form)."""
    differences, _ = layout.differences(kinematics, magnitudes=False)
    law, _, _ = joints.law(differences[0], differences[1])
    k_ref = joints.reference_stiffness(step_size)
    off = joints.flexible & (np.abs(forces + law) / k_ref > settings.tolerance)
    return [f"joint '{layout.joint_of[r]}' ({layout.labels[r]}): extension "
            f"{differences[0][r]:.4g}, rate {differences[1][r]:.4g}, law force "
            f"{-law[r]:.4g} N" for r in np.flatnonzero(off)]


def check_start(mode: str, backend, layout, joints, forces, reported, settings,
                step_size: float) -> list[str]:
    """After initialization mode: warnings about an inconsistent start (errors for
    ``consistent``)."""
    if not layout.size:
        return []
    kinematics = backend.kinematics()
    if mode == "consistent":
        for name, before, after in zip(backend.names, reported, kinematics):
            a_before, a_after = before[2], after[2]
            if a_before is None or a_after is None or not len(a_after):
                continue
            scale = max(1.0, float(np.max(np.abs(a_after))))
            if np.max(np.abs(a_after - a_before)) > 1e-8 * scale:
                raise InputError(
                    f"start='consistent': component '{name}' reports other port "
                    "accelerations after initialization mode than in it (it computes its "
                    "outputs only when it leaves initialization mode), so the start forces "
                    "cannot be made consistent for it (use start='auto' or 'rest')")
        return []
    written = np.zeros(layout.size) if forces is None else forces
    off = _stretched(layout, joints, kinematics, written, settings, step_size)
    if not off:
        return []
    if mode == "rest":
        return [f"start='rest': {entry} starts with zero force: the start is inconsistent "
                "and the run loses accuracy from its first step (start='auto' preloads it)"
                for entry in off]
    return [f"start='auto': {entry} differs from the start force, computed from the outputs "
            "in initialization mode (an FMU computes them only when it leaves it): the "
            "start is inconsistent" for entry in off]
