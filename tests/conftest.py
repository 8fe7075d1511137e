import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, os.path.dirname(__file__))


import pytest


@pytest.fixture
def one_torch_thread():
    """One torch thread: tiny networks run several times faster than with threads fighting for
    two shared cores."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
