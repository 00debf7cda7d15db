"""SCENES.md four_post (seed sections 4.2.2 and 5.3.4): an FE plate body on a four-post
shaker, glued by dsim, against the same model solved as one.

Monolithic reference (:func:`monolithic`): the plate (the very ElasticBody the FMU
builds from the scene's mesh file and parameters, any fidelity set), the four posts and
the four mounts as one system of equations, integrated with the same Newmark average
acceleration rule (the trapezoidal rule of the posts) and step. Flexible mounts: Newton
on every unknown (plate coordinates and post positions) per step, to round-off; the
Jacobian is the constant assembled matrix plus the mounts' tangent stiffness, a rank-4
term, solved through the constant factorization by the Woodbury identity. Fixed mounts:
the post masses ride on the pads (x_post = z_pad), one linear solve per step.

``python -m examples.four_post`` runs the glued scene (flexible and fixed mounts), the
reference, prints the differences and iterations per step and writes
results/four_post_motion.png (benchmarks/four_post_fidelity.py writes the docs' copy);
``--stop`` shortens the runs.
"""
from __future__ import annotations

import argparse
import time as clock
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from dsim.build_fmus.four_post_scenes import (CORNERS, FOUR_POST, body_parameters, fidelity_values,
                                              post_parameters)
from dsim.fmus.elastic.body_spec import build_body, spec_from_parameters
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain

ROOT = Path(__file__).resolve().parent.parent
#: the scene folder, where its mesh_file values ("resources/meshes/...") are
SCENE = ROOT / "ssp" / "four_post_flexible"
CORNER_COLUMNS = [f"body.{port}.u_z" for port, _, _ in CORNERS.values()]
FORCE_COLUMNS = [f"mount_{corner}.f_z" for corner in CORNERS]


def plate_body(fidelity: str = "fine", **overrides):
    """The plate core exactly as the scene's FMU builds it under fidelity set ``fidelity``
    (``overrides``: more ElasticBody parameters, e.g. another ``mesh_file``)."""
    values = {**body_parameters(), **fidelity_values(fidelity), **overrides}
    return build_body(spec_from_parameters(values), SCENE)


def kirchhoff_frequencies(count: int = 6, element_size: float = 0.1) -> np.ndarray:
    """Lowest ``count`` elastic natural frequencies (Hz) of the free plate as a Kirchhoff
    plate: Argyris triangles (C1 quintic; converged to 5 digits at 0.1 m), the thin-plate
    reference that shows how much the solid elements lock."""
    from skfem import Basis, BilinearForm, ElementTriArgyris, MeshTri, asm
    from skfem.helpers import dd, ddot, eye, trace

    from dsim.fmus.elastic.reduction import generalized_eigen

    p = FOUR_POST
    rigidity = p["youngs_modulus"] * p["thickness"] ** 3 / (12 * (1 - p["poisson_ratio"] ** 2))
    nu = p["poisson_ratio"]
    mesh = MeshTri.init_tensor(np.linspace(0, p["length"], round(p["length"] / element_size) + 1),
                               np.linspace(0, p["width"], round(p["width"] / element_size) + 1))
    basis = Basis(mesh, ElementTriArgyris())

    @BilinearForm
    def bending(u, v, w):
        curvature = dd(u)
        moment = rigidity * ((1 - nu) * curvature + nu * eye(trace(curvature), 2))
        return ddot(moment, dd(v))

    @BilinearForm
    def inertia(u, v, w):
        return p["density"] * p["thickness"] * u * v

    values, _ = generalized_eigen(asm(bending, basis), asm(inertia, basis), count + 3)
    return np.sqrt(np.maximum(values[3:], 0.0)) / (2 * np.pi)  # skip the 3 rigid modes


def free_plate_frequencies(element_size: float, order: int, count: int = 6) -> np.ndarray:
    """Lowest ``count`` elastic frequencies (Hz) of the free plate as a solid: hexahedra of
    ``element_size`` in plane, one through the thickness, ``order`` 1 (8-node) or 2
    (20-node serendipity)."""
    from dsim.build_fmus.four_post_scenes import plate_mesh
    from dsim.fmus.elastic import ElasticBody, Material

    p = FOUR_POST
    body = ElasticBody(plate_mesh(element_size),
                       Material(p["youngs_modulus"], p["poisson_ratio"], p["density"]),
                       order=order)
    return body.natural_frequencies(count + 6)[6:]  # skip the 6 rigid-body modes


