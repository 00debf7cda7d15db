"""The pages and the JSON API of ``dsim serve``.

Pages (HTML, htmx): ``/`` home and upload, ``/models`` and ``/models/{id}``,
``/scenes``, ``/scenes/new`` (assemble), ``/scenes/{id}`` (diagram, parameter
sets, runs, run and sweep forms), ``/scenes/{id}/parameters`` (a new parameter
set), ``/scenes/{id}/compare``, ``/runs`` and ``/runs/{id}`` (live progress and
plots through ``/runs/{id}/events``, server-sent events).  JSON under ``/api``
(see ``/api/docs``).  Ids in addresses are integers and files are found by
them; nothing a request says becomes a path.
"""
from __future__ import annotations

import asyncio
import json
import math
import shutil
import time
from pathlib import Path

from fastapi import APIRouter, File, HTTPException, Request, UploadFile
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import (FileResponse, HTMLResponse, JSONResponse, RedirectResponse,
                               Response, StreamingResponse)

from dsim.master.sweeps.sweep import TIGHTEST
from dsim.serve import diagram, results
from dsim.serve.forms import (FormError, parameter_edits, run_settings, scene_form, scene_spec,
                              sweep_spec)
from dsim.serve.run_parameters import checked, command_options, form_groups, form_values
from dsim.serve.store import ACTIVE, Store
from dsim.serve.uploads import UploadError, store_scene, store_upload

router = APIRouter()
api = APIRouter(prefix="/api")

#: run files a user can download: address suffix -> (file, media type)
DOWNLOADS = {"results.csv": ("results.csv", "text/csv"),
             "stats.json": ("results.stats.json", "application/json"),
             "sweep.csv": ("sweep.csv", "text/csv"), "sweep.md": ("sweep.md", "text/markdown"),
             "sweep.png": ("sweep.png", "image/png"), "kpis.png": ("kpis.png", "image/png"),
             "scatter.png": ("scatter.png", "image/png"),
             "sensitivity.csv": ("sensitivity.csv", "text/csv"),
             "sensitivity.md": ("sensitivity.md", "text/markdown"),
             "design.json": ("design.json", "application/json")}


# --- helpers -------------------------------------------------------------------------
def add_filters(env) -> None:
    """Jinja filters the templates use."""
    env.filters["num"] = lambda v, f=".4g": "" if v is None else (
        format(v, f) if isinstance(v, (int, float)) and math.isfinite(v) else str(v))
    env.filters["when"] = lambda t: time.strftime("%Y-%m-%d %H:%M:%S",
                                                  time.localtime(t)) if t else ""
    env.filters["command_options"] = command_options
    env.globals["row_value"] = lambda fields, name, k: (
        str(fields[name][k]) if k is not None and k < len(fields.get(name, ())) else "")


def _store(request: Request) -> Store:
    return request.app.state.store


def _render(request: Request, name: str, code: int = 200, **context) -> HTMLResponse:
    return request.app.state.templates.TemplateResponse(request, name, context,
                                                        status_code=code)


def _found(row, what: str):
    if row is None:
        raise HTTPException(404, f"no such {what}")
    return row


def _get(store: Store, table: str, item: int) -> dict:
    """The model or scene ``item`` (``table``: models or scenes), or 404."""
    return _found(store.one(f"SELECT * FROM {table} WHERE id = ?", item), table[:-1])


def _blob(store: Store, row: dict, suffix: str) -> FileResponse:
    """The stored file of a model or scene, named after it."""
    return FileResponse(store.blob_path(row["sha256"]), media_type="application/zip",
                        filename=_download_name(row["name"], suffix))


def _redirect(url: str) -> RedirectResponse:
    return RedirectResponse(url, status_code=303)


