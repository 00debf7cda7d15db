"""Tests of the elastic-body core (fmus/elastic): closed forms, rollback, gluing by hand.

Cantilever references (Euler-Bernoulli, plane stress, thickness t, depth H, length L):
tip deflection P L^3 / (3 E I) and first frequency 1.8751^2 / (2 pi) sqrt(E I / (rho A L^4)),
I = t H^3 / 12, A = t H. The beam is slender (L / H = 50) so shear deformation is ~0.1%.
"""
import numpy as np
import pytest

from dsim.fmus.elastic import (STEEL, ElasticBody, PointLoad, craig_bampton_error, in_box,
                               load_mesh, rectangle)
from dsim.fmus.elastic import frame

E, RHO = STEEL.youngs_modulus, STEEL.density
L, H, T = 1.0, 0.02, 0.01
INERTIA = T * H ** 3 / 12
TIP_LOAD = -10.0


def cantilever(element_size, modes=None, kind="quad", port=False):
    """Beam [0, L] x [0, H] clamped at x = 0, tip load (or a tip port), probes."""
    return ElasticBody(
        rectangle(0.0, L, 0.0, H, element_size, kind), STEEL, thickness=T,
        node_sets={"root": in_box((0, 0), (0, H)), "tip": in_box((L, 0), (L, H))},
        clamped=["root"], ports=["tip"] if port else [],
        loads=[] if port else [PointLoad((L, H / 2), "y", constant=TIP_LOAD)],
        probes={"tip": (L, H / 2), "mid": (L / 2, H / 2)}, modes=modes)


def probe_static(body, probe="tip.u_y"):
    """Probe value of the static solution (the state is left untouched)."""
    saved = body.get_state()
    body.set_static_equilibrium()
    value = body.outputs()[probe]
    body.set_state(saved)
    return value


@pytest.fixture(scope="module")
def fine_cantilever():
    return cantilever(H / 8)


def test_cantilever_static_tip_deflection(fine_cantilever):
    exact = TIP_LOAD * L ** 3 / (3 * E * INERTIA)
    error_fine = abs(probe_static(fine_cantilever) / exact - 1)
    error_coarse = abs(probe_static(cantilever(H / 4)) / exact - 1)
    print(f"tip deflection error: {error_coarse:.2e} (H/4), {error_fine:.2e} (H/8)")
    assert error_fine < 0.01
    # bilinear quads lock in bending; the locking error falls as h^2
    assert np.log2(error_coarse / error_fine) > 1.7


def test_cantilever_first_frequency(fine_cantilever):
    exact = 1.875104068711961 ** 2 / (2 * np.pi) * np.sqrt(E * INERTIA / (RHO * T * H * L ** 4))
    first = fine_cantilever.natural_frequencies(2)[0]
    print(f"first frequency {first:.4f} Hz, Euler-Bernoulli {exact:.4f} Hz")
    assert abs(first / exact - 1) < 0.01


def test_triangles_agree_with_quads():
    tri, quad = cantilever(H / 4, kind="tri"), cantilever(H / 4)
    assert tri.stiffness.shape == quad.stiffness.shape
    ratio = tri.natural_frequencies(1)[0] / quad.natural_frequencies(1)[0]
    assert 1.0 < ratio < 1.5  # linear triangles are stiffer still, but the same beam


def test_initial_acceleration_and_constant_force_exactness():
    """Free block, constant force: M a0 = f gives F / m; the rule is exact for constant a."""
    force = 1000.0
    body = ElasticBody(rectangle(0, 0.2, 0, 0.1, 0.025), STEEL, thickness=T,
                       loads=[PointLoad((0.2, 0.05), "x", constant=force)],
                       probes={"c": (0.1, 0.05)})
    total_mass = RHO * T * 0.2 * 0.1
    body.initialize(0.0)
    x_dofs = body.basis.nodal_dofs[0]
    assert np.sum((body.mass @ body.get_state()["a"])[x_dofs]) == pytest.approx(force, rel=1e-12)
    h, steps = 1e-4, 30
    for n in range(steps):
        body.step(n * h, h)
    mean_u = np.sum((body.mass @ body.get_state()["q"])[x_dofs]) / total_mass  # centre of mass
    assert mean_u == pytest.approx(force / total_mass * (steps * h) ** 2 / 2, rel=1e-9)


