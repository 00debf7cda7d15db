"""Names a user writes for what a scene holds (``component.variable``, a joint's
coefficient, an input table's column): split at their owner, and, when unknown, the
closest names for the one line that refuses them."""
from __future__ import annotations

import difflib

#: the most names one 'closest' search compares (a large FE FMU has thousands)
SEARCHED = 50000


def closest(name: str, candidates, count: int = 3) -> str:
    """' (closest: a, b)' of the names nearest ``name``, or ''."""
    found = difflib.get_close_matches(name, list(candidates)[:SEARCHED], n=count, cutoff=0.5)
    return f" (closest: {', '.join(found)})" if found else ""


def owner_split(name: str, owners) -> tuple[str, str] | None:
    """(owner, rest) for the longest owner path that prefixes ``name`` and a dot, or None."""
    parts = name.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        owner = ".".join(parts[:cut])
        if owner in owners:
            return owner, ".".join(parts[cut:])
    return None
