"""Where cells run: in this process, in a pool of local processes, or as tasks on a Ray cluster.

Every executor takes the cells still to run and a ``done(cell, result)`` callback that the
driver uses to write the cell's JSON (so results land in the same layout whichever executor
ran them, and a resumed run skips them). A cell that raises is reported and the others go
on; a cell whose worker process died (killed, out of memory) is retried up to
``retries`` times.

* ``local`` with ``jobs=1``: one cell after another in this process.
* ``local`` with ``jobs=N``: ``N`` worker processes (spawned, so no torch/Warp state is
  forked); each gets ``cpu_count // N`` torch threads.
* ``ray``: one Ray task per cell, asking for the cell's ``cpus``; ``address`` is a running
  cluster (``ray start --head`` prints it), or None to start a local Ray instance.
"""

from __future__ import annotations

import os
import sys
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

EXECUTORS = ("local", "ray")
Done = Callable[[Any, dict[str, Any]], None]


@dataclass
class CellFailure:
    """A cell that did not produce a result."""

    cell: Any
    error: str

    def __str__(self) -> str:
        return f"{self.cell.key}: {self.error}"


class CellsFailed(RuntimeError):
    """Raised after all other cells finished when some cells failed."""

    def __init__(self, failures: list[CellFailure]):
        self.failures = failures
        lines = "\n".join(f"  {f}" for f in failures)
        super().__init__(f"{len(failures)} cell(s) failed:\n{lines}")


def _checkpoint_folder(checkpoints: str | Path | None, cell: Any) -> Path | None:
    """The cell's own folder under the checkpoint root (None: no checkpoints)."""
    return Path(checkpoints) / cell.key if checkpoints else None


def _execute(cell: Any, demo_cache: str | None, threads: int | None, checkpoints: str | None = None) -> dict[str, Any]:
    """Worker entry point: run one cell (module-level so processes and Ray can import it)."""
    from lfd_bench.cell import run_cell

    import torch

    flush_denormals(True)  # see run_serial
    if threads:
        torch.set_num_threads(int(threads))
    return run_cell(cell, progress=False, demo_cache=Path(demo_cache) if demo_cache else None,
                    checkpoints=_checkpoint_folder(checkpoints, cell))


def flush_denormals(enable: bool) -> None:
    """``torch.set_flush_denormal(enable)``, with numpy's float limits computed first: numpy
    derives them on first use, and with subnormals flushed it would find the smallest subnormal
    to be zero (and warn "The value of the smallest subnormal ... is zero" each run)."""
    import numpy as np
    import torch

    for dtype in (np.float16, np.float32, np.float64, np.longdouble):
        np.finfo(dtype)  # cached by numpy with the true values
    torch.set_flush_denormal(enable)


def flush_denormals_enabled() -> bool:
    """Whether torch flushes float subnormals to zero on this CPU (``torch.set_flush_denormal``)."""
    import torch

    return bool(torch.tensor([1e-40], dtype=torch.float32).item() == 0.0)


def _error(exc: BaseException) -> str:
    return "".join(traceback.format_exception_only(type(exc), exc)).strip()


def run_serial(cells: list[Any], done: Done, *, demo_cache: Path | None, progress: bool = True,
               checkpoints: Path | None = None) -> None:
    """Run ``cells`` one after another in this process."""
    import torch
    from tqdm import tqdm

    from lfd_bench.cell import run_cell

    # Weights and Adam moments that decay into float subnormals make every CPU matmul several
    # times slower as training goes on (DMfD: 40 -> 11 updates/s after ~6k updates); flush them.
    flushing = flush_denormals_enabled()
    flush_denormals(True)
    failures = []
    threads = torch.get_num_threads()
    for cell in tqdm(cells, desc="cells", disable=not progress, file=sys.stderr):
        # the cell's own core count: more torch threads than cores make tiny networks crawl
        # (threads wait for each other whenever another process holds a core)
        torch.set_num_threads(max(1, int(getattr(cell, "cpus", 1))))
        try:
            result = run_cell(cell, progress=progress, demo_cache=demo_cache,
                              checkpoints=_checkpoint_folder(checkpoints, cell))
        except Exception as exc:  # report, keep going: the other cells are independent
            traceback.print_exc(file=sys.stderr)
            failures.append(CellFailure(cell, _error(exc)))
            continue
        finally:
            torch.set_num_threads(threads)
        done(cell, result)
    flush_denormals(flushing)
    if failures:
        raise CellsFailed(failures)


