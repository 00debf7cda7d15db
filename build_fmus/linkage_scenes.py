"""Write the linkage scene folders of ssp/ (SCENES.md: crank_slider_rigid,
crank_slider_flexible, four_bar_singular_*, crank_slider_penalized*).

``python -m dsim.build_fmus.linkage_scenes`` (re)writes them; ``python -m dsim.build_fmus``
then packs them with their FMUs (Linkage2D, FlexibleLink2D) into build/ssp.

Measures and tolerances (docs/linkages.md explains the choice):

* crank slider (rigid and flexible coupler): ``penalized`` with xi = 1,
  omega = 1000 rad/s, the same row as the Linkage parts' own Baumgarte
  stabilisation, so the glued rigid mechanism solves the monolithic discrete
  equations.  Tolerance 1e-7 (m/s^2, the penalized blend's units): its
  round-off floor is near 1e-9 (omega^2 = 1e6 times a position's last bits).
  Predictor ``quadratic`` and ``refreshAfter`` 3: the mechanism's interface
  flexibility turns with the links, so a Lambda a few steps old converges
  slowly (measured over 0..1 s: 3.4 iterations per step against 5.3 with the
  default linear predictor and refreshAfter 10).
* four bar: ``displacement`` (Table 5.1's setting), H = 0.01, tolerance chosen
  on the command line (``dsim run ... --tol 1e-9``); the scene's default 1e-8.
  Fixed joints on the displacement measure are position-level (index-3) rows, whose
  forces the trapezoidal rule leaves an undamped period-2 mode that grows towards the
  singular point: four_bar_singular_fixed's parts integrate with generalized-alpha
  (``spectral_radius`` FOUR_BAR["spectral_radius"]), the master re-measures the
  interface flexibility at every step (``refresh="step"``) and also asks the joint
  forces to have converged (``convergence="forces"``); the parameter set
  ``trapezoidal`` gives the parts today's rule back (docs/linkages.md measures each).
  four_bar_singular_penalized: the fixed joints on ``penalized`` (xi = 1, omega =
  1000, the Linkage parts' row), trapezoidal parts.
* crank_slider_penalized: the flexible crank slider glued on ``acceleration``
  only (crank_slider_penalized_acceleration) versus ``penalized``; both record
  the port kinematics of joint A on both sides, for the drift figures.
"""
from __future__ import annotations

from pathlib import Path

from dsim.build_fmus.scenes import SceneWriter, write_parameter_sets
from dsim.fmus.linkage.description import mechanism_to_text
from dsim.fmus.linkage.scenes import crank_slider_part, four_bar_part

ROOT = Path(__file__).resolve().parent.parent
FOUR_BAR_PARTS = ("crank", "coupler", "rocker")

#: Crank slider (seed section 4.2.1): 0..5 s, H = 1e-3, penalized xi = 1, omega = 1000.
CRANK_SLIDER = {"stop": 5.0, "step": 1e-3, "tolerance": 1e-7, "xi": 1.0, "omega": 1000.0,
                "max_iterations": 20, "predictor": "quadratic", "refresh_after": 3}
#: Four bar (seed section 5.3.2): H = 0.01, bushings k = 1e6 N/m, c = 2 0.707 1e3 N.s/m;
#: two crank turns from 45 degrees: four collinear (singular) passes.
#: Its fixed joints on the displacement measure: the parts' generalized-alpha spectral
#: radius (chosen by the measurements of docs/four_bar_table.md) and the master's refresh
#: policy and convergence test.
FOUR_BAR = {"stop": 2.0, "step": 0.01, "tolerance": 1e-8, "k": 1e6, "c": 2 * 0.707 * 1e3,
            "max_iterations": 50, "tolerances": (1e-7, 1e-8, 1e-9, 1e-10),
            "spectral_radius": 0.3, "fixed_refresh": "step", "fixed_convergence": "forces"}
#: The seed's coupler as a flexible link (6 m steel 0.1 x 0.1, 6 elements) from x = 3 to 9 m.
COUPLER = {"length": 6.0, "density": 7850.0, "area": 0.01, "young": 210e9,
           "second_moment": 0.1 ** 4 / 12.0, "elements": 6, "x0": 6.0}
#: Port kinematics recorded by the penalized scenes (interface error figures).
PORT_RECORDS = ["A.u_x", "A.u_y", "A.v_x", "A.v_y", "A.a_x", "A.a_y"]


def _part(scene: str, part: str, **parameters) -> dict:
    """The Linkage2D parameters of a shipped part: its mechanism's description (what a
    user writes for a linkage of their own; docs/linkages.md), and ``parameters``."""

    build = crank_slider_part if scene == "crank_slider" else four_bar_part
    return {"mechanism": mechanism_to_text(build(part)), **parameters}


