"""Comparing the runs of a scene's family (the scene, its ancestors' and descendants'
runs): ``dsim compare``'s verdict against the family's baseline run, one column of
several runs overlaid, choosing the baseline; ``/scenes/{id}/compare``,
``/scenes/{id}/overlay...``, ``/scenes/{id}/baseline`` and ``/api/scenes/{id}/compare``."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import HTMLResponse, Response

from dsim.serve import results
from dsim.serve.routes.common import (family, form_fields, or_404, redirect, render,
                                      results_csv, runs_of, store_of, stored)
from dsim.serve.store import ACTIVE, Store

router = APIRouter()
api = APIRouter()


def _comparable(store: Store, scene_id: int) -> tuple[int, dict, list[dict]]:
    root, members = family(store, scene_id)
    baseline = store.one("SELECT baseline_run_id FROM scenes WHERE id = ?",
                         root)["baseline_run_id"]
    runs = [r for r in runs_of(store, members) if r["status"] not in ACTIVE
            and results_csv(store, r)]
    return root, {"baseline": baseline}, runs


def comparison(store: Store, scene_id: int, chosen: list[int], rtol: float,
               atol: float) -> dict:
    """The runs of a scene's family, the baseline, and the ``dsim compare`` verdict
    of each chosen run against it."""
    root, marks, runs = _comparable(store, scene_id)
    by_id = {r["id"]: r for r in runs}
    chosen = [i for i in chosen if i in by_id] or [r["id"] for r in runs[:2]]
    baseline = marks["baseline"] if marks["baseline"] in by_id else None
    verdicts = {}
    if baseline is not None:
        for run_id in chosen:
            if run_id != baseline:
                verdicts[run_id] = results.verdict(results_csv(store, by_id[run_id]),
                                                   results_csv(store, by_id[baseline]),
                                                   rtol, atol)
    return {"root": root, "runs": runs, "chosen": chosen, "baseline": baseline,
            "verdicts": verdicts, "rtol": rtol, "atol": atol}


def _columns(store: Store, scene_id: int) -> list[str]:
    scene = store.one("SELECT description FROM scenes WHERE id = ?", scene_id)
    return [c for c in scene["description"]["columns"]] if scene else []


@router.get("/scenes/{scene_id}/compare", response_class=HTMLResponse)
def compare_page(request: Request, scene_id: int, rtol: float = 1e-6, atol: float = 0.0,
                 column: str = ""):
    store = store_of(request)
    scene = stored(store, "scenes", scene_id)
    chosen = [int(v) for v in request.query_params.getlist("run") if v.isdigit()]
    found = comparison(store, scene_id, chosen, rtol, atol)
    columns = _columns(store, scene_id)
    return render(request, "compare.html", scene=scene, columns=columns,
                  column=column if column in columns else (columns[0] if columns else ""),
                  **found)


def _overlay_sources(request: Request, scene_id: int) -> dict:
    store = store_of(request)
    _, _, runs = _comparable(store, scene_id)
    by_id = {r["id"]: r for r in runs}
    chosen = [int(v) for v in request.query_params.getlist("run") if v.isdigit()]
    return {f"run {i}": results_csv(store, by_id[i]) for i in chosen if i in by_id}


@router.get("/scenes/{scene_id}/overlay.json")
def overlay_json(request: Request, scene_id: int, column: str):
    """One column of the chosen runs (``?run=1&run=2``), for the overlay chart."""
    return results.overlay(_overlay_sources(request, scene_id), column)


@router.get("/scenes/{scene_id}/overlay.png")
def overlay_png(request: Request, scene_id: int, column: str):
    sources = _overlay_sources(request, scene_id)
    if not sources:
        raise HTTPException(404, "choose runs with results")
    return Response(results.overlay_png(sources, [column], column), media_type="image/png")


@router.post("/scenes/{scene_id}/baseline")
async def baseline_page(request: Request, scene_id: int):
    """Mark a run as the baseline of its scene's family."""
    store = store_of(request)
    fields = await form_fields(request)
    root, _, runs = _comparable(store, scene_id)
    chosen = str((fields.get("baseline") or [""])[0])
    if not chosen.isdigit() or int(chosen) not in {r["id"] for r in runs}:
        raise HTTPException(400, "the baseline must be an ended run of this scene with results")
    store.execute("UPDATE scenes SET baseline_run_id = ? WHERE id = ?", int(chosen), root)
    back = "&".join(f"run={r}" for r in fields.get("run", []) if str(r).isdigit())
    return redirect(f"/scenes/{scene_id}/compare" + (f"?{back}" if back else ""))


@api.get("/scenes/{scene_id}/compare")
def compare_api(request: Request, scene_id: int, rtol: float = 1e-6, atol: float = 0.0):
    """The verdict of the chosen runs (``?run=``) against the scene's baseline."""
    or_404(store_of(request).one("SELECT id FROM scenes WHERE id = ?", scene_id), "scene")
    chosen = [int(v) for v in request.query_params.getlist("run") if v.isdigit()]
    found = comparison(store_of(request), scene_id, chosen, rtol, atol)
    return {"baseline": found["baseline"], "chosen": found["chosen"],
            "verdicts": {str(k): v for k, v in found["verdicts"].items()}}