def test_rollback_is_bit_for_bit():
    body = frame.cross_front()
    body.initialize(0.0)
    rng = np.random.default_rng(1)
    for n in range(3):
        body.set_interface_forces(rng.normal(size=len(body.interface)))
        body.step(n * 1e-4, 1e-4)
    saved = body.get_state()
    body.set_interface_forces(rng.normal(size=len(body.interface)))
    body.step(3e-4, 1e-4)
    first = [k.copy() for k in body.interface_kinematics()] + [body.displacement()]
    first_q = body.get_state()["q"]
    out_first = body.outputs()
    copy = body.get_state()
    copy["q"][:] = 0.0  # a deep copy: mutating it leaves the body alone
    assert np.array_equal(body.get_state()["q"], first_q) and first_q.any()
    restored = body.get_state()
    body.set_state(saved)
    body.step(2e-4, 2e-4)  # a different step size refactors ...
    body.set_state(saved)
    body.set_interface_forces(restored["forces"])
    body.step(3e-4, 1e-4)  # ... and the original one refactors back
    again = list(body.interface_kinematics()) + [body.displacement()]
    for x, y in zip(first, again):
        assert np.array_equal(x, y)
    assert body.outputs() == out_first
    assert body.time == restored["time"]


def glue(bodies, joints, step_size, steps, output):
    """T-T gluing by hand: Newton on joint forces, flexibilities by perturbation.

    ``joints`` are (a, b) = ("component.port", ...) glued node to node on displacement;
    b receives +F, a receives -F, residual u_b - u_a. Returns ``output`` of every step.
    """
    names = list(bodies)
    sizes = {n: len(bodies[n].interface) for n in names}
    blocks, total = [], 0
    for a, b in joints:
        (ca, pa), (cb, pb) = a.split("."), b.split(".")
        sa, sb = bodies[ca].port_slice(pa), bodies[cb].port_slice(pb)
        blocks.append(((ca, sa, -1.0), (cb, sb, +1.0), slice(total, total + sa.stop - sa.start)))
        total += sa.stop - sa.start
    select = {n: np.zeros((total, sizes[n])) for n in names}  # R = sum Q_i u_i, f_i = Q_i^T F
    for ends_a, ends_b, rows in blocks:
        for name, cols, sign in (ends_a, ends_b):
            select[name][rows, cols] += sign * np.eye(rows.stop - rows.start)
    for body in bodies.values():
        body.initialize(0.0)
    forces, jacobian, history = np.zeros(total), None, []

    def trial(time, states, force_vector):
        positions = []
        for name in names:
            bodies[name].set_state(states[name])
            bodies[name].set_interface_forces(select[name].T @ force_vector)
            bodies[name].step(time, step_size)
            positions.append(select[name] @ bodies[name].interface_kinematics()[0])
        return np.sum(positions, axis=0)

    for n in range(steps):
        time = n * step_size
        states = {name: bodies[name].get_state() for name in names}
        if jacobian is None:  # linear bodies, fixed step: one flexibility is enough
            jacobian = np.zeros((total, total))
            for name in names:
                body, scale = bodies[name], 1e4  # large, so positions do not round it off
                columns = []
                for unit in np.vstack([np.zeros(sizes[name]), scale * np.eye(sizes[name])]):
                    body.set_state(states[name])
                    body.set_interface_forces(unit)
                    body.step(time, step_size)
                    columns.append(body.interface_kinematics()[0])
                flexibility = (np.array(columns[1:]) - columns[0]).T / scale
                jacobian += select[name] @ flexibility @ select[name].T
        for _ in range(4):
            residual = trial(time, states, forces)
            if np.max(np.abs(residual)) < 1e-15:
                break
            forces = forces - np.linalg.lstsq(jacobian, residual, rcond=None)[0]
        component, variable = output
        history.append(bodies[component].outputs()[variable])
    return np.array(history)


