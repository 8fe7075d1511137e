"""Warp set-up shared by the engine and the renderer.

Warp prints a banner, a CUDA-driver notice on machines without a GPU (from its native
library, straight to file descriptor 2), and one line per loaded kernel module. lfd keeps
that quiet unless ``LFD_WARP_VERBOSE=1`` is set (useful when a kernel compiles for the first
time). Later warnings and errors still show; a failed initialisation still raises.
"""

import contextlib
import os
import sys

import warp as wp


@contextlib.contextmanager
def _silenced_stderr_fd():
    """Redirect the process-level stderr (fd 2) to /dev/null inside the block."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real fd 2 (e.g. embedded interpreters)
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


if os.environ.get("LFD_WARP_VERBOSE", "") not in ("1", "true", "yes"):
    wp.config.log_level = wp.LOG_ERROR
    with _silenced_stderr_fd():
        wp.init()
    wp.config.log_level = wp.LOG_WARNING  # module-load lines are INFO; real warnings still show
