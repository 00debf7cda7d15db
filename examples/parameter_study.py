"""A design-of-experiments study of the glued spring-mass chain (spring_mass_linear):
which of three model parameters sets how far the loaded mass m3 moves?

The chain is m1 on a spring k_g to ground (component ``left``), glued by the joint
j1 (k0 = 100 N/m, c0 = 14.14 N s/m) to m2, which a spring k_r ties to m3 (component
``right``); a constant force F = 10 N pulls m3 from t = 0.  The study varies, by a
64-point Latin hypercube (seed 1):

* ``left.k_ground[1]`` = k_g, log-uniform on 50 .. 200 N/m;
* ``right.k[1]`` = k_r, log-uniform on 100 .. 400 N/m;
* ``right.m[2]`` = m3, uniform on 5 .. 20 kg;

and measures two KPIs of m3's position x3 over 0 .. 10 s: ``mean(right.x[2])`` and
``max(right.x[2])``.

What the physics says.  The springs are in series between the ground and the force,
so m3's static deflection is x_s = F (1/k_g + 1/k0 + 1/k_r), whatever the masses.  A
force applied at once makes the chain oscillate about x_s (the joint's damper damps
it slowly): the time average of x3 is close to x_s and the peak close to 2 x_s.  Both
KPIs therefore depend on the compliances 1/k_g and 1/k_r and hardly on m3, and k_g
matters more than k_r because its compliance spans twice as much over its range
(1/50 - 1/200 = 0.015 m/N against 1/100 - 1/400 = 0.0075 m/N): the ranking must be
k_g > k_r > m3.  The monolithic twin of the scene (the same chain in one model,
:class:`dsim.fmus.spring_mass.core.SpringMassChain`, same integrator and step) is run at
every sampled point too: the glued KPIs are compared with the twin's, and the
twin's own ranking is the reference ranking.

``python -m examples.parameter_study`` runs the study (on Ray with ``--ray``) and
writes the figure docs/parameter_study.png; the test (tests/sweeps/test_doe.py) runs it on
a local Ray cluster after killing a first attempt.
"""
from __future__ import annotations

import argparse
import math
import shutil
from pathlib import Path

import numpy as np

from dsim.build_fmus.scenes import SPRING_MASS

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "build" / "ssp" / "spring_mass_linear.ssp"
FACTORS = ("left.k_ground[1]=50:200:log", "right.k[1]=100:400:log", "right.m[2]=5:20")
KPIS = ("mean(right.x[2])", "max(right.x[2])")
SAMPLES, SEED, STOP = 64, 1, 10.0
#: the ranking the physics gives (see the module docstring)
PHYSICS_RANKING = ["left.k_ground[1]", "right.k[1]", "right.m[2]"]


def sweep_of(samples: int = SAMPLES, stop: float = STOP, backend: str | None = None):
    """The study as a :class:`~dsim.master.sweeps.sweep.Sweep`."""
    from dsim.master.sweeps.design import parse_vary
    from dsim.master.sweeps.sweep import Sweep

    fixed = {"stop": stop, **({"backend": backend} if backend else {})}
    return Sweep(vary=[parse_vary(f, sampled=True) for f in FACTORS], design="lhs",
                 samples=samples, seed=SEED, kpis=list(KPIS), fixed=fixed)


def command(out, samples: int = SAMPLES, stop: float = STOP, backend: str | None = None):
    """The same study as a ``dsim sweep`` command line (its arguments after ``dsim``)."""
    words = ["sweep", str(SCENE), "--design", "lhs", "--samples", str(samples), "--seed",
             str(SEED), "--stop", repr(stop), "--out", str(out)]
    for factor in FACTORS:
        words += ["--vary", factor]
    for kpi in KPIS:
        words += ["--kpi", kpi]
    return words + (["--backend", backend] if backend else [])


def static_deflection(configuration: dict) -> float:
    """x_s = F (1/k_g + 1/k0 + 1/k_r) (m) at a point's parameters."""
    p = SPRING_MASS
    return p["F"] * (1 / configuration["left.k_ground[1]"] + 1 / p["k0"]
                     + 1 / configuration["right.k[1]"])


