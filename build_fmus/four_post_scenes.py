"""The four_post scenes (SCENES.md; seed sections 4.2.2 and 5.3.4): a vehicle body, an FE
plate, on a four-post shaker.

- ``body``: the generic ElasticBody FMU, a steel plate x in [0, 2] (front at x = 0),
  y in [0, 1], z in [0, 0.02] m, 20-node serendipity hexahedra (``order = 2``: linear
  hexahedra lock in bending, docs/four_post.md), one element through the thickness,
  Rayleigh damping beta = 2e-4 s (about 2% at the first elastic modes, 27 and 33 Hz).
  Each corner has a 0.1 x 0.1 m mount pad through the thickness, a rigid port
  (``rigid1`` front left, ``rigid2`` front right, ``rigid3`` rear left, ``rigid4`` rear
  right) whose reference point is the pad's centre on the bottom face (z = 0).
- ``post_fl``, ``post_fr``, ``post_rl``, ``post_rr``: SpringMass FMUs, one mass
  m = 30 kg on a spring-damper k = 2e5 N/m, c = 1e3 N.s/m to a base that makes a 0.05 m
  half-sine bump of 0.1 s (front posts at t = 0.5 s, rear at t = 1.0 s). The mass moves
  vertically: its variables ``P.*_x`` are mapped onto port ``top``, dof z (glue:Port).
- mounts ``mount_fl`` ... ``mount_rr`` from ``post_*.top`` (a) to ``body.rigidK`` (b),
  dof z: four_post_flexible has the seed's nonlinear bushings k0 = 3e5 N/m,
  k1 = 1e4 N/m^2, c0 = 1.5e3 N.s/m, c1 = 1e2 N.s^2/m^2 (section 5.3.4); four_post_fixed
  has fixed joints. No gravity: motion about the static equilibrium of the unloaded rig.
- H = 1e-3 s, 0 to 5.2 s; recorded: the corners' and the plate centre's heights.

Fidelity parameter sets (resources/fidelity/*.ssv, ``dsim run ... --parameter-set NAME``):
``fine`` (the default model: full FE, 0.1 m mesh), ``coarse`` (full FE, 0.2 m mesh),
``cb4``, ``cb12``, ``cb30`` (Craig-Bampton on the fine mesh with 4, 12, 30
fixed-interface modes) and ``rigid`` (the plate as one rigid body).
"""
from __future__ import annotations

from pathlib import Path

from dsim.build_fmus.scenes import ROOT, SceneWriter, write_parameter_sets

FOUR_POST = {
    "length": 2.0, "width": 1.0, "thickness": 0.02, "pad": 0.1,
    "youngs_modulus": 210e9, "poisson_ratio": 0.3, "density": 7850.0,
    "rayleigh_beta": 2e-4, "order": 2,
    "post_mass": 30.0, "post_k": 2e5, "post_c": 1e3,
    "bump": 0.05, "bump_duration": 0.1, "bump_front": 0.5, "bump_rear": 1.0,
    "k0": 3e5, "k1": 1e4, "c0": 1.5e3, "c1": 1e2,
    "step": 1e-3, "stop": 5.2, "tolerance": 1e-10, "predictor": "quadratic",
}
#: Element sizes (m) of the plate meshes: fine is the scene's default model.
MESH_SIZES = {"coarse": 0.2, "fine": 0.1}
#: corner -> (rigid port, x, y of the corner)
CORNERS = {"fl": ("rigid1", 0.0, 0.0), "fr": ("rigid2", 0.0, 1.0),
           "rl": ("rigid3", 2.0, 0.0), "rr": ("rigid4", 2.0, 1.0)}
#: name -> the body's parameters the set changes (on top of the scene's bindings)
FIDELITY = {
    "fine": {"fidelity": "full", "modes": 0},
    "coarse": {"fidelity": "full", "modes": 0, "mesh": "coarse"},
    "cb4": {"fidelity": "craig_bampton", "modes": 4},
    "cb12": {"fidelity": "craig_bampton", "modes": 12},
    "cb30": {"fidelity": "craig_bampton", "modes": 30},
    "rigid": {"fidelity": "rigid", "modes": 0},
}
OUTPUTS = [f"{port}.u_z" for port, _, _ in CORNERS.values()] + ["probe1.u_z"]


def mesh_file(mesh: str) -> str:
    """The plate's mesh file (its path in the scene) for ``coarse``/``fine``."""
    return f"resources/meshes/four_post_plate_{MESH_SIZES[mesh]:g}.vtk"


