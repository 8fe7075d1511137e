"""Crash-safe files of the harness: atomic writes, validated cell results, writable folders.

Every file the harness produces (cell JSON, ``leaderboard.md``, plots) is written to a
temporary name in the target folder and renamed over the target, so a killed run leaves
either the old file or the new one, never a truncated one. Cell results are validated when
read; a broken one raises :class:`CorruptResult` naming its path.

Results layout: ``<out>/<suite>/<env>[__<label>]/<agent>/seed<k>.json``. Folders whose name
starts with ``_`` (the demonstration cache ``_demos``) are not results.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from pathlib import Path
from typing import Any, Callable

#: keys every cell result must have to count as finished
REQUIRED_KEYS = ("cell", "final_normalized_performance", "learning_curve", "trained_steps")


class CorruptResult(ValueError):
    """A cell result file that cannot be used (truncated, not JSON, missing keys)."""

    def __init__(self, path: Path, reason: str):
        super().__init__(f"corrupt result {path}: {reason}")
        self.path = Path(path)


def atomic_write(path: str | os.PathLike, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp)`` for a temporary file next to ``path``, then rename it to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        tmp.replace(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (module docstring)."""
    return atomic_write(path, lambda tmp: tmp.write_text(text))


def write_result(path: str | os.PathLike, result: dict[str, Any]) -> Path:
    """Write one cell result atomically."""
    return atomic_write_text(path, json.dumps(result, indent=1))


def read_result(path: str | os.PathLike) -> dict[str, Any]:
    """One cell result, validated; raises :class:`CorruptResult` naming ``path`` otherwise."""
    path = Path(path)
    try:
        result = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CorruptResult(path, f"{type(exc).__name__}: {exc}") from exc
    if not isinstance(result, dict):
        raise CorruptResult(path, f"expected a JSON object, got {type(result).__name__}")
    missing = [k for k in REQUIRED_KEYS if k not in result]
    if missing:
        raise CorruptResult(path, f"missing keys {missing}")
    finals = result["final_normalized_performance"]
    if not isinstance(finals, list) or not finals or not all(isinstance(v, (int, float)) for v in finals):
        raise CorruptResult(path, "final_normalized_performance must be a non-empty list of numbers")
    cell = result["cell"]
    if not isinstance(cell, dict) or not {"env_id", "agent", "seed"} <= set(cell):
        raise CorruptResult(path, "cell must name env_id, agent and seed")
    extra = result.get("final_metrics", {})  # absent in results written before it was recorded
    if not isinstance(extra, dict) or not all(
            isinstance(v, list) and len(v) == len(finals) and all(isinstance(x, (int, float)) for x in v)
            for v in extra.values()):
        raise CorruptResult(path, "final_metrics must map names to one number per evaluation episode")
    return result


def safe_name(name: str) -> str:
    """A file-name-safe version of ``name`` (letters, digits, ``._-``), as used in the layout."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", str(name)).strip("_")


def result_files(results_dir: str | os.PathLike, suite: str | None = None) -> list[Path]:
    """Cell result files of ``suite`` (all suites if None) in the results layout, sorted."""
    root = Path(results_dir)
    pattern = f"{safe_name(suite)}/*/*/seed*.json" if suite else "*/*/*/seed*.json"
    return sorted(p for p in root.glob(pattern)
                  if p.is_file() and not any(part.startswith("_") for part in p.relative_to(root).parts))


def check_writable(folder: str | os.PathLike) -> Path:
    """Create ``folder`` if needed and prove a file can be written there; ``ValueError`` otherwise."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".write-test-"):
            pass
    except OSError as exc:
        raise ValueError(f"cannot write to {folder}: {exc.strerror or exc}") from exc
    return folder