def run_processes(cells: list[Any], done: Done, *, jobs: int, demo_cache: Path | None, progress: bool = True,
                  checkpoints: Path | None = None,
                  retries: int = 2) -> None:
    """Run ``cells`` in ``jobs`` spawned worker processes; retry cells whose worker died."""
    import multiprocessing as mp

    from tqdm import tqdm

    threads = max(1, (os.cpu_count() or 1) // jobs)
    attempts = {id(c): 0 for c in cells}
    todo, failures = list(cells), []
    bar = tqdm(total=len(cells), desc=f"cells ({jobs} processes)", disable=not progress, file=sys.stderr)
    while todo:
        died = []
        with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn")) as pool:
            futures = {pool.submit(_execute, c, str(demo_cache) if demo_cache else None, threads,
                                   str(checkpoints) if checkpoints else None): c for c in todo}
            pending = set(futures)
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in finished:
                    cell = futures[fut]
                    try:
                        result = fut.result()
                    except BrokenProcessPool as exc:
                        died.append((cell, exc))
                        continue
                    except Exception as exc:
                        print(f"cell {cell.key} failed: {_error(exc)}", file=sys.stderr)
                        failures.append(CellFailure(cell, _error(exc)))
                        bar.update(1)
                        continue
                    done(cell, result)
                    bar.update(1)
        todo = []
        for cell, exc in died:
            attempts[id(cell)] += 1
            if attempts[id(cell)] > retries:
                failures.append(CellFailure(cell, f"worker died {attempts[id(cell)]} times ({_error(exc)})"))
                bar.update(1)
            else:
                print(f"worker of cell {cell.key} died; retrying", file=sys.stderr)
                todo.append(cell)
    bar.close()
    if failures:
        raise CellsFailed(failures)


def run_ray(cells: list[Any], done: Done, *, address: str | None, demo_cache: Path | None, progress: bool = True,
            checkpoints: Path | None = None,
            retries: int = 2) -> None:
    """Run every cell as a Ray task (``num_cpus`` = the cell's ``cpus``) and gather results here."""
    try:
        import ray
    except ImportError as exc:
        raise ValueError("--executor ray needs Ray: pip install -e '.[cluster]' in this checkout (the distribution "
                         "is lfd-suite) or pip install 'ray[default]'") from exc
    from tqdm import tqdm

    started = False
    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=progress)
        started = True
    try:
        remote = ray.remote(_execute)
        capacity = float(ray.cluster_resources().get("CPU", 0))
        refs, failures = {}, []
        for cell in cells:
            cpus = max(1, int(getattr(cell, "cpus", 1)))
            if cpus > capacity:  # Ray would queue it forever
                failures.append(CellFailure(cell, f"asks for {cpus} CPUs; the cluster has {capacity:g}"))
                continue
            ref = remote.options(num_cpus=cpus, max_retries=retries, retry_exceptions=False).remote(
                cell, str(demo_cache) if demo_cache else None, cpus, str(checkpoints) if checkpoints else None)
            refs[ref] = cell
        pending = list(refs)
        with tqdm(total=len(refs), desc="cells (ray)", disable=not progress, file=sys.stderr) as bar:
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                for ref in ready:
                    cell = refs[ref]
                    try:
                        result = ray.get(ref)
                    except Exception as exc:  # RayTaskError (cell raised) or WorkerCrashedError after retries
                        cause = getattr(exc, "cause", None) or exc
                        print(f"cell {cell.key} failed: {_error(cause)}", file=sys.stderr)
                        failures.append(CellFailure(cell, _error(cause)))
                    else:
                        done(cell, result)
                    bar.update(1)
    finally:
        if started:
            ray.shutdown()
    if failures:
        raise CellsFailed(failures)


def run_cells(cells: list[Any], done: Done, *, executor: str = "local", jobs: int = 1, address: str | None = None,
              demo_cache: Path | None = None, progress: bool = True, checkpoints: Path | None = None) -> None:
    """Dispatch to the executor named ``executor`` (module docstring); ``checkpoints`` is the root
    folder of the cells' checkpoints (:mod:`lfd_bench.checkpoints`; on a cluster, a folder every
    node can write, as ``--out`` is), None for none."""
    if executor not in EXECUTORS:
        raise ValueError(f"unknown executor {executor!r}; valid: {list(EXECUTORS)}")
    if jobs < 1:
        raise ValueError(f"--jobs must be >= 1, got {jobs}")
    if not cells:
        return
    if executor == "ray":
        run_ray(cells, done, address=address, demo_cache=demo_cache, progress=progress, checkpoints=checkpoints)
    elif jobs == 1:
        run_serial(cells, done, demo_cache=demo_cache, progress=progress, checkpoints=checkpoints)
    else:
        run_processes(cells, done, jobs=min(jobs, len(cells)), demo_cache=demo_cache, progress=progress,
                      checkpoints=checkpoints)
