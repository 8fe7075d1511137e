"""Checkpoints of unfinished cells and their progress files.

A cell that trains a learner with a training state (:mod:`lfd_agents.training_state`) stops at
fixed step counts — every curve point and every ``checkpoint_steps`` env steps — saves what it
needs to go on, and continues from a freshly built learner loaded from that save. A re-run of
a killed cell starts from the newest save and so ends with exactly the result of a run that was
never killed. Everything lives in ``<out>/_checkpoints/<cell key>/``:

* ``state.pt`` — the learner's training state, the curve so far and the harness's counters
  (written atomically: a kill leaves the previous save or the new one);
* ``progress.json`` — steps done, rate, ETA, rewritten at every stop while the cell runs
  (``cat <out>/_checkpoints/*/*/*/seed*/progress.json`` shows every running cell).

The folder is removed once the cell's result is written.
"""

from __future__ import annotations

import io
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from lfd_bench.storage import atomic_write, atomic_write_text

CHECKPOINT_DIRNAME = "_checkpoints"
FORMAT = 1  #: bumped when the layout of ``state.pt`` changes; other versions are not resumed


@dataclass
class CheckpointStore:
    """The checkpoint folder of one cell."""

    folder: Path

    @classmethod
    def for_cell(cls, out: Path, key: str) -> "CheckpointStore":
        return cls(Path(out) / CHECKPOINT_DIRNAME / key)

    @property
    def state_path(self) -> Path:
        return self.folder / "state.pt"

    def save(self, state: dict[str, Any]) -> None:
        """Write ``state`` atomically (the previous save stays until the new one is complete)."""
        buffer = io.BytesIO()
        torch.save({"format": FORMAT, **state}, buffer)
        atomic_write(self.state_path, lambda tmp: tmp.write_bytes(buffer.getvalue()))

    def load(self) -> dict[str, Any] | None:
        """The newest save, or None if there is none (or one this version cannot resume)."""
        if not self.state_path.exists():
            return None
        try:
            state = torch.load(self.state_path, map_location="cpu", weights_only=False)
        except Exception as exc:  # noqa: BLE001 - a broken save only costs the work since the previous one
            print(f"warning: cannot read checkpoint {self.state_path} ({type(exc).__name__}: {exc}); "
                  "starting the cell again", flush=True)
            return None
        if not isinstance(state, dict) or state.get("format") != FORMAT:
            return None
        return state

    def write_progress(self, *, steps: int, budget: int, rate: float, started: float) -> None:
        """Rewrite ``progress.json``: steps done of ``budget``, env steps/s of this process
        (``rate``), ETA in seconds and when this process started (``started``, epoch seconds)."""
        remaining = max(0, budget - steps)
        progress = {"steps": steps, "budget": budget, "fraction": steps / budget if budget else 1.0,
                    "steps_per_s": rate, "eta_s": remaining / rate if rate > 0 else None,
                    "running_since": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(started)),
                    "updated_at": time.strftime("%Y-%m-%d %H:%M:%S")}
        atomic_write_text(self.folder / "progress.json", json.dumps(progress, indent=1))

    def remove(self) -> None:
        """Delete the cell's checkpoint folder (and the parents it leaves empty, up to ``_checkpoints``)."""
        shutil.rmtree(self.folder, ignore_errors=True)
        parent = self.folder.parent
        while parent.name and parent.name != CHECKPOINT_DIRNAME:
            try:
                parent.rmdir()
            except OSError:
                break
            parent = parent.parent
        try:
            parent.rmdir()  # _checkpoints itself, once no cell has one
        except OSError:
            pass
