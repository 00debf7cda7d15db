"""A scenario given with a run of a stored scene (the scene page's form, or the JSON API's
``scenario`` and ``events``; docs/serve.md): its text checked against the scene by
``dsim run --scenario``'s rules in a child process (:mod:`dsim.serve.inspect`, as the
model parameters are), stored with the run's settings, and written into the run's own
folder as a file when the run starts (serve/worker.py).

The text is untrusted: its size is bounded here before anything reads it, and the child
parses it with the master's readers (libcosim's JSON or YAML, ECOS's XML without DTDs or
entities: reading/small_files.py)."""
from __future__ import annotations

import json

from dsim import EVENT_MODES
from dsim.serve.forms import FormError
from dsim.serve.uploads import UploadError, inspect_file

#: the largest scenario a form or the API takes (characters): a scenario of hundreds of
#: events is a few kilobytes
MAX_CHARACTERS = 256 * 1024


def scenario_format(text: str) -> str:
    """The file suffix a scenario's text is read by: ECOS's XML where it starts with
    ``<``, JSON where it starts with ``{``, else libcosim's YAML."""
    start = text.lstrip()[:1]
    return "xml" if start == "<" else "json" if start == "{" else "yml"


def given_scenario(text, events) -> dict | None:
    """The scenario a form or JSON body gives (``text``; ``events``: point or exact), or
    None (no text); FormError for a text too long or an unknown ``events``."""
    events = str(events or "point").strip() or "point"
    if events not in EVENT_MODES:
        raise FormError([f"events '{events}' is not one of: {', '.join(EVENT_MODES)}"])
    if text is None or not str(text).strip():
        if events != "point":
            raise FormError(["events chooses when a scenario's events take effect: give a "
                             "scenario with it"])
        return None
    if not isinstance(text, str):
        raise FormError(['"scenario" must be the text of a scenario (libcosim\'s JSON or '
                         "YAML, or ECOS's XML)"])
    if len(text) > MAX_CHARACTERS:
        raise FormError([f"the scenario has {len(text)} characters, more than the "
                         f"{MAX_CHARACTERS} a run takes"])
    return {"text": text, "format": scenario_format(text), "events": events}


def checked_scenario(store, scene: dict, given: dict, settings: dict,
                     max_unpacked: int) -> list[str]:
    """The lines ``dsim info --scenario`` says of ``given`` on ``scene`` run with
    ``settings`` (its stop time and step place the events; its model parameters are
    the unmodified values); FormError listing what is wrong."""
    try:
        answer = inspect_file("scenario", store.blob_path(scene["sha256"]), max_unpacked,
                              scene["filename"], json.dumps({**given, "settings": settings}))
    except UploadError as error:
        raise FormError(error.problems) from None
    return answer["lines"]