def twin_kpis(configuration: dict, stop: float = STOP) -> dict:
    """The KPIs of the monolithic twin (eq. 5.37's chain in one model, the scene's
    integrator and step) at a point's parameters."""
    from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain
    from dsim.master.sweeps.kpi import parse

    p = SPRING_MASS
    params = ChainParameters(n=3)
    params.m[:3] = (p["m"], p["m"], configuration["right.m[2]"])
    params.k_ground[0] = configuration["left.k_ground[1]"]
    params.k[:2] = (p["k0"], configuration["right.k[1]"])
    params.c[0] = p["c0"]
    params.F0[2] = p["F"]
    count = round(stop / p["step"])
    x3 = SpringMassChain(params).history(count, p["step"])[:, 2]
    signals = {"time": np.arange(count + 1) * p["step"], "right.x[2]": x3}
    return {k: parse(k).value(signals) for k in KPIS}


def main(plot: bool = False, samples: int = SAMPLES, stop: float = STOP,
         backend: str | None = None, out=ROOT / "results" / "parameter_study",
         progress=None, resumed=None) -> dict:
    """Run (or finish) the study in ``out``; compare it with the twin and the physics.
    Returns the points, each KPI's largest difference from the twin relative to the
    twin's value, the largest gap of the mean position from x_s, and the rankings
    (the sweep's, the twin's) per KPI."""
    from dsim.master.sweeps import sensitivity
    from dsim.master.sweeps.sweep import run_sweep

    sweep = sweep_of(samples, stop, backend)
    points, interrupted = run_sweep(SCENE, sweep, Path(out), progress, resumed=resumed)
    design = sweep.plan()
    completed = [p for p in points if p.status == "completed"]
    configurations = [p.settings for p in completed]
    twins = [twin_kpis(c, stop) for c in configurations]
    differences = {k: max(abs(p.kpis[k] - t[k]) / abs(t[k]) for p, t in zip(completed, twins))
                   for k in KPIS}
    glued = sensitivity.analyse(design, configurations,
                                {k: [p.kpis[k] for p in completed] for k in KPIS})
    twin = sensitivity.analyse(design, configurations, {k: [t[k] for t in twins] for k in KPIS})
    result = {
        "points": points, "completed": len(completed), "interrupted": interrupted,
        "kpi_difference": differences,
        "mean_against_static": max(abs(p.kpis[KPIS[0]] / static_deflection(c) - 1)
                                   for p, c in zip(completed, configurations)),
        "peak_over_static": [min(p.kpis[KPIS[1]] / static_deflection(c) for p, c in
                                 zip(completed, configurations)),
                             max(p.kpis[KPIS[1]] / static_deflection(c) for p, c in
                                 zip(completed, configurations))],
        "ranking": {k: sensitivity.ranking(glued, k) for k in KPIS},
        "twin_ranking": {k: sensitivity.ranking(twin, k) for k in KPIS},
        "src": {(i.kpi, i.factor): i.value for i in glued if i.measure == "SRC"},
        "twin_src": {(i.kpi, i.factor): i.value for i in twin if i.measure == "SRC"},
        "r2": {i.kpi: i.value for i in glued if i.measure == "R2"},
        "out": Path(out),
    }
    if plot:
        shutil.copyfile(Path(out) / "kpis.png", ROOT / "docs" / "parameter_study.png")
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ray", action="store_true", help="run the points on a local Ray")
    parser.add_argument("--out", default=str(ROOT / "results" / "parameter_study"))
    arguments = parser.parse_args()
    found = main(plot=True, backend="ray" if arguments.ray else None, out=arguments.out)
    print(f"{found['completed']} points completed")
    for kpi in KPIS:
        print(f"{kpi}: ranking {' > '.join(found['ranking'][kpi])} (twin: "
              f"{' > '.join(found['twin_ranking'][kpi])}), largest difference from the "
              f"twin {found['kpi_difference'][kpi]:.2e}, R^2 {found['r2'][kpi]:.3f}")
        print("  SRC " + ", ".join(f"{f} {found['src'][(kpi, f)]:+.3f} (twin "
                                   f"{found['twin_src'][(kpi, f)]:+.3f})"
                                   for f in PHYSICS_RANKING))
    print(f"mean x3 against x_s: within {found['mean_against_static']:.1%}; peak / x_s "
          f"{found['peak_over_static'][0]:.2f} .. {found['peak_over_static'][1]:.2f}")
    print(f"figure: docs/parameter_study.png; table: {Path(arguments.out) / 'sweep.csv'}")
    assert math.isfinite(found["mean_against_static"])