def test_a_repeated_step_takes_the_linear_response_and_equals_the_full_step():
    """A Newton iteration's repeats of a step (restore, other forces, step) are answered
    by q1 + Z dF once the step size has seen as many repeats as the body has interface
    dofs; the state equals a fresh body's full step to round-off, and a repeat with the
    first forces is the first end state bit for bit."""
    from dsim.fmus.elastic.retry import RepeatedStep

    h, rng = 1e-4, np.random.default_rng(7)
    body, fresh = frame.cross_front(), frame.cross_front()
    for b in (body, fresh):
        b.initialize(0.0)
    m = len(body.interface)
    for n in range(m + 3):  # step n: a first trial, then a repeat with other forces
        start = body.get_state()
        first = rng.normal(size=m)
        body.set_interface_forces(first)
        body.step(n * h, h)
        end_first = body.get_state()
        body.set_state(start)
        second = rng.normal(size=m)
        body.set_interface_forces(second)
        body.step(n * h, h)
        fresh.set_state(start)
        fresh._repeat = RepeatedStep(fresh.integrator, fresh._interface_map)  # forget
        fresh.set_interface_forces(second)
        fresh.step(n * h, h)
        for x, y in zip(body.interface_kinematics(), fresh.interface_kinematics()):
            assert np.max(np.abs(x - y)) <= 1e-12 * max(np.max(np.abs(y)), 1e-300)
        body.set_state(start)
        body.set_interface_forces(first)
        body.step(n * h, h)
        for key in ("q", "v", "a"):
            assert np.array_equal(body.get_state()[key], end_first[key])
    assert body._repeat._response is not None and body._repeat._response[0] == h
    assert fresh._repeat._response is None


def test_the_newmark_step_products_are_scipys_to_the_bit():
    """The Newmark step multiplies by the mass and damping matrices through scipy's own
    kernel, skipping its dispatch: the same bits as ``@`` (a difference in one product
    would change every result after it), and ``@`` itself for what the kernel cannot take."""
    from dsim.fmus.elastic.newmark import _product

    rng = np.random.default_rng(11)
    body = frame.rail("left")
    integrator = body.integrator
    for matrix in (integrator.mass, integrator.stiffness):
        for _ in range(3):
            x = rng.normal(size=matrix.shape[1]) * 10.0 ** rng.integers(-12, 6)
            assert _product(matrix, x).tobytes() == (matrix @ x).tobytes()
    whole = rng.integers(-5, 5, size=integrator.mass.shape[1])  # not float: plain ``@``
    assert np.array_equal(_product(integrator.mass, whole), integrator.mass @ whole)


def test_glued_halves_equal_one_piece_bar():
    size, length, depth = 0.025, 1.0, 0.1
    load = PointLoad((length, depth / 2), "y", amplitude=1e3, omega=2 * np.pi * 50)
    sets = {"root": in_box((0, 0), (0, depth)), "cut": in_box((0.5, 0), (0.5, depth))}
    left = ElasticBody(rectangle(0, 0.5, 0, depth, size), STEEL, thickness=T, node_sets=sets,
                       clamped=["root"], ports=["cut"])
    right = ElasticBody(rectangle(0.5, length, 0, depth, size), STEEL, thickness=T,
                        node_sets={"cut": sets["cut"]}, ports=["cut"], loads=[load],
                        probes={"tip": (length, depth / 2)})
    whole = ElasticBody(rectangle(0, length, 0, depth, size), STEEL, thickness=T,
                        node_sets={"root": sets["root"]}, clamped=["root"], loads=[load],
                        probes={"tip": (length, depth / 2)})
    assert np.allclose(left.port_coordinates("cut"), right.port_coordinates("cut"))
    steps, h = 150, 1e-4
    glued = glue({"left": left, "right": right}, [("left.cut", "right.cut")], h, steps,
                 ("right", "tip.u_y"))
    reference = frame.simulate(whole, "tip.u_y", h, steps * h)[1][1:]
    peak = np.max(np.abs(reference))
    print(f"bar: peak {peak:.3e} m, glued - one piece {np.max(np.abs(glued - reference)):.2e} m")
    assert peak > 1e-4
    assert np.max(np.abs(glued - reference)) < 1e-9 * peak