def _download_name(text: str, suffix: str) -> str:
    """A file name for a download, from a name out of the database (its letters,
    digits and ``-_.``)."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in text)[:80].strip("._")
    return (safe or "dsim") + suffix


async def _fields(request: Request) -> dict:
    """Form fields as name -> list of values (rows of a form repeat names)."""
    form = await request.form()
    fields: dict = {}
    for key, value in form.multi_items():
        fields.setdefault(key, []).append(value)
    return fields


def _first(fields: dict) -> dict:
    return {k: v[0] for k, v in fields.items()}


def family(store: Store, scene_id: int) -> tuple[int, list[int]]:
    """The first scene of a scene's family (its oldest ancestor) and every scene that
    descends from it: their runs can be compared."""
    root = scene_id
    while True:
        parent = store.one("SELECT parent_id FROM scenes WHERE id = ?", root)
        if not parent or not parent["parent_id"]:
            break
        root = parent["parent_id"]
    members, frontier = [root], [root]
    while frontier:
        children = store.all(f"SELECT id FROM scenes WHERE parent_id IN "
                             f"({','.join('?' * len(frontier))})", *frontier)
        frontier = [c["id"] for c in children]
        members += frontier
    return root, members


def scene_models(store: Store, scene: dict) -> dict:
    """model id -> FMU description, for the models of a scene's components."""
    ids = {c.get("model_id") for c in scene["description"]["components"]} - {None}
    return {m["id"]: m["description"] for m in store.all(
        f"SELECT id, description FROM models WHERE id IN ({','.join('?' * len(ids))})",
        *ids)} if ids else {}


def editable_parameters(store: Store, scene: dict) -> list[dict]:
    """Every parameter of every component of a scene, with the value it has in the
    scene (else its FMU's start value), in the order the page shows them."""
    models = scene_models(store, scene)
    rows = []
    for component in scene["description"]["components"]:
        model = models.get(component.get("model_id"), {})
        given = component["parameters"]
        for variable in model.get("variables", ()):
            if variable["causality"] != "parameter" or variable["variability"] == "constant":
                continue
            value = given[variable["name"]][1] if variable["name"] in given else \
                variable["start"]
            if isinstance(value, bool):
                value = str(value).lower()
            rows.append({"component": component["path"], "name": variable["name"],
                         "type": variable["type"], "unit": variable["unit"] or "",
                         "value": "" if value is None else value,
                         "set": variable["name"] in given,
                         "description": variable["description"]})
    return rows


def _runs_of(store: Store, scene_ids: list[int], kind: str = "run") -> list[dict]:
    marks = ",".join("?" * len(scene_ids))
    return store.all(f"SELECT * FROM runs WHERE kind = ? AND scene_id IN ({marks}) "
                     "ORDER BY id DESC", kind, *scene_ids)


def _csv(store: Store, run: dict) -> Path | None:
    path = store.run_folder(run["id"]) / "results.csv"
    return path if path.exists() else None


# --- home, uploads -----------------------------------------------------------------
@router.get("/", response_class=HTMLResponse)
def home(request: Request):
    store = _store(request)
    counts = {table: store.one(f"SELECT COUNT(*) AS n FROM {table}")["n"]
              for table in ("models", "scenes", "runs")}
    recent = store.all("SELECT runs.*, scenes.name AS scene_name FROM runs JOIN scenes "
                       "ON scenes.id = runs.scene_id ORDER BY runs.id DESC LIMIT 10")
    return _render(request, "home.html", counts=counts, runs=recent)


def _receive(request: Request, upload: UploadFile) -> tuple[str, int]:
    """Keep an uploaded file (it is checked in a child process)."""
    store = _store(request)
    path = store.temporary()
    with open(path, "wb") as target:
        shutil.copyfileobj(upload.file, target, 1 << 20)
    return store_upload(store, path, upload.filename,
                        max_unpacked=4 * request.app.state.max_upload)


@router.post("/upload")
def upload_page(request: Request, file: UploadFile = File(...)):
    try:
        kind, item = _receive(request, file)
    except UploadError as error:
        return _render(request, "error.html", 400, status=400, problems=error.problems,
                       back="/")
    return _redirect(f"/{kind}s/{item}")


@api.post("/upload")
def upload_api(request: Request, file: UploadFile = File(...)):
    """Upload an FMU or .ssp: ``{"kind": "model"|"scene", "id": N}``, or 400 with
    ``problems``."""
    try:
        kind, item = _receive(request, file)
    except UploadError as error:
        return JSONResponse({"problems": error.problems}, status_code=400)
    return {"kind": kind, "id": item}


