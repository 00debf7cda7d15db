"""The home page (counts, recent runs, the upload form) and uploads of FMUs and .ssp
scenes: ``/``, ``/upload`` and ``/api/upload``."""
from __future__ import annotations

import shutil

from fastapi import APIRouter, File, Request, UploadFile
from fastapi.responses import HTMLResponse, JSONResponse

from dsim.serve.routes.common import redirect, render, store_of
from dsim.serve.uploads import UploadError, store_upload

router = APIRouter()
api = APIRouter()


@router.get("/", response_class=HTMLResponse)
def home(request: Request):
    store = store_of(request)
    counts = {table: store.one(f"SELECT COUNT(*) AS n FROM {table}")["n"]
              for table in ("models", "scenes", "runs")}
    recent = store.all("SELECT runs.*, scenes.name AS scene_name FROM runs JOIN scenes "
                       "ON scenes.id = runs.scene_id ORDER BY runs.id DESC LIMIT 10")
    return render(request, "home.html", counts=counts, runs=recent)


def _receive(request: Request, upload: UploadFile) -> tuple[str, int]:
    """Keep an uploaded file (it is checked in a child process)."""
    store = store_of(request)
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
        return render(request, "error.html", 400, status=400, problems=error.problems,
                      back="/")
    return redirect(f"/{kind}s/{item}")


@api.post("/upload")
def upload_api(request: Request, file: UploadFile = File(...)):
    """Upload an FMU or .ssp: ``{"kind": "model"|"scene", "id": N}``, or 400 with
    ``problems``."""
    try:
        kind, item = _receive(request, file)
    except UploadError as error:
        return JSONResponse({"problems": error.problems}, status_code=400)
    return {"kind": kind, "id": item}
