"""Runs: launching one from a scene's form or the JSON API, the list, a run's page
(a sweep's: :mod:`.sweeps`) with its live progress and plots through
``/runs/{id}/events`` (server-sent events), cancel and rerun, its signals and files;
``/api/scenes/{id}/runs`` and ``/api/runs/{id}...``."""
from __future__ import annotations

import asyncio
import json
from pathlib import Path

from fastapi import APIRouter, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import (FileResponse, HTMLResponse, JSONResponse, Response,
                               StreamingResponse)

from dsim.serve import results
from dsim.serve.forms import FormError, run_settings
from dsim.serve.routes import sweeps
from dsim.serve.routes.common import (download_name, first_values, form_fields, launch,
                                      or_404, redirect, render, results_csv, store_of,
                                      with_parameters, with_scenario)
from dsim.serve.run_parameters import form_values
from dsim.serve.run_scenario import given_scenario
from dsim.serve.store import ACTIVE
from dsim import SETTINGS

router = APIRouter()
api = APIRouter()

#: run files a user can download: address suffix -> (file, media type)
DOWNLOADS = {"results.csv": ("results.csv", "text/csv"),
             "stats.json": ("results.stats.json", "application/json"),
             "sweep.csv": ("sweep.csv", "text/csv"), "sweep.md": ("sweep.md", "text/markdown"),
             "sweep.png": ("sweep.png", "image/png"), "kpis.png": ("kpis.png", "image/png"),
             "scatter.png": ("scatter.png", "image/png"),
             "sensitivity.csv": ("sensitivity.csv", "text/csv"),
             "sensitivity.md": ("sensitivity.md", "text/markdown"),
             "design.json": ("design.json", "application/json")}


@router.post("/scenes/{scene_id}/runs")
async def run_form(request: Request, scene_id: int):
    fields = await form_fields(request)
    try:
        values = first_values(fields)
        settings = run_settings(values)
        given = given_scenario(values.get("scenario"), values.get("events"))
        settings = await with_parameters(request, scene_id, settings, form_values(values))
        settings = await with_scenario(request, scene_id, settings, given)
    except FormError as error:
        return render(request, "error.html", 400, status=400, problems=error.problems,
                      back=f"/scenes/{scene_id}")
    return redirect(f"/runs/{launch(request, scene_id, settings, fields.get('signal', []))}")


@router.get("/runs", response_class=HTMLResponse)
def runs_page(request: Request):
    runs = store_of(request).all("SELECT runs.*, scenes.name AS scene_name FROM runs JOIN "
                                 "scenes ON scenes.id = runs.scene_id ORDER BY runs.id DESC")
    return render(request, "runs.html", runs=runs)


def _run_context(request: Request, run_id: int) -> dict:
    store = store_of(request)
    run = or_404(store.run(run_id), "run")
    scene = store.one("SELECT id, name, description FROM scenes WHERE id = ?", run["scene_id"])
    folder = store.run_folder(run_id)
    return {"run": run, "scene": scene, "active": run["status"] in ACTIVE,
            "files": {k: (folder / f).exists() for k, (f, _) in DOWNLOADS.items()}}


@router.get("/runs/{run_id}", response_class=HTMLResponse)
def run_page(request: Request, run_id: int, target: str = ""):
    context = _run_context(request, run_id)
    if context["run"]["kind"] == "sweep":
        return sweeps.sweep_page(request, run_id, target, context)
    return render(request, "run.html", **context)


@router.get("/runs/{run_id}/status", response_class=HTMLResponse)
def run_status(request: Request, run_id: int):
    return render(request, "_status.html", **_run_context(request, run_id))


def _sse(event: str, data: str) -> str:
    return f"event: {event}\n" + "".join(f"data: {line}\n" for line in data.split("\n")) + "\n"


def _thinned_history(lines: list) -> list:
    """The live lines a page receives when it opens: every line that is not a sample,
    and at most about :data:`results.MAX_POINTS` samples evenly spread, the last one
    kept (a long run writes 20 samples a second)."""
    samples = [k for k, line in enumerate(lines) if line.get("type") == "sample"]
    kept = set(samples[results.thin(len(samples))]) | set(samples[-1:])
    return [line for k, line in enumerate(lines)
            if line.get("type") != "sample" or k in kept]


def _new_lines(path: Path, offset: int) -> tuple[list, int]:
    """Whole JSON lines of ``live.jsonl`` after ``offset``, and the new offset."""
    try:
        with open(path, "rb") as file:
            file.seek(offset)
            data = file.read()
    except OSError:
        return [], offset
    whole = data[:data.rfind(b"\n") + 1]
    return [json.loads(line) for line in whole.splitlines() if line.strip()], offset + len(whole)