def test_frame_ports_pair_up():
    for cross_size in (0.025, 0.0125):
        parts = frame.frame_parts(cross_element_size=cross_size)
        for a, b in frame.JOINTS:
            (ca, pa), (cb, pb) = a.split("."), b.split(".")
            xa, xb = parts[ca].port_coordinates(pa), parts[cb].port_coordinates(pb)
            assert np.allclose(xa[[0, -1]], xb[[0, -1]])  # same edge, same direction
            if cross_size == 0.025:
                assert np.allclose(xa, xb) and xa.shape == (5, 2)
            else:
                assert xb.shape == (9, 2)
    assert parts["cross_front"].interface[:3] == (("left[1]", "x"), ("left[1]", "y"),
                                                  ("left[2]", "x"))


def test_frame_monolithic_short_run():
    body = frame.frame_body()
    assert body.mesh.nvertices == 2 * 161 * 5 + 3 * 5 * 41 - 6 * 5  # shared interface nodes
    times, u = frame.simulate(body, "load.u_x", frame.STEP_SIZE, 50 * frame.STEP_SIZE)
    assert times.size == 51 and np.all(np.isfinite(u))
    assert u[0] == 0.0 and 1e-8 < np.max(np.abs(u)) < 1e-3
    assert u[-1] > 0  # F_x = 1000 sin(50 pi t) > 0 over the first 5 ms pushes +x


def test_frame_parts_glued_equal_monolithic():
    steps = 20
    glued = glue(frame.frame_parts(), frame.JOINTS, frame.STEP_SIZE, steps,
                 ("cross_front", "load.u_x"))
    reference = frame.simulate(frame.frame_body(), "load.u_x", frame.STEP_SIZE,
                               steps * frame.STEP_SIZE)[1][1:]
    peak = np.max(np.abs(reference))
    print(f"frame: peak {peak:.3e} m, glued - monolithic {np.max(np.abs(glued - reference)):.2e} m")
    assert peak > 1e-8
    assert np.max(np.abs(glued - reference)) < 1e-8 * peak


def test_craig_bampton_error_decreases_with_modes():
    def build(modes):
        return cantilever(H / 2, modes=modes, port=True)

    def tip_force(time):  # a step load on the tip port nodes, y direction
        return np.tile([0.0, 10.0], 3)

    errors = [craig_bampton_error(build, n, 1e-4, 150, tip_force) for n in (1, 4, 16)]
    response = [e.response for e in errors]
    print("Craig-Bampton response errors (1, 4, 16 modes):", response)
    assert response[0] > response[1] > response[2]
    assert response[2] < 1e-4 and errors[2].frequency < 1e-3
    reduced = build(4)
    assert reduced.stiffness.shape == (6 + 4, 6 + 4)
    assert reduced.interface == build(None).interface


def test_rigid_port_moves_as_a_rigid_set():
    body = ElasticBody(rectangle(0, L, 0, H, H / 4), STEEL, thickness=T,
                       node_sets={"root": in_box((0, 0), (0, H)), "tip": in_box((L, 0), (L, H))},
                       clamped=["root"], rigid_ports={"tip": None})
    assert body.interface == (("tip", "x"), ("tip", "y"), ("tip", "rz"))
    body.set_interface_forces([0.0, 0.0, 1.0])  # a tip moment of 1 N.m
    u = body.static_displacement()
    nodes = body.node_sets["tip"]
    ux, uy = u[body.basis.nodal_dofs[0, nodes]], u[body.basis.nodal_dofs[1, nodes]]
    slope = np.polyfit(body.mesh.p[1, nodes], ux, 1)[0]
    assert np.allclose(uy, uy[0]) and slope < 0  # plane section, rotated counterclockwise
    exact = L / (E * INERTIA)  # tip rotation under a tip moment, M L / (E I)
    assert -slope == pytest.approx(exact, rel=0.05)