# --- models --------------------------------------------------------------------------
@router.get("/models", response_class=HTMLResponse)
def models_page(request: Request, q: str = ""):
    return _render(request, "models.html", models=_store(request).search_models(q), q=q)


@router.get("/models/{model_id}", response_class=HTMLResponse)
def model_page(request: Request, model_id: int):
    store = _store(request)
    model = _get(store, "models", model_id)
    used = store.all("SELECT scenes.id, scenes.name, scene_models.component FROM "
                     "scene_models JOIN scenes ON scenes.id = scene_models.scene_id "
                     "WHERE model_id = ? ORDER BY scenes.id", model_id)
    return _render(request, "model.html", model=model, d=model["description"], used=used)


@router.get("/models/{model_id}/download")
def model_download(request: Request, model_id: int):
    store = _store(request)
    return _blob(store, _get(store, "models", model_id), ".fmu")


@api.get("/models")
def models_api(request: Request, q: str = ""):
    """Stored FMUs matching ``q`` (name, file name, description, variables)."""
    return [{k: m[k] for k in ("id", "name", "filename", "sha256", "size")}
            for m in _store(request).search_models(q)]


@api.get("/models/{model_id}")
def model_api(request: Request, model_id: int):
    return _get(_store(request), "models", model_id)


# --- scenes ----------------------------------------------------------------------------
@router.get("/scenes", response_class=HTMLResponse)
def scenes_page(request: Request):
    scenes = _store(request).all(
        "SELECT scenes.*, (SELECT COUNT(*) FROM runs WHERE runs.scene_id = scenes.id) "
        "AS run_count FROM scenes ORDER BY id DESC")
    return _render(request, "scenes.html", scenes=scenes)


def _assemble_page(request: Request, status: int = 200, problems=(), fields=None):
    models = _store(request).all("SELECT * FROM models ORDER BY name, id")
    return _render(request, "assemble.html", status, models=models, problems=list(problems),
                   fields=fields or {}, rows=_form_rows(fields or {}))


def _form_rows(fields: dict) -> dict:
    """How many rows of each kind the assembly form shows (what was sent, or the
    defaults: two components, one joint, no port map, one connection)."""
    return {"component": max(2, len(fields.get("component_name", []))),
            "joint": max(1, len(fields.get("joint_name", []))),
            "port": len(fields.get("port_component", [])),
            "connection": max(1, len(fields.get("connection_start", [])))}


@router.get("/scenes/new", response_class=HTMLResponse)
def assemble_form(request: Request, start: int | None = None):
    """The assembly form, empty or (``start``: a stored scene's id) filled with that
    scene, to save as a new one."""
    if start is None:
        return _assemble_page(request)
    scene = _get(_store(request), "scenes", start)
    try:
        return _assemble_page(request, fields=scene_form(scene))
    except FormError as error:
        return _assemble_page(request, 400, error.problems)


@router.get("/scenes/new/row/{kind}", response_class=HTMLResponse)
def assemble_row(request: Request, kind: str):
    """One more empty row of the assembly form (htmx appends it)."""
    if kind not in ("component", "joint", "port", "connection"):
        raise HTTPException(404, "no such row")
    models = _store(request).all("SELECT id, name, filename FROM models ORDER BY name, id")
    return _render(request, "_row.html", kind=kind, models=models, fields={}, k=None)


@router.post("/scenes/new")
async def assemble(request: Request):
    fields = await _fields(request)
    store = _store(request)
    try:
        spec, files = scene_spec(fields, store)
        scene_id = await run_in_threadpool(_save_assembled, request, spec, files)
    except (FormError, UploadError) as error:
        return _assemble_page(request, 400, error.problems, fields)
    return _redirect(f"/scenes/{scene_id}")


def _save_assembled(request: Request, spec, files) -> int:
    from dsim.serve.assemble import write_scene

    store = _store(request)
    path = write_scene(spec, files, store.temporary(".ssp"))
    try:
        return store_scene(store, path, f"{spec.name}.ssp", 4 * request.app.state.max_upload,
                           origin="assembled")
    finally:
        path.unlink(missing_ok=True)