def _posts():
    """The four posts as SpringMass cores (for their parameters and base motion)."""
    posts = []
    for corner in CORNERS:
        params = ChainParameters()
        for name, value in post_parameters(corner).items():
            if "[" in name:
                getattr(params, name.split("[")[0])[0] = value
        posts.append(SpringMassChain(params))
    return posts


def _mount_law(q, qd):
    """Mount force -F (N) for extension q (m) and rate qd (m/s), and its tangents."""
    p = FOUR_POST
    force = (p["k0"] + p["k1"] * np.abs(q)) * q + (p["c0"] + p["c1"] * np.abs(qd)) * qd
    return force, p["k0"] + 2 * p["k1"] * np.abs(q), p["c0"] + 2 * p["c1"] * np.abs(qd)


def monolithic(joints: str = "flexible", fidelity: str = "fine",
               step: float = FOUR_POST["step"], stop: float = FOUR_POST["stop"],
               snapshots=(), ordering: str = "COLAMD", base_force=None,
               **overrides) -> dict:
    """The four-post rig in one solver: columns named as the glued run's CSV (``time``,
    ``body.rigidK.u_z``, ``body.probe1.u_z``, ``post_*.x[1]``, ``mount_*.f_z``; m, N),
    ``seconds`` (wall time), ``newton`` (iterations per step) and, for each time in
    ``snapshots``, the plate's full displacement vector (``shapes``). ``ordering``: the
    sparse LU's column ordering (another one shows the solution's round-off floor);
    ``base_force``: a function of the step's end time t1 (s) giving the force (N) on
    each post in place of its base's spring and damper (a road profile fed as a force:
    examples/four_post_road.py), else the posts' own bumps; ``overrides`` change the
    plate's parameters (:func:`plate_body`)."""
    start = clock.perf_counter()
    body, posts, h = plate_body(fidelity, **overrides), _posts(), step
    rows = [body.interface.index((port, "z")) for port, _, _ in CORNERS.values()]
    B = body.interface_matrix[rows]  # pad heights = B q (their reference height is 0)
    n = body.stiffness.shape[0]
    stiffness, mass = body.stiffness, body.mass
    damping = body.damping if body.damping is not None else sp.csr_matrix((n, n))
    m = np.array([post.p.m[0] for post in posts])
    k = np.array([post.p.k_ground[0] for post in posts])
    c = np.array([post.p.c_ground[0] for post in posts])
    a_body = sp.csc_matrix(stiffness + 2 / h * damping + 4 / h ** 2 * mass)
    a_post = k + 2 / h * c + 4 / h ** 2 * m
    if joints == "fixed":  # x_post = B q: the posts' mass, spring and damper on the pads
        lu = splu(sp.csc_matrix(a_body + B.T @ sp.diags(a_post) @ B), permc_spec=ordering)
    else:
        lu = splu(a_body, permc_spec=ordering)
        U = sp.vstack([B.T, -sp.identity(4)]).tocsc()  # mount extension = U^T y
        Z = np.vstack([lu.solve(B.T.toarray()), -np.diag(1 / a_post)])  # A0^-1 U
        coupling = U.T @ Z  # d extension / d law: the mounts' flexibility

    def solve0(r):  # A0^-1 r, A0 = blockdiag(a_body, a_post)
        return np.concatenate([lu.solve(r[:n]), r[n:] / a_post])

    q, v, a = np.zeros(n), np.zeros(n), np.zeros(n)
    x, xv, xa = np.zeros(4), np.zeros(4), np.zeros(4)
    count = int(round(stop / h))
    columns = {name: np.zeros(count + 1) for name in
               CORNER_COLUMNS + ["body.probe1.u_z"] + [f"post_{c}.x[1]" for c in CORNERS]
               + FORCE_COLUMNS}
    columns["time"] = h * np.arange(count + 1)
    shapes, newton = {}, []
    wanted = {int(round(t / h)): t for t in snapshots}
    for i in range(1, count + 1):
        t1 = i * h
        base = np.array([post.base(t1) for post in posts])[:, :, 0]  # (4, 2): y, yd
        rhs_body = mass @ (4 / h ** 2 * q + 4 / h * v + a) + damping @ (2 / h * q + v)
        # (summed in the order the terms always were: the same bits)
        rhs_post = m * (4 / h ** 2 * x + 4 / h * xv + xa) + c * (2 / h * x + xv)
        if base_force is None:
            rhs_post = rhs_post + k * base[:, 0] + c * base[:, 1]
        else:
            rhs_post = rhs_post + base_force(t1)
        if joints == "fixed":
            q1 = lu.solve(rhs_body + B.T @ rhs_post)
            x1 = B @ q1
            force = rhs_post - a_post * x1  # on the body (the post receives -force)
            newton.append(1)
        else:
            # y = A0^-1 (rhs - U law) = w - Z law: Newton on the four mount laws
            extension0, rate0 = B @ q - x, B @ v - xv
            w = solve0(np.concatenate([rhs_body, rhs_post]))
            law = np.zeros(4) if i == 1 else -force
            for iteration in range(1, 30):
                extension = U.T @ w - coupling @ law
                law_now, dk, dc = _mount_law(extension, 2 / h * (extension - extension0) - rate0)
                jacobian = np.identity(4) + (dk + 2 / h * dc)[:, None] * coupling
                delta = np.linalg.solve(jacobian, law - law_now)
                law = law - delta
                if np.max(np.abs(delta)) <= 1e-13 * max(1.0, np.max(np.abs(law))):
                    break
            else:
                raise ArithmeticError(f"four_post monolithic: the mount laws did not "
                                      f"converge at t = {t1:g} s")
            newton.append(iteration)
            y = w - Z @ law
            q1, x1 = y[:n], y[n:]
            force = -law
        v1 = 2 / h * (q1 - q) - v
        a1 = 4 / h ** 2 * (q1 - q) - 4 / h * v - a
        xv1 = 2 / h * (x1 - x) - xv
        xa1 = 4 / h ** 2 * (x1 - x) - 4 / h * xv - xa
        q, v, a, x, xv, xa = q1, v1, a1, x1, xv1, xa1
        body.set_state({"time": t1, "q": q, "v": v, "a": a, "forces": np.zeros(len(body.interface))})
        heights = B @ q
        for j, corner in enumerate(CORNERS):
            columns[CORNER_COLUMNS[j]][i] = heights[j]
            columns[f"post_{corner}.x[1]"][i] = x[j]
            columns[FORCE_COLUMNS[j]][i] = force[j]
        columns["body.probe1.u_z"][i] = body.outputs()["probe1.u_z"]
        if i in wanted:
            shapes[wanted[i]] = body.displacement()
    return {"columns": columns, "seconds": clock.perf_counter() - start,
            "newton": float(np.mean(newton)), "shapes": shapes, "body": body}