@router.get("/runs/{run_id}/events")
async def run_events(request: Request, run_id: int):
    """Server-sent events of a run: ``samples`` (new lines of live.jsonl, JSON),
    ``status`` (the status block, HTML, when it changes), ``done`` when it ended."""
    store = store_of(request)
    or_404(store.run(run_id), "run")
    path = store.run_folder(run_id) / "live.jsonl"
    template = request.app.state.templates.env.get_template("_status.html")

    async def stream():
        offset, shown = 0, None
        yield "retry: 2000\n\n"
        while True:
            context = await run_in_threadpool(_run_context, request, run_id)
            first = offset == 0
            lines, offset = await run_in_threadpool(_new_lines, path, offset)
            if first:  # a page opened on a long run: its history, thinned
                lines = _thinned_history(lines)
            if lines:
                yield _sse("samples", json.dumps(lines))
            state = (context["run"]["status"], context["run"]["cancel_requested"])
            if state != shown:
                shown = state
                yield _sse("status", template.render(request=request, **context))
            if not context["active"]:
                yield _sse("done", context["run"]["status"])
                return
            await asyncio.sleep(0.25)

    return StreamingResponse(stream(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache"})


@router.post("/runs/{run_id}/cancel")
def cancel_page(request: Request, run_id: int):
    or_404(store_of(request).run(run_id), "run")
    request.app.state.jobs.cancel(run_id)
    return redirect(f"/runs/{run_id}")


@router.post("/runs/{run_id}/rerun")
def rerun_page(request: Request, run_id: int):
    """The same scene file (by its hash) with the same settings, as a new run."""
    run = or_404(store_of(request).run(run_id), "run")
    new = launch(request, run["scene_id"], run["settings"], run["signals"], run["kind"],
                 rerun_of=run_id)
    return redirect(f"/runs/{new}")


@router.get("/runs/{run_id}/signals.json")
def run_signals(request: Request, run_id: int):
    """Every numeric column of a run's CSV, thinned for a chart."""
    store = store_of(request)
    run = or_404(store.run(run_id), "run")
    path = or_404(results_csv(store, run), "results CSV")
    return results.signals(path, run["signals"] or None)


# last of /runs/{run_id}/...: any name the routes above do not take
@router.get("/runs/{run_id}/{name}")
def run_download(request: Request, run_id: int, name: str):
    """A run's files: results.csv, stats.json, results.mat and results.png (made from
    the CSV with dsim's writers), a sweep's sweep.csv, sweep.md, sweep.png."""
    store = store_of(request)
    run = or_404(store.run(run_id), "run")
    scene = store.one("SELECT name FROM scenes WHERE id = ?", run["scene_id"])
    stem = download_name(f"{scene['name']}_run{run_id}", "")
    if name in ("results.mat", "results.png"):
        path = or_404(results_csv(store, run), "results CSV")
        if name == "results.mat":
            data, media = results.mat(path), "application/x-matlab-data"
        else:
            data, media = results.png(path, f"{scene['name']}, run {run_id}"), "image/png"
        return Response(data, media_type=media, headers={
            "Content-Disposition": f'attachment; filename="{stem}{Path(name).suffix}"'})
    if name not in DOWNLOADS:
        raise HTTPException(404, "no such file")
    file, media = DOWNLOADS[name]
    path = or_404(store.run_folder(run_id) / file, "file")
    if not path.exists():
        raise HTTPException(404, f"run {run_id} has no {name}")
    return FileResponse(path, media_type=media, filename=f"{stem}_{name}")


@api.post("/scenes/{scene_id}/runs")
async def run_api(request: Request, scene_id: int):
    """Launch a run: JSON body ``{"settings": {...}, "signals": [...], "parameters":
    {...}, "scenario": "...", "events": "point"}`` (settings as ``dsim.simulate``'s
    keywords, parameters as its ``parameters``: name -> value; scenario the text of a
    scenario file, libcosim's JSON or YAML or ECOS's XML, and events when its events
    take effect); ``{"id": N}`` or 400 with ``problems``."""
    body = await _json_object(request)
    settings, signals = body.get("settings") or {}, body.get("signals") or []
    parameters = body.get("parameters") or {}
    if not isinstance(settings, dict):
        raise HTTPException(400, '"settings" must be a JSON object of setting: value')
    if not isinstance(parameters, dict):
        raise HTTPException(400, '"parameters" must be a JSON object of name: value')
    if not isinstance(signals, list) or not all(isinstance(s, str) for s in signals):
        raise HTTPException(400, '"signals" must be a JSON list of column names')
    unknown = sorted(set(settings) - set(SETTINGS) | ({"ssd"} & set(settings)))
    if unknown:  # a form has other fields; a JSON body names settings only
        raise HTTPException(400, f"unknown setting {', '.join(map(repr, unknown))} "
                                 f"(known: {', '.join(SETTINGS)})")
    try:
        settings = run_settings(settings)
        given = given_scenario(body.get("scenario"), body.get("events"))
        settings = await with_parameters(request, scene_id, settings, parameters)
        settings = await with_scenario(request, scene_id, settings, given)
    except FormError as error:
        return JSONResponse({"problems": error.problems}, status_code=400)
    return {"id": launch(request, scene_id, settings, signals)}


async def _json_object(request: Request) -> dict:
    """The request's body as a JSON object, else 400 with one line."""
    try:
        body = json.loads(await request.body())
    except (ValueError, RecursionError) as error:  # bad JSON, bad UTF-8, nesting
        reason = str(error).splitlines()[0][:200] if str(error) else type(error).__name__
        raise HTTPException(400, f"the body is not JSON: {reason}") from None
    if not isinstance(body, dict):
        raise HTTPException(400, "the body must be a JSON object")
    return body


@api.get("/runs/{run_id}")
def run_get_api(request: Request, run_id: int):
    return or_404(store_of(request).run(run_id), "run")


@api.post("/runs/{run_id}/cancel")
def cancel_api(request: Request, run_id: int):
    or_404(store_of(request).run(run_id), "run")
    return {"cancelled": request.app.state.jobs.cancel(run_id)}