@router.get("/scenes/{scene_id}", response_class=HTMLResponse)
def scene_page(request: Request, scene_id: int, parameter_set: str = ""):
    from dsim.master.settings import SETTINGS, choices

    store = _store(request)
    scene = _get(store, "scenes", scene_id)
    root, members = family(store, scene_id)
    root_scene = store.one("SELECT baseline_run_id FROM scenes WHERE id = ?", root)
    d = scene["description"]
    defaults = {**d["master"], "stop": d["stop_time"], "backend": "in-process",
                "parameter_set": ""}
    settings = [{"keyword": k, "option": s.option, "help": s.help, "default": defaults.get(k),
                 "choices": choices(k) if s.kind is str and s.rule == "choice" else None}
                for k, s in SETTINGS.items() if k not in ("parameter_set", "ssd")]
    models = scene_models(store, scene)
    return _render(request, "scene.html", scene=scene, d=d, models=models,
                   svg=diagram.scene_svg(d, models), groups=form_groups(scene, models),
                   runs=_runs_of(store, [scene_id]), sweeps=_runs_of(store, [scene_id], "sweep"),
                   settings=settings, chosen_set=parameter_set,
                   baseline=root_scene["baseline_run_id"],
                   parent=store.one("SELECT id, name FROM scenes WHERE id = ?",
                                    scene["parent_id"]) if scene["parent_id"] else None,
                   references=[r for r in _runs_of(store, members) if _csv(store, r)])


@router.get("/scenes/{scene_id}/diagram.svg")
def scene_diagram(request: Request, scene_id: int):
    store = _store(request)
    scene = _get(store, "scenes", scene_id)
    return Response(diagram.scene_svg(scene["description"], scene_models(store, scene)),
                    media_type="image/svg+xml")


@router.get("/scenes/{scene_id}/download")
def scene_download(request: Request, scene_id: int):
    store = _store(request)
    return _blob(store, _get(store, "scenes", scene_id), ".ssp")


@router.get("/scenes/{scene_id}/parameters", response_class=HTMLResponse)
def parameters_form(request: Request, scene_id: int):
    store = _store(request)
    scene = _get(store, "scenes", scene_id)
    return _render(request, "parameters.html", scene=scene,
                   rows=editable_parameters(store, scene), problems=[], fields={})


@router.post("/scenes/{scene_id}/parameters")
async def parameters_save(request: Request, scene_id: int):
    """A new .ssv of the changed values: a new scene (the old one plus the set)."""
    store = _store(request)
    scene = _get(store, "scenes", scene_id)
    fields = _first(await _fields(request))
    rows = editable_parameters(store, scene)
    name = str(fields.get("set_name") or "").strip() or "edited"
    try:
        values = parameter_edits(fields, rows)
        new_id, member = await run_in_threadpool(_save_parameter_set, request, scene, name,
                                                 values)
    except (FormError, UploadError) as error:
        return _render(request, "parameters.html", 400, scene=scene, rows=rows,
                       problems=error.problems, fields=fields)
    return _redirect(f"/scenes/{new_id}?parameter_set={member}")


def _save_parameter_set(request: Request, scene: dict, name: str, values) -> tuple[int, str]:
    from dsim.serve.assemble import add_parameter_set

    store = _store(request)
    path = store.temporary(".ssp")
    try:
        member = add_parameter_set(store.blob_path(scene["sha256"]), name, values, path)
        new_id = store_scene(store, path, scene["filename"], 4 * request.app.state.max_upload,
                             origin="parameters", parent_id=scene["id"])
    finally:
        path.unlink(missing_ok=True)
    return new_id, member


@api.get("/scenes")
def scenes_api(request: Request):
    return [{k: s[k] for k in ("id", "name", "sha256", "origin", "parent_id")}
            for s in _store(request).all("SELECT * FROM scenes ORDER BY id")]


@api.get("/scenes/{scene_id}")
def scene_api(request: Request, scene_id: int):
    return _get(_store(request), "scenes", scene_id)