def compare(glued: dict, reference: dict) -> dict:
    """Largest differences between a glued run's signals and the reference's columns,
    relative to the reference's peak: pad heights (``heights``), mount forces
    (``forces``), and the plate centre (``centre``)."""
    ref = reference["columns"]
    if len(glued["time"]) != len(ref["time"]) or not np.allclose(glued["time"], ref["time"]):
        raise ValueError("the glued run and the reference have different time grids")

    def error(names):
        peak = max(np.max(np.abs(ref[name])) for name in names)
        return max(np.max(np.abs(np.asarray(glued[name]) - ref[name])) for name in names) / peak
    return {"heights": error(CORNER_COLUMNS), "forces": error(FORCE_COLUMNS),
            "centre": error(["body.probe1.u_z"])}


def run_glued(joints: str, stop: float, **settings):
    """The glued scene build/ssp/four_post_<joints>.ssp through dsim (signals in memory)."""
    from dsim.master.api import simulate

    result = simulate(ROOT / "build" / "ssp" / f"four_post_{joints}.ssp", stop=stop,
                      **settings)
    if not result.ok:
        raise RuntimeError(f"four_post_{joints}: {result.message}")
    return result


def heave_pitch_roll(columns) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heave (m, mean pad height), pitch (rad, nose up positive: front x = 0 higher) and
    roll (rad, left y = 0 higher) from the four pad heights."""
    fl, fr, rl, rr = (np.asarray(columns[name]) for name in CORNER_COLUMNS)
    span_x = FOUR_POST["length"] - FOUR_POST["pad"]
    span_y = FOUR_POST["width"] - FOUR_POST["pad"]
    return ((fl + fr + rl + rr) / 4, ((fl + fr) - (rl + rr)) / 2 / span_x,
            ((fl + rl) - (fr + rr)) / 2 / span_y)


def plot_motion(glued: dict, reference: dict, fixed: dict, snapshot: tuple, png: Path) -> None:
    """Heave, pitch and mount force over time (glued vs monolithic, flexible vs fixed
    mounts) and the plate's elastic deformation at one instant."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dsim.master.recording.results import save_figure

    figure = plt.figure(figsize=(11, 8))
    grid = figure.add_gridspec(3, 2, width_ratios=(1.6, 1))
    times = np.asarray(reference["columns"]["time"])
    axes = [figure.add_subplot(grid[i, 0]) for i in range(3)]
    for source, style, label in ((reference["columns"], "k-", "monolithic"),
                                 (glued, "C1--", "glued (dsim)"), (fixed, "C2:", "glued, fixed mounts")):
        heave, pitch, _ = heave_pitch_roll(source)
        axes[0].plot(times, 1e3 * heave, style, label=label)
        axes[1].plot(times, 1e3 * pitch, style)
        axes[2].plot(times, np.asarray(source["mount_fl.f_z"]) / 1e3, style)
    axes[0].set_ylabel("heave (mm)")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title("four_post: bumps under the front posts at 0.5 s, the rear at 1.0 s")
    axes[1].set_ylabel("pitch (mrad)")
    axes[2].set_ylabel("front-left mount force (kN)")
    axes[2].set_xlabel("time (s)")
    for axis in axes:
        axis.grid(True, alpha=0.3)
        if times[-1] > 2.6:  # quiet before the first bump, decayed by 2.6 s
            axis.set_xlim(0.4, 2.6)
    at, shape, body = snapshot
    axis = figure.add_subplot(grid[:, 1])
    vertices = body.mesh.p
    bottom = np.isclose(vertices[2], 0.0)
    z = shape[body.node_dofs[2][:vertices.shape[1]]][bottom]
    xy = vertices[:2, bottom]
    plane = np.linalg.lstsq(np.column_stack([np.ones(xy.shape[1]), xy.T]), z, rcond=None)[0]
    elastic = 1e3 * (z - np.column_stack([np.ones(xy.shape[1]), xy.T]) @ plane)
    contour = axis.tricontourf(xy[1], xy[0], elastic, levels=21, cmap="coolwarm")
    figure.colorbar(contour, ax=axis, label="elastic deflection (mm)", shrink=0.8)
    axis.set_aspect("equal")
    axis.invert_yaxis()
    axis.set_xlabel("y (m)")
    axis.set_ylabel("x (m), front at 0")
    axis.set_title(f"plate deflection at t = {at:g} s\n(rigid motion removed, monolithic)",
                   fontsize=9)
    save_figure(figure, png)


