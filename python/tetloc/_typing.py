"""The types of tetloc's public API, for type checkers (the package ships ``py.typed``):
what points, progress callbacks and meshes may be, and the keyword options of ``Locator``.
Room is left for more: a ``tetloc.torch`` module or time-series arguments add their own
aliases here."""

from __future__ import annotations

from typing import Any, Callable, Literal, Optional, Protocol, TypedDict, Union

import numpy.typing as npt


class SupportsDLPack(Protocol):
    """An array that numpy can take over without a copy (``numpy.from_dlpack``): CPU tensors
    of torch, JAX, CuPy's host arrays, ..."""

    def __dlpack__(self, *args: Any, **kwargs: Any) -> Any: ...


#: Query points: anything of shape (K, 3) or (..., 3) that numpy reads (arrays, nested lists,
#: objects with ``__array__``), or a DLPack tensor. float32 and float64 (integers as float64).
PointsLike = Union[npt.ArrayLike, SupportsDLPack]

#: ``progress(stage, fraction or None, seconds)``: called during long builds and batches.
Progress = Callable[[str, Optional[float], float], None]

#: ``progress=``: ``True`` for a bar on stderr, ``False``/``None`` for none, or a callable.
ProgressArg = Union[bool, None, Progress]

#: A ``tetloc.Mesh``, or a pyvista dataset (converted with ``Mesh.from_pyvista``); pyvista is
#: optional, so its datasets are typed as ``Any``.
MeshLike = Any

#: The backends ``Locator`` takes (also as a plain ``str``: ``tetloc.BACKENDS`` lists them).
BackendName = Literal["auto", "cpu", "soft-bvh", "rt-bvh", "rt-rep-faces", "rt-shared-faces"]


class LocatorOptions(TypedDict, total=False):
    """The keyword options of ``tetloc.Locator`` past ``backend`` and ``device`` (what the
    extension's ``_Locator`` parses; an unknown one raises ``TypeError``). Every key may be
    left out::

        opts: tetloc.LocatorOptions = {"tolerance": "1%", "precision": "f64"}
        loc = tetloc.Locator(mesh, "cpu", **opts)
    """

    #: A bar on stderr (``True``) or a callable ``progress(stage, fraction or None, seconds)``.
    progress: ProgressArg
    #: Points outside but within this distance of the boundary get the nearest boundary cell:
    #: a distance in mesh units, or a string such as ``"1%"`` (of the mean edge length).
    tolerance: Union[float, str]
    #: rt kernels: primitives per bottom-level acceleration structure; ``None``: one structure.
    split: Optional[int]
    #: rt kernels: compact the acceleration structures.
    compact: bool
    #: ``"f64"``: float64 points get float64 values computed on the host.
    precision: Literal["f32", "f64"]
    #: cpu: build the search when a call first needs it.
    deferred: bool


__all__ = ["BackendName", "LocatorOptions", "MeshLike", "PointsLike", "Progress", "ProgressArg", "SupportsDLPack"]