# --- runs ----------------------------------------------------------------------------------
def launch(request: Request, scene_id: int, settings: dict, signals: list,
           kind: str = "run", rerun_of: int | None = None) -> int:
    """Queue a run (or sweep) of a stored scene; its id."""
    store = _store(request)
    _found(store.one("SELECT id FROM scenes WHERE id = ?", scene_id), "scene")
    run_id = store.add_run(kind, scene_id, settings, signals, rerun_of)
    request.app.state.jobs.submit(run_id)
    return run_id


async def _with_parameters(request: Request, scene_id: int, settings: dict,
                           values: dict) -> dict:
    """``settings`` with the model parameters ``values`` as the run will apply them,
    checked by ``dsim run --set``'s rules over the stored scene (FormError)."""
    if not values:
        return settings
    store = _store(request)
    scene = _get(store, "scenes", scene_id)
    applied = await run_in_threadpool(checked, store, scene, values,
                                      request.app.state.max_upload * 4)
    return {**settings, "parameters": applied}


@router.post("/scenes/{scene_id}/runs")
async def run_form(request: Request, scene_id: int):
    fields = await _fields(request)
    try:
        settings = run_settings(_first(fields))
        settings = await _with_parameters(request, scene_id, settings,
                                          form_values(_first(fields)))
    except FormError as error:
        return _render(request, "error.html", 400, status=400, problems=error.problems,
                       back=f"/scenes/{scene_id}")
    return _redirect(f"/runs/{launch(request, scene_id, settings, fields.get('signal', []))}")


@router.post("/scenes/{scene_id}/sweeps")
async def sweep_form(request: Request, scene_id: int):
    store = _store(request)
    fields = _first(await _fields(request))
    reference = None
    if fields.get("reference") == TIGHTEST:
        reference = TIGHTEST
    elif str(fields.get("reference") or "").isdigit():
        run = _found(store.run(int(fields["reference"])), "run")
        reference = str(_found(_csv(store, run), "results of that run"))
    try:
        spec = sweep_spec(fields, reference)
        await _check_sweep_parameters(request, scene_id, spec)
    except FormError as error:
        return _render(request, "error.html", 400, status=400, problems=error.problems,
                       back=f"/scenes/{scene_id}")
    return _redirect(f"/runs/{launch(request, scene_id, spec, [], 'sweep')}")


async def _check_sweep_parameters(request: Request, scene_id: int, spec: dict) -> None:
    """Every value a sweep's model parameters take at the ends of their ranges (every
    entry of a list), checked as ``dsim run --set`` checks them, over the stored scene
    in a child process, before the sweep is queued (FormError listing the problems)."""
    from dsim.serve.forms import job_sweep

    factors = [f for f in job_sweep(spec).plan().factors if f.is_parameter]
    if not factors:
        return
    ends = [{f.name: f.values[0] if f.kind == "list" else f.low for f in factors},
            {f.name: f.values[-1] if f.kind == "list" else f.high for f in factors}]
    ends += [{**ends[0], f.name: v} for f in factors if f.kind == "list" for v in f.values]
    problems = []
    for trial in {json.dumps(t, sort_keys=True): t for t in ends}.values():
        try:
            await _with_parameters(request, scene_id, {}, trial)
        except FormError as error:
            problems += error.problems
    if problems:
        raise FormError(list(dict.fromkeys(problems)))


@router.get("/runs", response_class=HTMLResponse)
def runs_page(request: Request):
    runs = _store(request).all("SELECT runs.*, scenes.name AS scene_name FROM runs JOIN scenes "
                               "ON scenes.id = runs.scene_id ORDER BY runs.id DESC")
    return _render(request, "runs.html", runs=runs)


def _run_context(request: Request, run_id: int) -> dict:
    store = _store(request)
    run = _found(store.run(run_id), "run")
    scene = store.one("SELECT id, name, description FROM scenes WHERE id = ?", run["scene_id"])
    folder = store.run_folder(run_id)
    return {"run": run, "scene": scene, "active": run["status"] in ACTIVE,
            "files": {k: (folder / f).exists() for k, (f, _) in DOWNLOADS.items()}}