def main(stop: float = FOUR_POST["stop"],
         png: Path | None = ROOT / "results" / "four_post_motion.png", **settings) -> dict:
    """Glued flexible and fixed scenes against their references; iterations per step."""
    report = {}
    snapshot_time = 0.56  # just after the front bump's crest
    runs = {}
    for joints in ("flexible", "fixed"):
        glued = run_glued(joints, stop, **settings)
        reference = monolithic(joints, stop=stop,
                               snapshots=(snapshot_time,) if stop >= snapshot_time else ())
        stats = glued.statistics
        report[joints] = {**compare(glued.signals, reference),
                          "iterations": stats["iterations"]["mean_per_step"],
                          "glued_seconds": stats["wall_seconds"],
                          "monolithic_seconds": reference["seconds"]}
        runs[joints] = (glued.signals, reference)
    if png is not None and snapshot_time in runs["flexible"][1]["shapes"]:
        reference = runs["flexible"][1]
        plot_motion(runs["flexible"][0], reference, runs["fixed"][0],
                    (snapshot_time, reference["shapes"][snapshot_time], reference["body"]), png)
    return report


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--stop", type=float, default=FOUR_POST["stop"], help="stop time, s")
    args = parser.parse_args()
    for joints, r in main(stop=args.stop).items():
        print(f"four_post_{joints}: glued vs monolithic, max difference / peak: pad heights "
              f"{r['heights']:.2e}, mount forces {r['forces']:.2e}, plate centre "
              f"{r['centre']:.2e}; {r['iterations']:.3f} iterations per step; glued "
              f"{r['glued_seconds']:.1f} s, monolithic {r['monolithic_seconds']:.1f} s")
