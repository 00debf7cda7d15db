"""The pages and the JSON API of ``dsim serve``, a module per resource:

* :mod:`.home`: ``/`` (home and upload), ``/upload``;
* :mod:`.models`: ``/models`` and ``/models/{id}`` (the FMU database);
* :mod:`.scenes`: ``/scenes``, ``/scenes/new`` (assemble), ``/scenes/{id}`` (diagram,
  parameter sets, runs, run and sweep forms), ``/scenes/{id}/parameters`` (a new
  parameter set);
* :mod:`.runs`: ``/runs`` and ``/runs/{id}`` (live progress and plots through
  ``/runs/{id}/events``, server-sent events), a run's files;
* :mod:`.sweeps`: launching a sweep, a sweep's page;
* :mod:`.compare`: ``/scenes/{id}/compare``, overlays, the baseline.

:mod:`.common` holds what they share.  JSON under ``/api`` (see ``/api/docs``).  Ids in
addresses are integers and files are found by them; nothing a request says becomes a
path.  :func:`dsim.serve.app.create_app` includes :data:`router` and :data:`api`.
"""
from __future__ import annotations

from fastapi import APIRouter

from dsim.serve.routes import compare, home, models, runs, scenes, sweeps
from dsim.serve.routes.common import add_filters

__all__ = ["add_filters", "api", "router"]

router = APIRouter()
api = APIRouter(prefix="/api")
# the order of /api/docs; no path of one module matches another's, so it decides no request
# (inside a module the first route that matches answers: /scenes/new, then /scenes/{scene_id})
for module in (home, models, scenes, runs, sweeps, compare):
    router.include_router(module.router)
for module in (home, models, scenes, runs, compare):  # sweeps have no JSON of their own
    api.include_router(module.api)