@router.get("/runs/{run_id}", response_class=HTMLResponse)
def run_page(request: Request, run_id: int, target: str = ""):
    context = _run_context(request, run_id)
    if context["run"]["kind"] == "sweep":
        from dsim.master.sweeps.sensitivity import Index, ranking
        from dsim.master.sweeps.folder import read_sensitivity

        folder = _store(request).run_folder(run_id)
        names, kpis, points = results.sweep_table(folder)
        sensitivity = read_sensitivity(folder)
        indices = [Index(r["kpi"], r["factor"], r["method"], r["measure"], float(r["value"]))
                   for r in sensitivity]
        rankings = {k: ranking(indices, k) for k in dict.fromkeys(i.kpi for i in indices)}
        chosen, problem = None, None
        if target.strip():
            try:
                chosen = _cheapest(points, float(target))
            except ValueError:
                problem = f"target error '{target}' is not a number"
        return _render(request, "sweep.html", names=names, points=points, target=target,
                       chosen=chosen, problem=problem, kpis=kpis, sensitivity=sensitivity,
                       rankings=rankings, measured=any(p.error == p.error for p in points),
                       **context)
    return _render(request, "run.html", **context)


def _cheapest(points, target: float):
    from dsim.master.sweeps.sweep import cheapest
    return cheapest(points, target)


@router.get("/runs/{run_id}/status", response_class=HTMLResponse)
def run_status(request: Request, run_id: int):
    return _render(request, "_status.html", **_run_context(request, run_id))


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
    store = _store(request)
    _found(store.run(run_id), "run")
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
    _found(_store(request).run(run_id), "run")
    request.app.state.jobs.cancel(run_id)
    return _redirect(f"/runs/{run_id}")


@router.post("/runs/{run_id}/rerun")
def rerun_page(request: Request, run_id: int):
    """The same scene file (by its hash) with the same settings, as a new run."""
    run = _found(_store(request).run(run_id), "run")
    new = launch(request, run["scene_id"], run["settings"], run["signals"], run["kind"],
                 rerun_of=run_id)
    return _redirect(f"/runs/{new}")


@router.get("/runs/{run_id}/signals.json")
def run_signals(request: Request, run_id: int):
    """Every numeric column of a run's CSV, thinned for a chart."""
    store = _store(request)
    run = _found(store.run(run_id), "run")
    path = _found(_csv(store, run), "results CSV")
    return results.signals(path, run["signals"] or None)


@router.get("/runs/{run_id}/{name}")
def run_download(request: Request, run_id: int, name: str):
    """A run's files: results.csv, stats.json, results.mat and results.png (made from
    the CSV with dsim's writers), a sweep's sweep.csv, sweep.md, sweep.png."""
    store = _store(request)
    run = _found(store.run(run_id), "run")
    scene = store.one("SELECT name FROM scenes WHERE id = ?", run["scene_id"])
    stem = _download_name(f"{scene['name']}_run{run_id}", "")
    if name in ("results.mat", "results.png"):
        path = _found(_csv(store, run), "results CSV")
        if name == "results.mat":
            data, media = results.mat(path), "application/x-matlab-data"
        else:
            data, media = results.png(path, f"{scene['name']}, run {run_id}"), "image/png"
        return Response(data, media_type=media, headers={
            "Content-Disposition": f'attachment; filename="{stem}{Path(name).suffix}"'})
    if name not in DOWNLOADS:
        raise HTTPException(404, "no such file")
    file, media = DOWNLOADS[name]
    path = _found(store.run_folder(run_id) / file, "file")
    if not path.exists():
        raise HTTPException(404, f"run {run_id} has no {name}")
    return FileResponse(path, media_type=media, filename=f"{stem}_{name}")


@api.post("/scenes/{scene_id}/runs")
async def run_api(request: Request, scene_id: int):
    """Launch a run: JSON body ``{"settings": {...}, "signals": [...], "parameters":
    {...}}`` (settings as ``dsim.simulate``'s keywords, parameters as its
    ``parameters``: name -> value); ``{"id": N}`` or 400 with ``problems``."""
    body = await _json_object(request)
    settings, signals = body.get("settings") or {}, body.get("signals") or []
    parameters = body.get("parameters") or {}
    if not isinstance(settings, dict):
        raise HTTPException(400, '"settings" must be a JSON object of setting: value')
    if not isinstance(parameters, dict):
        raise HTTPException(400, '"parameters" must be a JSON object of name: value')
    if not isinstance(signals, list) or not all(isinstance(s, str) for s in signals):
        raise HTTPException(400, '"signals" must be a JSON list of column names')
    from dsim.master.settings import SETTINGS

    unknown = sorted(set(settings) - set(SETTINGS) | ({"ssd"} & set(settings)))
    if unknown:  # a form has other fields; a JSON body names settings only
        raise HTTPException(400, f"unknown setting {', '.join(map(repr, unknown))} "
                                 f"(known: {', '.join(SETTINGS)})")
    try:
        settings = run_settings(settings)
        settings = await _with_parameters(request, scene_id, settings, parameters)
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
    return _found(_store(request).run(run_id), "run")


