"""What the route modules share: the request's store and templates, 404s, redirects and
download names, form fields, the scene family and run queries, and launching a run or
sweep of a stored scene."""
from __future__ import annotations

import math
import time
from pathlib import Path

from fastapi import HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse

from dsim.serve.run_scenario import checked_scenario
from dsim.serve.run_parameters import checked, command_options, run_command
from dsim.serve.store import Store


def add_filters(env) -> None:
    """Jinja filters the templates use."""
    env.filters["num"] = lambda v, f=".4g": "" if v is None else (
        format(v, f) if isinstance(v, (int, float)) and math.isfinite(v) else str(v))
    env.filters["when"] = lambda t: time.strftime("%Y-%m-%d %H:%M:%S",
                                                  time.localtime(t)) if t else ""
    env.filters["command_options"] = command_options
    env.filters["command"] = run_command
    # numbers as a person reads them (14.14, not 14.139999999999999), lists joined
    env.filters["numbers"] = lambda v: " ".join(
        format(x, ".10g") if isinstance(x, float) else str(x) for x in v) \
        if isinstance(v, (list, tuple)) else (format(v, ".10g") if isinstance(v, float)
                                              else str(v))
    env.globals["row_value"] = lambda fields, name, k: (
        str(fields[name][k]) if k is not None and k < len(fields.get(name, ())) else "")


def store_of(request: Request) -> Store:
    return request.app.state.store


def render(request: Request, name: str, code: int = 200, **context) -> HTMLResponse:
    return request.app.state.templates.TemplateResponse(request, name, context,
                                                        status_code=code)


def or_404(row, what: str):
    """``row``, or 404 "no such ``what``" when there is none."""
    if row is None:
        raise HTTPException(404, f"no such {what}")
    return row


def stored(store: Store, table: str, item: int) -> dict:
    """The model or scene ``item`` (``table``: models or scenes), or 404."""
    return or_404(store.one(f"SELECT * FROM {table} WHERE id = ?", item), table[:-1])


def stored_file(store: Store, row: dict, suffix: str) -> FileResponse:
    """The stored file of a model or scene, named after it."""
    return FileResponse(store.blob_path(row["sha256"]), media_type="application/zip",
                        filename=download_name(row["name"], suffix))


def redirect(url: str) -> RedirectResponse:
    return RedirectResponse(url, status_code=303)


def download_name(text: str, suffix: str) -> str:
    """A file name for a download, from a name out of the database (its letters,
    digits and ``-_.``)."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in text)[:80].strip("._")
    return (safe or "dsim") + suffix


async def form_fields(request: Request) -> dict:
    """Form fields as name -> list of values (rows of a form repeat names)."""
    form = await request.form()
    fields: dict = {}
    for key, value in form.multi_items():
        fields.setdefault(key, []).append(value)
    return fields


def first_values(fields: dict) -> dict:
    """name -> the first value of :func:`form_fields`' lists."""
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


def runs_of(store: Store, scene_ids: list[int], kind: str = "run") -> list[dict]:
    """The runs (or sweeps) of some scenes, newest first."""
    marks = ",".join("?" * len(scene_ids))
    return store.all(f"SELECT * FROM runs WHERE kind = ? AND scene_id IN ({marks}) "
                     "ORDER BY id DESC", kind, *scene_ids)


def results_csv(store: Store, run: dict) -> Path | None:
    """A run's results.csv, None while it has none."""
    path = store.run_folder(run["id"]) / "results.csv"
    return path if path.exists() else None


def launch(request: Request, scene_id: int, settings: dict, signals: list,
           kind: str = "run", rerun_of: int | None = None) -> int:
    """Queue a run (or sweep) of a stored scene; its id."""
    store = store_of(request)
    or_404(store.one("SELECT id FROM scenes WHERE id = ?", scene_id), "scene")
    run_id = store.add_run(kind, scene_id, settings, signals, rerun_of)
    request.app.state.jobs.submit(run_id)
    return run_id


async def with_scenario(request: Request, scene_id: int, settings: dict,
                        given: dict | None) -> dict:
    """``settings`` with the scenario ``given`` (serve/run_scenario.py), checked by
    ``dsim run --scenario``'s rules over the stored scene with the run's model
    parameters (FormError)."""
    if given is None:
        return settings
    store = store_of(request)
    scene = stored(store, "scenes", scene_id)
    await run_in_threadpool(checked_scenario, store, scene, given, settings,
                            request.app.state.max_upload * 4)
    return {**settings, "scenario": given}


async def with_parameters(request: Request, scene_id: int, settings: dict,
                          values: dict) -> dict:
    """``settings`` with the model parameters ``values`` as the run will apply them,
    checked by ``dsim run --set``'s rules over the stored scene (FormError)."""
    if not values:
        return settings
    store = store_of(request)
    scene = stored(store, "scenes", scene_id)
    applied = await run_in_threadpool(checked, store, scene, values,
                                      request.app.state.max_upload * 4)
    return {**settings, "parameters": applied}
