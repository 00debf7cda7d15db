"""Scenes: the list, a scene's page (diagram, components, parameter sets, runs, the run
and sweep forms), its SVG and file, assembling a new scene from stored FMUs in forms
(``/scenes/new``), a new parameter set of a scene (``/scenes/{id}/parameters``), and
``/api/scenes...``."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import HTMLResponse, Response

from dsim.serve import diagram
from dsim.serve.forms import FormError, parameter_edits, scene_form, scene_spec
from dsim.serve.routes.common import (family, first_values, form_fields, redirect, render,
                                      results_csv, runs_of, store_of, stored, stored_file)
from dsim.serve.run_parameters import form_groups
from dsim.serve.store import Store
from dsim.serve.uploads import UploadError, store_scene
from dsim import SETTINGS, choices
from dsim.serve.assemble import add_parameter_set, write_scene

router = APIRouter()
api = APIRouter()


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


@router.get("/scenes", response_class=HTMLResponse)
def scenes_page(request: Request):
    scenes = store_of(request).all(
        "SELECT scenes.*, (SELECT COUNT(*) FROM runs WHERE runs.scene_id = scenes.id) "
        "AS run_count FROM scenes ORDER BY id DESC")
    return render(request, "scenes.html", scenes=scenes)


def _assemble_page(request: Request, status: int = 200, problems=(), fields=None):
    models = store_of(request).all("SELECT * FROM models ORDER BY name, id")
    return render(request, "assemble.html", status, models=models, problems=list(problems),
                  fields=fields or {}, rows=_form_rows(fields or {}))


def _form_rows(fields: dict) -> dict:
    """How many rows of each kind the assembly form shows (what was sent, or the
    defaults: two components, one joint, no port map, one connection)."""
    return {"component": max(2, len(fields.get("component_name", []))),
            "joint": max(1, len(fields.get("joint_name", []))),
            "port": len(fields.get("port_component", [])),
            "connection": max(1, len(fields.get("connection_start", [])))}


# /scenes/new before /scenes/{scene_id}: the first route whose path matches answers
@router.get("/scenes/new", response_class=HTMLResponse)
def assemble_form(request: Request, start: int | None = None):
    """The assembly form, empty or (``start``: a stored scene's id) filled with that
    scene, to save as a new one."""
    if start is None:
        return _assemble_page(request)
    scene = stored(store_of(request), "scenes", start)
    try:
        return _assemble_page(request, fields=scene_form(scene))
    except FormError as error:
        return _assemble_page(request, 400, error.problems)


@router.get("/scenes/new/row/{kind}", response_class=HTMLResponse)
def assemble_row(request: Request, kind: str):
    """One more empty row of the assembly form (htmx appends it)."""
    if kind not in ("component", "joint", "port", "connection"):
        raise HTTPException(404, "no such row")
    models = store_of(request).all("SELECT id, name, filename FROM models ORDER BY name, id")
    return render(request, "_row.html", kind=kind, models=models, fields={}, k=None)


@router.post("/scenes/new")
async def assemble(request: Request):
    fields = await form_fields(request)
    store = store_of(request)
    try:
        spec, files = scene_spec(fields, store)
        scene_id = await run_in_threadpool(_save_assembled, request, spec, files)
    except (FormError, UploadError) as error:
        return _assemble_page(request, 400, error.problems, fields)
    return redirect(f"/scenes/{scene_id}")


def _save_assembled(request: Request, spec, files) -> int:
    store = store_of(request)
    path = write_scene(spec, files, store.temporary(".ssp"))
    try:
        return store_scene(store, path, f"{spec.name}.ssp", 4 * request.app.state.max_upload,
                           origin="assembled")
    finally:
        path.unlink(missing_ok=True)


@router.get("/scenes/{scene_id}", response_class=HTMLResponse)
def scene_page(request: Request, scene_id: int, parameter_set: str = ""):
    store = store_of(request)
    scene = stored(store, "scenes", scene_id)
    root, members = family(store, scene_id)
    root_scene = store.one("SELECT baseline_run_id FROM scenes WHERE id = ?", root)
    d = scene["description"]
    defaults = {**d["master"], "stop": d["stop_time"], "backend": "in-process",
                "parameter_set": ""}
    settings = [{"keyword": k, "option": s.option, "help": s.help, "default": defaults.get(k),
                 "choices": choices(k) if s.kind is str and s.rule == "choice" else None}
                for k, s in SETTINGS.items() if k not in ("parameter_set", "ssd")]
    models = scene_models(store, scene)
    return render(request, "scene.html", scene=scene, d=d, models=models,
                  svg=diagram.scene_svg(d, models), groups=form_groups(scene, models),
                  runs=runs_of(store, [scene_id]), sweeps=runs_of(store, [scene_id], "sweep"),
                  settings=settings, chosen_set=parameter_set,
                  baseline=root_scene["baseline_run_id"],
                  parent=store.one("SELECT id, name FROM scenes WHERE id = ?",
                                   scene["parent_id"]) if scene["parent_id"] else None,
                  references=[r for r in runs_of(store, members) if results_csv(store, r)])


@router.get("/scenes/{scene_id}/diagram.svg")
def scene_diagram(request: Request, scene_id: int):
    store = store_of(request)
    scene = stored(store, "scenes", scene_id)
    return Response(diagram.scene_svg(scene["description"], scene_models(store, scene)),
                    media_type="image/svg+xml")


@router.get("/scenes/{scene_id}/download")
def scene_download(request: Request, scene_id: int):
    store = store_of(request)
    return stored_file(store, stored(store, "scenes", scene_id), ".ssp")


@router.get("/scenes/{scene_id}/parameters", response_class=HTMLResponse)
def parameters_form(request: Request, scene_id: int):
    store = store_of(request)
    scene = stored(store, "scenes", scene_id)
    return render(request, "parameters.html", scene=scene,
                  rows=editable_parameters(store, scene), problems=[], fields={})


@router.post("/scenes/{scene_id}/parameters")
async def parameters_save(request: Request, scene_id: int):
    """A new .ssv of the changed values: a new scene (the old one plus the set)."""
    store = store_of(request)
    scene = stored(store, "scenes", scene_id)
    fields = first_values(await form_fields(request))
    rows = editable_parameters(store, scene)
    name = str(fields.get("set_name") or "").strip() or "edited"
    try:
        values = parameter_edits(fields, rows)
        new_id, member = await run_in_threadpool(_save_parameter_set, request, scene, name,
                                                 values)
    except (FormError, UploadError) as error:
        return render(request, "parameters.html", 400, scene=scene, rows=rows,
                      problems=error.problems, fields=fields)
    return redirect(f"/scenes/{new_id}?parameter_set={member}")


def _save_parameter_set(request: Request, scene: dict, name: str, values) -> tuple[int, str]:
    store = store_of(request)
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
            for s in store_of(request).all("SELECT * FROM scenes ORDER BY id")]


@api.get("/scenes/{scene_id}")
def scene_api(request: Request, scene_id: int):
    return stored(store_of(request), "scenes", scene_id)