@api.post("/runs/{run_id}/cancel")
def cancel_api(request: Request, run_id: int):
    _found(_store(request).run(run_id), "run")
    return {"cancelled": request.app.state.jobs.cancel(run_id)}


# --- compare ---------------------------------------------------------------------------------
def _comparable(store: Store, scene_id: int) -> tuple[int, dict, list[dict]]:
    root, members = family(store, scene_id)
    baseline = store.one("SELECT baseline_run_id FROM scenes WHERE id = ?",
                         root)["baseline_run_id"]
    runs = [r for r in _runs_of(store, members) if r["status"] not in ACTIVE
            and _csv(store, r)]
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
                verdicts[run_id] = results.verdict(_csv(store, by_id[run_id]),
                                                   _csv(store, by_id[baseline]), rtol, atol)
    return {"root": root, "runs": runs, "chosen": chosen, "baseline": baseline,
            "verdicts": verdicts, "rtol": rtol, "atol": atol}


def _columns(store: Store, scene_id: int) -> list[str]:
    scene = store.one("SELECT description FROM scenes WHERE id = ?", scene_id)
    return [c for c in scene["description"]["columns"]] if scene else []


@router.get("/scenes/{scene_id}/compare", response_class=HTMLResponse)
def compare_page(request: Request, scene_id: int, rtol: float = 1e-6, atol: float = 0.0,
                 column: str = ""):
    store = _store(request)
    scene = _get(store, "scenes", scene_id)
    chosen = [int(v) for v in request.query_params.getlist("run") if v.isdigit()]
    found = comparison(store, scene_id, chosen, rtol, atol)
    columns = _columns(store, scene_id)
    return _render(request, "compare.html", scene=scene, columns=columns,
                   column=column if column in columns else (columns[0] if columns else ""),
                   **found)


def _overlay_sources(request: Request, scene_id: int) -> dict:
    store = _store(request)
    _, _, runs = _comparable(store, scene_id)
    by_id = {r["id"]: r for r in runs}
    chosen = [int(v) for v in request.query_params.getlist("run") if v.isdigit()]
    return {f"run {i}": _csv(store, by_id[i]) for i in chosen if i in by_id}


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
    store = _store(request)
    fields = await _fields(request)
    root, _, runs = _comparable(store, scene_id)
    chosen = str((fields.get("baseline") or [""])[0])
    if not chosen.isdigit() or int(chosen) not in {r["id"] for r in runs}:
        raise HTTPException(400, "the baseline must be an ended run of this scene with results")
    store.execute("UPDATE scenes SET baseline_run_id = ? WHERE id = ?", int(chosen), root)
    back = "&".join(f"run={r}" for r in fields.get("run", []) if str(r).isdigit())
    return _redirect(f"/scenes/{scene_id}/compare" + (f"?{back}" if back else ""))


@api.get("/scenes/{scene_id}/compare")
def compare_api(request: Request, scene_id: int, rtol: float = 1e-6, atol: float = 0.0):
    """The verdict of the chosen runs (``?run=``) against the scene's baseline."""
    _found(_store(request).one("SELECT id FROM scenes WHERE id = ?", scene_id), "scene")
    chosen = [int(v) for v in request.query_params.getlist("run") if v.isdigit()]
    found = comparison(_store(request), scene_id, chosen, rtol, atol)
    return {"baseline": found["baseline"], "chosen": found["chosen"],
            "verdicts": {str(k): v for k, v in found["verdicts"].items()}}
