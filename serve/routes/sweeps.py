"""Sweeps: launching one from a scene's sweep form (``/scenes/{id}/sweeps``, its model
parameters checked at the ends of their ranges first), and a sweep's page at
``/runs/{id}``: its points, Pareto front, cheapest point within a target error and
sensitivity rankings."""
from __future__ import annotations

import json

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from dsim import TIGHTEST, cheapest, Index, ranking_text, read_sensitivity, unrecorded_columns
from dsim.serve import results
from dsim.serve.forms import FormError, job_sweep, sweep_spec
from dsim.serve.routes.common import (first_values, form_fields, launch, or_404, redirect,
                                      render, results_csv, store_of, stored,
                                      with_parameters, with_scenario)
from dsim.serve.run_scenario import given_scenario

router = APIRouter()


@router.post("/scenes/{scene_id}/sweeps")
async def sweep_form(request: Request, scene_id: int):
    store = store_of(request)
    fields = first_values(await form_fields(request))
    reference = None
    if fields.get("reference") == TIGHTEST:
        reference = TIGHTEST
    elif str(fields.get("reference") or "").isdigit():
        run = or_404(store.run(int(fields["reference"])), "run")
        reference = str(or_404(results_csv(store, run), "results of that run"))
    try:
        spec = sweep_spec(fields, reference)
        given = given_scenario(fields.get("scenario"), fields.get("events"))
        _check_sweep_columns(store, scene_id, spec)
        await _check_sweep_parameters(request, scene_id, spec)
        if given is not None:  # checked with the settings every point shares
            await with_scenario(request, scene_id, dict(spec.get("fixed") or {}), given)
            spec["scenario"] = given
    except FormError as error:
        return render(request, "error.html", 400, status=400, problems=error.problems,
                      back=f"/scenes/{scene_id}")
    return redirect(f"/runs/{launch(request, scene_id, spec, [], 'sweep')}")


def _check_sweep_columns(store, scene_id: int, spec: dict) -> None:
    """Every KPI of a sweep matches a column the stored scene records (as ``dsim
    sweep`` checks them, closest names offered), before the sweep is queued."""
    columns = stored(store, "scenes", scene_id)["description"].get("columns")
    if columns is None:  # a scene stored before descriptions listed them: the run says
        return
    problems = unrecorded_columns(job_sweep(spec), ["time"] + list(columns))
    if problems:
        raise FormError(problems)


async def _check_sweep_parameters(request: Request, scene_id: int, spec: dict) -> None:
    """Every value a sweep's model parameters take at the ends of their ranges (every
    entry of a list), checked as ``dsim run --set`` checks them, over the stored scene
    in a child process, before the sweep is queued (FormError listing the problems)."""
    factors = [f for f in job_sweep(spec).plan().factors if f.is_parameter]
    if not factors:
        return
    ends = [{f.name: f.values[0] if f.kind == "list" else f.low for f in factors},
            {f.name: f.values[-1] if f.kind == "list" else f.high for f in factors}]
    ends += [{**ends[0], f.name: v} for f in factors if f.kind == "list" for v in f.values]
    problems = []
    for trial in {json.dumps(t, sort_keys=True): t for t in ends}.values():
        try:
            await with_parameters(request, scene_id, {}, trial)
        except FormError as error:
            problems += error.problems
    if problems:
        raise FormError(list(dict.fromkeys(problems)))


def sweep_page(request: Request, run_id: int, target: str, context: dict) -> HTMLResponse:
    """The page of sweep ``run_id`` (``context``: the run's, as a run's page has it);
    ``target``: an error whose cheapest point to pick out."""
    folder = store_of(request).run_folder(run_id)
    names, kpis, points = results.sweep_table(folder)
    sensitivity = read_sensitivity(folder)
    indices = [Index(r["kpi"], r["factor"], r["method"], r["measure"], float(r["value"]),
                     float(r.get("confidence") or "nan")) for r in sensitivity]
    rankings = {k: ranking_text(indices, k) for k in dict.fromkeys(i.kpi for i in indices)}
    chosen, problem = None, None
    if target.strip():
        try:
            chosen = _cheapest(points, float(target))
        except ValueError:
            problem = f"target error '{target}' is not a number"
    return render(request, "sweep.html", names=names, points=points, target=target,
                  chosen=chosen, problem=problem, kpis=kpis, sensitivity=sensitivity,
                  rankings=rankings, measured=any(p.error == p.error for p in points),
                  **context)


def _cheapest(points, target: float):
    return cheapest(points, target)
