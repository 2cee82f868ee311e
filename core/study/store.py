"""A study's results: one SQLite row per cell, written only by the client as tasks complete.

Each finished cell's full result goes to ``runs/<case>/<algorithm>/<seed>.json`` (written atomically
before its row), so a crash or Ctrl-C loses nothing finished, and a row never names a half-written file.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from core.formats.files import atomic_write, dir_lock
from core.formats.study import effective_settings

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    key TEXT PRIMARY KEY,
    case_name TEXT NOT NULL,
    algorithm TEXT NOT NULL,
    seed INTEGER NOT NULL,
    status TEXT NOT NULL,
    error TEXT,
    metrics TEXT,
    result_path TEXT,
    task_time REAL,
    attempts INTEGER NOT NULL DEFAULT 1,
    settings TEXT,
    code TEXT
);
CREATE TABLE IF NOT EXISTS meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
"""


@contextmanager
def study_lock(directory: str | Path) -> Iterator[None]:
    """Hold ``DIR/.lock`` while a study runs into ``DIR``: a second ``clm study`` on the same directory is
    refused (it ran every cell again beside the first, doubling the cost and the attempts counted). The file goes
    with the study (a finished study's folder kept it, with a dead process's number; QA, session 37)."""
    with dir_lock(directory, "clm study", remove=True):
        yield


# The digest scheme ``meta["study"]["digest"]`` names: 2 since session 24 (settings narrowed to what the cell runs);
# a study written before has no such key and digests of the settings as they were compared then.
DIGEST = 2


def settings_digest(settings: str, scheme: int = DIGEST) -> str:
    """A cell's effective settings (a JSON text, which holds its case config's contents) in 16 hex digits."""
    return hashlib.sha256(effective_settings(settings, narrow=scheme >= 2).encode("utf-8")).hexdigest()[:16]


def current_rows(meta: dict[str, Any] | None, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows of the study's cells as the study file last set them (``meta["cells"]``: key -> settings
    digest): not the cells since removed (seeds, algorithms, cases), nor those run with other settings and not run
    again. A study begun before ``cells`` was kept: the rows of its listed seeds."""
    meta = meta or {}
    cells = meta.get("cells")
    if cells is not None:
        scheme = int(meta.get("digest", 1))  # an older study's digests: its report kept every row otherwise dropped
        return [r for r in rows if r["key"] in cells
                and (r.get("settings") is None or settings_digest(r["settings"], scheme) == cells[r["key"]])]
    seeds = set(meta.get("seeds", [r["seed"] for r in rows]))
    return [r for r in rows if r["seed"] in seeds]


class Store:
    """The study directory: ``study.sqlite``, ``runs/``, ``report.md``, ``report.html``."""

    def __init__(self, directory: str | Path) -> None:
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.db = sqlite3.connect(self.dir / "study.sqlite", isolation_level=None)
        self.db.executescript(SCHEMA)
        columns = {row[1] for row in self.db.execute("PRAGMA table_info(runs)")}
        if "settings" not in columns:  # a study begun before cells kept their settings: those read as unknown
            self.db.execute("ALTER TABLE runs ADD COLUMN settings TEXT")
        if "code" not in columns:  # begun before cells kept the digest of their code (session 30): unknown
            self.db.execute("ALTER TABLE runs ADD COLUMN code TEXT")

    def close(self) -> None:
        self.db.close()

    def set_meta(self, name: str, value: Any) -> None:
        self.db.execute("INSERT OR REPLACE INTO meta VALUES (?, ?)", (name, json.dumps(value)))

    def meta(self, name: str, default: Any = None) -> Any:
        row = self.db.execute("SELECT value FROM meta WHERE name = ?", (name,)).fetchone()
        return default if row is None else json.loads(row[0])

    def done(self) -> set[str]:
        return set(self.finished())

    def finished(self) -> dict[str, str | None]:
        """The finished cells' keys and the settings they ran with (None: kept before settings were); a cell whose
        result file is gone (deleted by hand) is not finished: it runs again."""
        rows = self.db.execute("SELECT key, settings, result_path FROM runs WHERE status = 'done'").fetchall()
        return {key: settings for key, settings, path in rows if path is None or (self.dir / path).is_file()}

    def codes(self) -> dict[str, str | None]:
        """The finished cells' keys and the digest of the code that ran them (None: not recorded)."""
        rows = self.db.execute("SELECT key, code FROM runs WHERE status = 'done'").fetchall()
        return {key: code for key, code in rows}

    def save(self, record: dict[str, Any]) -> None:
        """Keep a finished cell: its result file first, then its row (replacing an earlier failed one)."""
        path = None
        if record["status"] == "done":
            rel = Path("runs") / record["case"] / record["algorithm"] / f"{record['seed']}.json"
            atomic_write(self.dir / rel, record["result"])
            path = str(rel)
        prev = self.db.execute("SELECT attempts FROM runs WHERE key = ?", (record["key"],)).fetchone()
        attempts = 1 if prev is None else prev[0] + 1
        self.db.execute(
            "INSERT OR REPLACE INTO runs (key, case_name, algorithm, seed, status, error, metrics, result_path, "
            "task_time, attempts, settings, code) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (record["key"], record["case"], record["algorithm"], record["seed"], record["status"],
             record.get("error"), json.dumps(record.get("metrics")), path, record.get("task_time"), attempts,
             record.get("settings"), record.get("code")),
        )

    def rows(self) -> list[dict[str, Any]]:
        """Every row, ordered by case, algorithm and seed, metrics decoded."""
        return _rows(self.db)


def _rows(db: sqlite3.Connection) -> list[dict[str, Any]]:
    # A study begun before cells kept their settings (or code) has no such column when read without migrating it.
    columns = {row[1] for row in db.execute("PRAGMA table_info(runs)")}
    cur = db.execute(
        "SELECT key, case_name, algorithm, seed, status, error, metrics, result_path, task_time, attempts, "
        f"{'settings' if 'settings' in columns else 'NULL'}, {'code' if 'code' in columns else 'NULL'} FROM runs "
        "ORDER BY case_name, algorithm, seed")
    names = ("key", "case", "algorithm", "seed", "status", "error", "metrics", "result_path", "task_time",
             "attempts", "settings", "code")
    out = []
    for row in cur:
        d = dict(zip(names, row, strict=True))
        d["metrics"] = json.loads(d["metrics"]) if d["metrics"] else None
        out.append(d)
    return out


def read_study(directory: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """A study's meta (decoded) and rows (as ``Store.rows``), opened read-only: nothing is created or migrated, so
    a study another process writes, or one on a read-only disk, can be read (the studio's Studies panel).

    Raises:
        ValueError: the directory holds no ``study.sqlite``, or it is not a readable study.
    """
    db_path = Path(directory) / "study.sqlite"
    if not db_path.is_file():
        raise ValueError(f"{directory} holds no study.sqlite")
    try:
        db = sqlite3.connect(f"file:{db_path}?mode=ro", uri=True)
        try:
            meta = {name: json.loads(value) for name, value in db.execute("SELECT name, value FROM meta")}
            rows = _rows(db)
        finally:
            db.close()
    except (sqlite3.Error, json.JSONDecodeError) as exc:
        raise ValueError(f"{db_path}: not a readable study ({exc})") from None
    return meta, rows