def crank_slider(name: str, coupler: str = "rigid", measure: str = "penalized",
                 record_ports: bool = False) -> SceneWriter:
    """crank, coupler, slider glued at A = (crank.A, coupler.A) and B = (coupler.B,
    slider.P), dofs x y; ``coupler`` is ``rigid`` (Linkage2D) or ``flexible``
    (FlexibleLink2D); ``measure`` is ``penalized`` or ``acceleration``."""
    p = CRANK_SLIDER
    scene = SceneWriter(name, f"Seed section 4.2.1: crank slider with a {coupler} coupler, "
                        f"three FMUs glued at revolute joints A and B ({measure} measure)")
    extra = PORT_RECORDS if record_ports else []
    scene.component("crank", "Linkage2D", _part("crank_slider", "crank"),
                    outputs=["theta", "omega", "torque"] + extra)
    coupler_outputs = ["omega"] + extra
    if coupler == "rigid":
        scene.component("coupler", "Linkage2D", _part("crank_slider", "coupler"),
                        outputs=["theta"] + coupler_outputs)
    else:
        scene.component("coupler", "FlexibleLink2D", dict(COUPLER),
                        outputs=["reference.theta"] + coupler_outputs
                        + ["deflection", "pim_iterations"])
    scene.component("slider", "Linkage2D", _part("crank_slider", "slider"),
                    outputs=["P.u_x", "P.v_x"])
    penalty = {"xi": p["xi"], "omega": p["omega"]} if measure == "penalized" else None
    for joint, a, b in (("A", "crank.A", "coupler.A"), ("B", "coupler.B", "slider.P")):
        scene.joint(joint, a, b, dofs="x y", measure=measure, penalty=penalty)
    return scene


def four_bar_singular(joints: str) -> SceneWriter:
    """Parallelogram four bar as crank, coupler, rocker glued at A = (crank.A,
    coupler.A) and B = (coupler.B, rocker.B), dofs x y; ``joints`` ``fixed`` or
    ``flexible`` (Kelvin-Voigt k, c of FOUR_BAR) on the displacement measure, or
    ``penalized``: fixed joints on the penalized measure (the parts' own Baumgarte
    row, as the crank slider: the glued mechanism solves the monolithic equations)."""
    p = FOUR_BAR
    name = f"four_bar_singular_{joints}"
    kind = "fixed joints on the penalized measure" if joints == "penalized" else (
        f"{joints} glue joints")
    scene = SceneWriter(name, f"Seed section 5.3.2: parallelogram four bar through its "
                        f"singular (collinear) configuration, {kind}")
    outputs = {"crank": ["theta", "omega", "torque"], "coupler": ["theta", "omega"],
               "rocker": ["theta", "omega"]}
    # fixed joints on the displacement measure are index-3 rows: damped integrator
    rule = {"spectral_radius": p["spectral_radius"]} if joints == "fixed" else {}
    for part in FOUR_BAR_PARTS:
        scene.component(part, "Linkage2D", _part("four_bar", part, **rule),
                        outputs=outputs[part])
    law = dict(kind="flexible", spring={"k0": p["k"], "k1": 0.0},
               damper={"c0": p["c"], "c1": 0.0}) if joints == "flexible" else {}
    if joints == "penalized":
        law = dict(measure="penalized", penalty={"xi": CRANK_SLIDER["xi"],
                                                  "omega": CRANK_SLIDER["omega"]})
    scene.joint("A", "crank.A", "coupler.A", dofs="x y", **law)
    scene.joint("B", "coupler.B", "rocker.B", dofs="x y", **law)
    return scene


def scenes() -> list[tuple[SceneWriter, dict]]:
    """Every linkage scene with its master settings."""
    cs, fb = CRANK_SLIDER, FOUR_BAR
    crank_master = dict(step=cs["step"], tolerance=cs["tolerance"],
                        maxIterations=cs["max_iterations"], predictor=cs["predictor"],
                        refreshAfter=cs["refresh_after"])
    four_master = dict(step=fb["step"], tolerance=fb["tolerance"],
                       maxIterations=fb["max_iterations"], predictor="linear", refreshAfter=10)
    return [
        (crank_slider("crank_slider_rigid"), dict(stop=cs["stop"], **crank_master)),
        (crank_slider("crank_slider_flexible", "flexible"), dict(stop=cs["stop"],
                                                                 **crank_master)),
        (crank_slider("crank_slider_penalized", "flexible", "penalized", True),
         dict(stop=cs["stop"], **crank_master)),
        (crank_slider("crank_slider_penalized_acceleration", "flexible", "acceleration",
                      True), dict(stop=cs["stop"], **crank_master)),
        # the crank turns at full speed from t = 0: fixed joints carry centripetal
        # forces at once, which the master's consistent start finds (master/running/start.py)
        (four_bar_singular("fixed"), dict(stop=fb["stop"], start="consistent",
                                          **four_master, refresh=fb["fixed_refresh"],
                                          convergence=fb["fixed_convergence"])),
        (four_bar_singular("flexible"), dict(stop=fb["stop"], **four_master)),
        (four_bar_singular("penalized"), dict(stop=fb["stop"], start="consistent",
                                              **four_master)),
    ]


def write_all(root: Path = ROOT) -> list[Path]:
    """(Re)write every linkage scene folder under ``root``/ssp; returns the folders."""
    folders = []
    for scene, settings in scenes():
        settings = dict(settings)
        stop = settings.pop("stop")
        folder = root / "ssp" / scene.name
        scene.write(folder, 0.0, stop, **settings)
        if scene.name == "four_bar_singular_fixed":
            # today's rule back: dsim run ... --parameter-set trapezoidal
            write_parameter_sets(folder, {"trapezoidal": {
                f"{part}.spectral_radius": 1.0 for part in FOUR_BAR_PARTS}})
        folders.append(folder)
    return folders


if __name__ == "__main__":
    for written in write_all():
        print(f"wrote {written.relative_to(ROOT)}")
