"""The model database of ``dsim serve``: one SQLite file (WAL mode, created on first
use) and, beside it, a folder of files named by what they are, never by what a
user called them.

* ``blobs/ab/abcdef...``: every uploaded or assembled FMU and .ssp, named by the
  sha256 of its content (the same file uploaded twice is stored once);
* ``runs/<id>/``: what a run or sweep writes (its CSV, statistics, live samples),
  named by the run's number in the database.

The database survives a killed server: every change is one committed
transaction, and a run in flight when the server died is marked interrupted
when the next server opens the database (:meth:`dsim.serve.jobs.Jobs.reconcile`).
Each run records the server that owns it (``owner``, :mod:`dsim.serve.owner`):
only that server starts and finalises it.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import sqlite3
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

SCHEMA = """
CREATE TABLE IF NOT EXISTS models (
    id INTEGER PRIMARY KEY,
    sha256 TEXT UNIQUE NOT NULL,
    size INTEGER NOT NULL,
    filename TEXT NOT NULL,          -- as uploaded: shown, never used as a path
    name TEXT NOT NULL,              -- modelName
    description TEXT NOT NULL,       -- JSON: the modelDescription summary
    created REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS scenes (
    id INTEGER PRIMARY KEY,
    sha256 TEXT UNIQUE NOT NULL,
    size INTEGER NOT NULL,
    filename TEXT NOT NULL,
    name TEXT NOT NULL,
    description TEXT NOT NULL,       -- JSON: components, connections, joints, columns ...
    parent_id INTEGER REFERENCES scenes(id),
    origin TEXT NOT NULL,            -- uploaded, assembled, parameters
    baseline_run_id INTEGER,
    created REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS scene_models (
    scene_id INTEGER NOT NULL REFERENCES scenes(id),
    model_id INTEGER NOT NULL REFERENCES models(id),
    component TEXT NOT NULL,
    PRIMARY KEY (scene_id, component)
);
CREATE TABLE IF NOT EXISTS runs (
    id INTEGER PRIMARY KEY,
    kind TEXT NOT NULL,              -- run or sweep
    scene_id INTEGER NOT NULL REFERENCES scenes(id),
    settings TEXT NOT NULL,          -- JSON: dsim run's settings (a sweep: its spec)
    signals TEXT NOT NULL,           -- JSON: columns plotted live
    status TEXT NOT NULL,            -- queued, running, completed, failed, interrupted
    message TEXT NOT NULL DEFAULT '',
    inputs TEXT NOT NULL DEFAULT '{}',  -- JSON: file -> sha256 of every input
    statistics TEXT,                 -- JSON: the run's statistics
    exit_code INTEGER,
    steps INTEGER,
    time_reached REAL,
    pid INTEGER,
    owner TEXT,                      -- the server that owns it (dsim.serve.owner)
    rerun_of INTEGER,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    created REAL NOT NULL,
    started REAL,
    ended REAL
);
CREATE INDEX IF NOT EXISTS runs_by_scene ON runs(scene_id);
"""

#: the largest id SQLite stores (a signed 64-bit integer): a larger one names no row
MAX_ID = 2**63 - 1

#: statuses of a run that has not ended
ACTIVE = ("queued", "running")


def sha256_file(path: Path) -> str:
    """The sha256 of a file's content (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for chunk in iter(lambda: file.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _row(row: sqlite3.Row | None) -> dict | None:
    """A row as a dict, its JSON columns decoded."""
    if row is None:
        return None
    data = dict(row)
    for key in ("description", "settings", "signals", "inputs", "statistics"):
        if isinstance(data.get(key), str):
            data[key] = json.loads(data[key])
    return data


def _beyond_sqlite(args) -> bool:
    """Whether an argument is an integer SQLite cannot hold (it would raise
    OverflowError): such an id names no row."""
    return any(isinstance(a, int) and not -MAX_ID - 1 <= a <= MAX_ID for a in args)


class Store:
    """The database file and its folder of blobs and run folders."""

    def __init__(self, path, owner: str | None = None):
        self.path = Path(path).resolve()
        #: the server this store belongs to: the owner of the runs it adds
        self.owner = owner
        self.files = self.path.with_name(self.path.name + ".files")
        self.blobs = self.files / "blobs"
        self.runs = self.files / "runs"
        self.incoming = self.files / "incoming"
        for folder in (self.blobs, self.runs, self.incoming):
            folder.mkdir(parents=True, exist_ok=True)
        with self.connect() as db:
            db.execute("PRAGMA journal_mode=WAL")
            db.executescript(SCHEMA)
            columns = {row["name"] for row in db.execute("PRAGMA table_info(runs)")}
            if "owner" not in columns:  # a database made before runs had owners
                db.execute("ALTER TABLE runs ADD COLUMN owner TEXT")

    # --- connections -------------------------------------------------------------
    @contextmanager
    def connect(self):
        """A connection for one unit of work, committed at the end (or rolled back)."""
        db = sqlite3.connect(self.path, timeout=30)
        db.row_factory = sqlite3.Row
        db.execute("PRAGMA foreign_keys=ON")
        db.execute("PRAGMA busy_timeout=30000")
        try:
            with db:
                yield db
        finally:
            db.close()

    def one(self, sql: str, *args) -> dict | None:
        if _beyond_sqlite(args):
            return None
        with self.connect() as db:
            return _row(db.execute(sql, args).fetchone())

    def all(self, sql: str, *args) -> list[dict]:
        if _beyond_sqlite(args):
            return []
        with self.connect() as db:
            return [_row(r) for r in db.execute(sql, args).fetchall()]

    def execute(self, sql: str, *args) -> int:
        """Run one statement; the new row's id."""
        with self.connect() as db:
            return db.execute(sql, args).lastrowid

    # --- blobs -------------------------------------------------------------------
    def blob_path(self, sha: str) -> Path:
        """Where the file with this content is (checked to be a sha256, so that no
        text from a request can name another path)."""
        if len(sha) != 64 or any(c not in "0123456789abcdef" for c in sha):
            raise ValueError(f"not a sha256: {sha!r}")
        return self.blobs / sha[:2] / sha

    def temporary(self, suffix: str = "") -> Path:
        """A new empty file in the store's own folder for incoming data (same file
        system as the blobs, so that keeping it is a rename)."""
        handle, name = tempfile.mkstemp(dir=self.incoming, suffix=suffix)
        os.close(handle)
        return Path(name)

    def keep(self, path: Path) -> tuple[str, int]:
        """Move a finished incoming file into the blobs under its sha256 (the copy
        already there wins); returns (sha256, size)."""
        sha, size = sha256_file(path), path.stat().st_size
        target = self.blob_path(sha)
        if target.exists():
            path.unlink()
        else:
            target.parent.mkdir(exist_ok=True)
            os.replace(path, target)
            os.chmod(target, 0o444)  # content-addressed: never changed in place
        return sha, size

    def keep_bytes(self, data: bytes) -> tuple[str, int]:
        """:meth:`keep` for bytes in memory."""
        path = self.temporary()
        path.write_bytes(data)
        return self.keep(path)

    def run_folder(self, run_id: int) -> Path:
        """The folder of run ``run_id`` (an integer: never a name from a request)."""
        return self.runs / str(int(run_id))

    # --- models and scenes ---------------------------------------------------------
    def add_model(self, sha: str, size: int, filename: str, description: dict) -> int:
        """The model with this content: stored now, or the one stored before."""
        # one statement that may find the row there: uploads of one file at once
        # (each checked in its own thread) all get the row the first one wrote
        with self.connect() as db:
            db.execute(
                "INSERT INTO models (sha256, size, filename, name, description, created) "
                "VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT (sha256) DO NOTHING", (
                    sha, size, filename, description.get("modelName") or filename,
                    json.dumps(description), time.time()))
            return db.execute("SELECT id FROM models WHERE sha256 = ?", (sha,)).fetchone()[0]

    def add_scene(self, sha: str, size: int, filename: str, description: dict,
                  models: dict, origin: str = "uploaded", parent_id: int | None = None) -> int:
        """The scene with this content (stored now or before); ``models`` maps each
        component to the id of its FMU's model."""
        with self.connect() as db:  # as add_model: the same file at once is one row
            inserted = db.execute(
                "INSERT INTO scenes (sha256, size, filename, name, description, parent_id, "
                "origin, created) VALUES (?, ?, ?, ?, ?, ?, ?, ?) "
                "ON CONFLICT (sha256) DO NOTHING", (
                    sha, size, filename, description.get("name") or filename,
                    json.dumps(description), parent_id, origin, time.time())).rowcount
            scene_id = db.execute("SELECT id FROM scenes WHERE sha256 = ?",
                                  (sha,)).fetchone()[0]
            if not inserted:
                return scene_id
            db.executemany("INSERT INTO scene_models VALUES (?, ?, ?)",
                           [(scene_id, model_id, component)
                            for component, model_id in models.items()])
        return scene_id

    def search_models(self, query: str = "") -> list[dict]:
        """Models whose name, file name, description or variables mention ``query``."""
        like = f"%{query.strip()}%"
        return self.all("SELECT * FROM models WHERE name LIKE ? OR filename LIKE ? "
                        "OR description LIKE ? ORDER BY name, id", like, like, like)

    # --- runs ----------------------------------------------------------------------
    def add_run(self, kind: str, scene_id: int, settings: dict, signals: list,
                rerun_of: int | None = None) -> int:
        """A new queued run (or sweep) of a scene."""
        return self.execute(
            "INSERT INTO runs (kind, scene_id, settings, signals, status, owner, rerun_of, "
            "created) VALUES (?, ?, ?, ?, 'queued', ?, ?, ?)", kind, scene_id,
            json.dumps(settings), json.dumps(signals), self.owner, rerun_of, time.time())

    def update_run(self, run_id: int, **values) -> None:
        """Set columns of a run (dicts and lists stored as JSON)."""
        columns = ", ".join(f"{key} = ?" for key in values)
        encoded = [json.dumps(v) if isinstance(v, (dict, list)) else v
                   for v in values.values()]
        self.execute(f"UPDATE runs SET {columns} WHERE id = ?", *encoded, run_id)

    def run(self, run_id: int) -> dict | None:
        return self.one("SELECT * FROM runs WHERE id = ?", run_id)

    def remove_incoming(self) -> None:
        """Forget uploads a killed server left half received."""
        shutil.rmtree(self.incoming, ignore_errors=True)
        self.incoming.mkdir(parents=True, exist_ok=True)