def test_bad_mesh_file_raises_value_error(tmp_path):
    bad = tmp_path / "broken.msh"
    bad.write_text("this is not a mesh\n")
    with pytest.raises(ValueError, match="broken.msh"):
        load_mesh(bad)
    with pytest.raises(ValueError, match="missing.vtk: no such file"):
        load_mesh(tmp_path / "missing.vtk")
    good = tmp_path / "plate.vtk"
    rectangle(0, 1, 0, 0.5, 0.25).save(str(good))
    body = ElasticBody(load_mesh(good), STEEL, thickness=T,
                       node_sets={"edge": in_box((0, 0), (0, 0.5))}, clamped=["edge"])
    assert body.stiffness.shape == (2 * 15 - 2 * 3, 2 * 15 - 2 * 3)


def test_empty_node_set_raises_value_error():
    with pytest.raises(ValueError, match="node set 'ghost' is empty"):
        ElasticBody(rectangle(0, 1, 0, 0.1, 0.05), STEEL, thickness=T,
                    node_sets={"ghost": in_box((2, 2), (3, 3))}, ports=["ghost"])
    with pytest.raises(ValueError, match="node set 'nowhere' is not defined"):
        ElasticBody(rectangle(0, 1, 0, 0.1, 0.05), STEEL, thickness=T, clamped=["nowhere"])


def test_von_mises_in_uniaxial_tension():
    """A bar pulled through a rigid end port: sigma = F / (H t) away from the ends."""
    force, depth = 1e4, 0.1
    body = ElasticBody(rectangle(0, 1, 0, depth, 0.025), STEEL, thickness=T,
                       node_sets={"root": in_box((0, 0), (0, depth)),
                                  "end": in_box((1, 0), (1, depth))},
                       clamped=["root"], rigid_ports={"end": None},
                       probes={"middle": (0.5, depth / 2)}, stress_outputs=True)
    body.set_interface_forces([force, 0.0, 0.0])
    body.set_static_equilibrium()
    values = body.outputs()
    assert values["middle.von_mises"] == pytest.approx(force / (depth * T), rel=0.01)
    assert values["middle.u_x"] == pytest.approx(force * 0.5 / (E * depth * T), rel=0.02)


def test_lumped_mass_keeps_total_mass_and_softens():
    consistent = cantilever(H / 2)
    lumped = ElasticBody(rectangle(0.0, L, 0.0, H, H / 2), STEEL, thickness=T, mass="lumped",
                         node_sets={"root": in_box((0, 0), (0, H))}, clamped=["root"])
    f_consistent = consistent.natural_frequencies(1)[0]
    f_lumped = lumped.natural_frequencies(1)[0]
    assert f_lumped < f_consistent < 1.1 * f_lumped  # lumping lowers the frequencies a bit
    assert lumped.mass.nnz == lumped.mass.shape[0]  # diagonal


def test_solid_hex_cantilever_with_rigid_end():
    from dsim.fmus.elastic import box
    side, length, force = 0.05, 1.0, -1000.0
    body = ElasticBody(box(0, length, 0, side, 0, side, side / 4), STEEL,
                       node_sets={"root": in_box((0, 0, 0), (0, side, side)),
                                  "tip": in_box((length, 0, 0), (length, side, side))},
                       clamped=["root"], rigid_ports={"tip": None})
    assert [dof for _, dof in body.interface] == ["x", "y", "z", "rx", "ry", "rz"]
    body.set_interface_forces([0, 0, force, 0, 0, 0])
    body.set_static_equilibrium()
    deflection, rotation = body.interface_kinematics()[0][[2, 4]]
    inertia = side ** 4 / 12
    # coarse trilinear hexes are a little stiff in bending: within 5% of Euler-Bernoulli
    assert deflection - side / 2 == pytest.approx(force * length ** 3 / (3 * E * inertia), rel=0.05)
    assert rotation == pytest.approx(-force * length ** 2 / (2 * E * inertia), rel=0.05)