def plate_mesh(size: float):
    """A linear hexahedral mesh of the plate, ``size`` (m) in plane, one element through
    the thickness (the 20-node elements of ``order = 2`` add the mid-side nodes)."""
    import numpy as np
    from skfem import MeshHex

    p = FOUR_POST
    return MeshHex.init_tensor(np.linspace(0.0, p["length"], round(p["length"] / size) + 1),
                               np.linspace(0.0, p["width"], round(p["width"] / size) + 1),
                               np.array([0.0, p["thickness"]]))


def pad(corner: str) -> tuple[str, str]:
    """Node set and reference point of a corner's mount pad (strings of the FMU)."""
    p = FOUR_POST
    _, x, y = CORNERS[corner]
    x0, x1 = (x, x + p["pad"]) if x == 0.0 else (x - p["pad"], x)
    y0, y1 = (y, y + p["pad"]) if y == 0.0 else (y - p["pad"], y)
    return (f"box {x0!r} {y0!r} 0.0 {x1!r} {y1!r} {p['thickness']!r}",
            f"{0.5 * (x0 + x1)!r} {0.5 * (y0 + y1)!r} 0.0")


def body_parameters(mesh: str = "fine") -> dict:
    """ElasticBody parameters of the plate: mesh, material, damping, pads, probe."""
    p = FOUR_POST
    values = {"mesh_file": mesh_file(mesh), "order": p["order"],
              "youngs_modulus": p["youngs_modulus"], "poisson_ratio": p["poisson_ratio"],
              "density": p["density"], "rayleigh_beta": p["rayleigh_beta"],
              "mass": "consistent", "fidelity": "full", "modes": 0,
              "probe1.point": f"{p['length'] / 2!r} {p['width'] / 2!r} "
                              f"{p['thickness'] / 2!r}"}
    for corner, (port, _, _) in CORNERS.items():
        values[f"{port}.set"], values[f"{port}.point"] = pad(corner)
    return values


def post_parameters(corner: str) -> dict:
    """SpringMass parameters of one post: the mass on its spring-damper and the bump."""
    p = FOUR_POST
    start = p["bump_front"] if corner.startswith("f") else p["bump_rear"]
    return {"n": 1, "m[1]": p["post_mass"], "k_ground[1]": p["post_k"],
            "c_ground[1]": p["post_c"], "bump[1]": p["bump"], "bump_start[1]": start,
            "bump_duration[1]": p["bump_duration"], "P.mass": 1, "Q.mass": 1}


def four_post(joints: str) -> SceneWriter:
    """four_post_flexible (``joints = "flexible"``) or four_post_fixed."""
    p = FOUR_POST
    scene = SceneWriter(f"four_post_{joints}",
                        "Seed sections 4.2.2 and 5.3.4: an FE plate body on a four-post "
                        f"shaker, {joints} body mounts")
    for mesh, size in MESH_SIZES.items():  # the fine one, and the coarse one of a set
        scene.file(mesh_file(mesh), lambda target, size=size: plate_mesh(size).save(
            str(target)))
    scene.component("body", "ElasticBody", body_parameters(), outputs=OUTPUTS)
    for corner, (port, _, _) in CORNERS.items():
        post = f"post_{corner}"
        scene.component(post, "SpringMass", post_parameters(corner), outputs=["x[1]"],
                         inline=True)
        scene.port_map(post, "top", "z", force="P.f_x", position="P.u_x",
                       velocity="P.v_x", acceleration="P.a_x")
        if joints == "flexible":
            scene.joint(f"mount_{corner}", f"{post}.top", f"body.{port}", dofs="z",
                        kind="flexible", spring={"k0": p["k0"], "k1": p["k1"]},
                        damper={"c0": p["c0"], "c1": p["c1"]})
        else:
            scene.joint(f"mount_{corner}", f"{post}.top", f"body.{port}", dofs="z")
    return scene


def fidelity_values(name: str) -> dict:
    """The body's parameters of fidelity set ``name`` (without the component prefix)."""
    values = {k: v for k, v in FIDELITY[name].items() if k != "mesh"}
    values["mesh_file"] = mesh_file(FIDELITY[name].get("mesh", "fine"))
    return values


def write_four_post_scenes(root: Path = ROOT) -> None:
    """four_post_flexible and four_post_fixed, their fidelity sets and plate meshes."""
    p = FOUR_POST
    for joints in ("flexible", "fixed"):
        scene = four_post(joints)
        folder = root / "ssp" / scene.name
        scene.write(folder, 0.0, p["stop"], step=p["step"], tolerance=p["tolerance"],
                    maxIterations=20, predictor=p["predictor"], refreshAfter=10)
        write_parameter_sets(folder, {
            name: {f"body.{key}": value for key, value in fidelity_values(name).items()}
            for name in FIDELITY})


if __name__ == "__main__":
    write_four_post_scenes()
