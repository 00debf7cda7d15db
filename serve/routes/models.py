"""The model database: the stored FMUs searched, one FMU's modelDescription and where
it is used, its file; ``/models...`` and ``/api/models...``."""
from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from dsim.serve.routes.common import render, store_of, stored, stored_file

router = APIRouter()
api = APIRouter()


@router.get("/models", response_class=HTMLResponse)
def models_page(request: Request, q: str = ""):
    return render(request, "models.html", models=store_of(request).search_models(q), q=q)


@router.get("/models/{model_id}", response_class=HTMLResponse)
def model_page(request: Request, model_id: int):
    store = store_of(request)
    model = stored(store, "models", model_id)
    used = store.all("SELECT scenes.id, scenes.name, scene_models.component FROM "
                     "scene_models JOIN scenes ON scenes.id = scene_models.scene_id "
                     "WHERE model_id = ? ORDER BY scenes.id", model_id)
    return render(request, "model.html", model=model, d=model["description"], used=used)


@router.get("/models/{model_id}/download")
def model_download(request: Request, model_id: int):
    store = store_of(request)
    return stored_file(store, stored(store, "models", model_id), ".fmu")


@api.get("/models")
def models_api(request: Request, q: str = ""):
    """Stored FMUs matching ``q`` (name, file name, description, variables)."""
    return [{k: m[k] for k in ("id", "name", "filename", "sha256", "size")}
            for m in store_of(request).search_models(q)]


@api.get("/models/{model_id}")
def model_api(request: Request, model_id: int):
    return stored(store_of(request), "models", model_id)
