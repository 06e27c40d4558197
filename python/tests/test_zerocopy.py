"""The zero-copy path of ``tetloc.torch`` where this machine can check it (CI has no CUDA):
without a CUDA driver the path is refused with a clear error and ``tetloc.torch`` stays on the
host path; CPU tensors always take the host path. The CUDA checks are
python/tests/cuda_zerocopy.py (scripts/h200/zerocopy.sh)."""

from __future__ import annotations

import pytest
from conftest import in_ci

import tetloc
import tetloc._tetloc as native

try:
    import torch
except ImportError:
    if in_ci():
        raise
    pytest.skip("no torch (pip install torch)", allow_module_level=True)
import tetloc.torch as tt  # noqa: E402


def test_cpu_tensors_take_the_host_path(grid_mesh):
    loc = tt.Locator(grid_mesh, device="cpu", backend="cpu")
    assert loc.path == "host" and loc.zero_copy_error is None
    assert "path='host'" in repr(loc)
    before = tt.host_copies()
    ids = loc.locate(torch.tensor([[0.5, 0.5, 0.5], [9.0, 9.0, 9.0]]))
    assert ids[0] >= 0 and ids[1] == -1
    assert tt.host_copies() == before


def test_without_a_cuda_driver_the_zero_copy_path_is_refused_clearly(grid_mesh):
    if native.cuda_driver_available():
        pytest.skip("a CUDA driver is installed here: scripts/h200/zerocopy.sh checks the path")
    with pytest.raises(tetloc.DeviceError, match="^CUDA driver not found"):
        native.CudaLocator(grid_mesh._raw, 0)
