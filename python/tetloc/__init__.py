"""tetloc: which cell of this unstructured mesh (tets, hexahedra, wedges, pyramids, their
higher-order kinds, mixed) contains this point, and what is the field value there? On GPUs
(Vulkan) and CPUs.

>>> import tetloc
>>> mesh = tetloc.read("mesh.vtu")                    # .vtu, .pvtu, .vtm, .vtk, .msh, .node/.ele
>>> loc = tetloc.Locator(mesh)                         # backend="auto": the fastest here, as the CLI
>>> ids = loc.locate(points)                           # (K, 3) -> (K,) int32, -1 outside
>>> f = loc.sample(points, "f")                        # float32, NaN outside

``resample_to_image``, ``probe`` and ``trace`` are ParaView's Resample To Image, Resample With
Dataset and Stream Tracer (numpy or pyvista out).
``Mesh.from_pyvista``, ``Mesh.to_pyvista``, ``Mesh.from_meshio`` and ``Mesh.to_meshio``
convert meshes (cells as pyvista has them: ``cells``, ``celltypes``, ``offsets``; the tets
located in: ``tets``);
``devices()`` lists the Vulkan devices. Errors: ``FileNotFoundError`` (``OSError``),
``ValueError`` naming the file or argument, ``TypeError`` for an argument of the wrong
kind, ``DeviceError`` for the GPU.
``tetloc.torch`` (imported on its own: ``import tetloc`` does not import torch) locates and
samples PyTorch tensors, differentiably.
"""

from ._locator import Locator
from ._mesh import Mesh, read
from ._ops import REASONS, probe, resample_to_image, trace
from ._steps import StepWeights
from ._tetloc import BACKENDS, DeviceError, __version__
from ._tetloc import devices as _devices
from ._typing import LocatorOptions
from ._view import Viewer, view

from typing import Any, Dict, List


def devices() -> List[Dict[str, Any]]:
    """The Vulkan devices: one dict each with ``index`` (for ``Locator(device=...)``),
    ``name``, ``driver``, ``device_type`` ("discrete", "integrated", "virtual", "cpu",
    "other"), ``api_version``, ``ray_tracing``, ``memory_bytes``, ``float64`` and
    ``backends`` (the GPU backends it runs). Empty when there is no Vulkan loader or device;
    the ``cpu`` backend works everywhere."""
    return _devices()


__all__ = [
    "BACKENDS",
    "DeviceError",
    "Locator",
    "LocatorOptions",
    "Mesh",
    "REASONS",
    "StepWeights",
    "__version__",
    "devices",
    "probe",
    "read",
    "resample_to_image",
    "trace",
    "view",
    "Viewer",
]