def test_rayleigh_damping_decay_rate():
    """alpha M damping gives zeta = alpha / (2 omega): released tip decays as exp(-zeta w t)."""
    zeta = 0.02
    omega = 2 * np.pi * cantilever(H / 2).natural_frequencies(1)[0]
    body = ElasticBody(rectangle(0.0, L, 0.0, H, H / 2), STEEL, thickness=T,
                       rayleigh=(2 * zeta * omega, 0.0),
                       node_sets={"root": in_box((0, 0), (0, H)), "tip": in_box((L, 0), (L, H))},
                       clamped=["root"], ports=["tip"], probes={"tip": (L, H / 2)})
    body.set_interface_forces(np.tile([0.0, 1.0], 3))
    body.set_static_equilibrium()
    body.set_interface_forces(np.zeros(6))  # release
    times, tip = frame.simulate(body, "tip.u_y", 2e-4, 4.5 * 2 * np.pi / omega)
    window = int(0.25 * 2 * np.pi / omega / 2e-4)  # a quarter period: skip higher-mode ripple
    peaks = [i for i in range(window, tip.size - window)
             if tip[i] == tip[i - window:i + window + 1].max()]
    cycles = len(peaks)  # the peaks after t = 0
    measured = tip[peaks[-1]] / tip[0]
    expected = np.exp(-zeta * omega * (times[peaks[-1]]))
    print(f"decay over {cycles} cycles: {measured:.4f}, exp(-zeta w t) = {expected:.4f}")
    assert cycles == 4
    assert measured == pytest.approx(expected, rel=0.03)


def test_matrices_are_assembled_once_per_mesh_material_and_thickness(monkeypatch):
    """A body made again on the same mesh takes its K and M from the process's cache
    (the same numbers to the bit, never the cached object itself); another mesh,
    material or thickness is assembled anew."""
    from dsim.fmus.elastic import assembly
    from dsim.fmus.elastic.geometry import rectangle

    monkeypatch.setattr(assembly, "_ASSEMBLED", {})
    made = []
    real = assembly.asm
    monkeypatch.setattr(assembly, "asm", lambda *a, **k: made.append(1) or real(*a, **k))
    basis = assembly.vector_basis(rectangle(0.0, 1.0, 0.0, 0.2, 0.05))
    first = assembly.stiffness_matrix(basis, STEEL, 0.01)
    first.data[:] = 0.0  # a caller's change stays the caller's
    again = assembly.stiffness_matrix(assembly.vector_basis(
        rectangle(0.0, 1.0, 0.0, 0.2, 0.05)), STEEL, 0.01)
    assert len(made) == 1
    fresh = assembly._stiffness_matrix(basis, STEEL, 0.01)
    def same(a, b) -> bool:
        return a.shape == b.shape and (a != b).nnz == 0

    assert same(again, fresh) and abs(fresh).max() > 1e6
    for other in (assembly.stiffness_matrix(basis, STEEL, 0.02),
                  assembly.stiffness_matrix(basis, assembly.Material(70e9, 0.33, 2700.0),
                                            0.01),
                  assembly.stiffness_matrix(assembly.vector_basis(
                      rectangle(0.0, 1.0, 0.0, 0.2, 0.1)), STEEL, 0.01)):
        assert not same(other, fresh)
    assert len(made) == 1 + 1 + 3  # the fresh one, then three others
    assert not same(assembly.mass_matrix(basis, STEEL, 0.01),
                    assembly.mass_matrix(basis, STEEL, 0.01, lumped=True))
