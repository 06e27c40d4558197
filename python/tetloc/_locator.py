"""``tetloc.Locator``: which cell holds each point, and the field values there."""

from __future__ import annotations

import sys
import warnings
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

from . import _fields
from ._mesh import Mesh
from ._points import as_points, as_points64
from ._progress import ProgressBar
from ._steps import StepWeights
from ._tetloc import _Locator
from ._typing import LocatorOptions, MeshLike, PointsLike, Progress

if TYPE_CHECKING:
    from typing_extensions import Unpack  # typing.Unpack from Python 3.11

#: Values: float32, or float64 for float64 points on float64 data or with precision="f64".
Values = npt.NDArray[np.floating[Any]]


class Locator:
    """A search structure over a mesh on one backend, answering batches of points. Answers
    are the mesh's cells (of any type: a point in a hexahedron gets the hexahedron's id and
    its values), located through the cells' tets (``Mesh.tets``).

    Parameters
    ----------
    mesh : Mesh or pyvista dataset
        A ``tetloc.Mesh``, or a pyvista dataset (converted with ``Mesh.from_pyvista``).
    backend : str
        ``"auto"`` (as the CLI's: ``cpu`` when there is no Vulkan device or only a CPU Vulkan
        driver such as lavapipe; else the fastest backend in a measurement of at most 2 s the
        first time, cached per device and driver in ``~/.cache/tetloc``), ``"cpu"``, or a
        Vulkan kernel: ``"soft-bvh"``, ``"rt-bvh"``,
        ``"rt-rep-faces"``, ``"rt-shared-faces"``. A Vulkan kernel without a usable device
        raises ``tetloc.DeviceError``.
    device : int, optional
        Vulkan device index (see ``tetloc.devices()``); the best device when omitted.
    **options : LocatorOptions
        ``progress=True``: show a progress bar on stderr during long builds and batches (or a
        callable, called as ``progress(stage, fraction or None, seconds)``).
        ``tolerance``: points outside the mesh but within this distance of its boundary get
        the nearest boundary cell and the value at the closest boundary point, as VTK's probe
        filter does with its tolerance: a distance in mesh units, or a string such as
        ``"1%"`` (of the mean edge length); default 0, exact.
        ``split`` (rt kernels: primitives per bottom-level acceleration structure, or None
        for one structure; default 1M), ``compact`` (rt kernels: compact the structures;
        default True). ``precision``: ``"f32"`` (default) or ``"f64"``: with ``"f64"``, float64
        points get float64 values computed on the host in float64 from the backend's cells
        (the CPU's values, bit for bit, on every backend); a bad value raises ``ValueError``.
        ``deferred=True`` (cpu): build the search (BVH, face neighbours) when a call first
        needs it, not now: ``resample_to_image`` on the CPU rasterizes the tets and needs it
        only for grid points on faces (the tie rule), and ``probe``'s batches build their
        bins and the face neighbours, the BVH only for points on faces; other backends
        ignore it.
        Unknown options raise ``TypeError``.

    Points are any array-like of shape (K, 3) (or (..., 3)), float32 or float64, C or
    Fortran order, including CPU tensors (DLPack or ``__array__``). float32 points are
    located as they are (a C-contiguous array without a copy). On a mesh with float64
    coordinates (or far from the origin) float64 points keep their precision: exact decisions
    on the mesh's float64 coordinates on the CPU; on the GPU the kernels search the mesh's
    working frame, centred on meshes far from the origin, and each answer is checked exactly
    on the host. On float32 meshes near the origin they are rounded to float32 (the fast path),
    unless a field has float64 data or ``precision="f64"``. Values of float64 points are
    float64 when the field has float64 data (interpolated in float64 on the CPU; the GPU
    kernels' float32 values unless ``precision="f64"``) or with ``precision="f64"``; else
    float32, as for float32 points. Results have the points'
    leading shape. A point with a NaN or infinite coordinate (or beyond float32 range) is
    answered -1 and NaN, as pyvista does, with a ``RuntimeWarning`` counting them. A point on a face shared by two cells gets one of them, always the same
    for a backend. Calls release the GIL (a Locator may be used from several threads; calls
    on one Locator run one at a time) and can be interrupted with Ctrl-C.
    """

    _mesh: Mesh

    def __init__(
        self, mesh: MeshLike, backend: str = "auto", device: Optional[int] = None, **options: Unpack[LocatorOptions]
    ) -> None:
        if not isinstance(mesh, Mesh):
            pv = sys.modules.get("pyvista")
            if pv is None or not isinstance(mesh, pv.DataSet):
                raise TypeError(f"mesh: expected a tetloc.Mesh or a pyvista dataset, got {type(mesh).__name__}")
            mesh = Mesh.from_pyvista(mesh)
        given = options.pop("progress", False)
        progress: Optional[Progress]
        if given is True:
            progress = ProgressBar(f"tetloc {backend}")
        elif given is False or given is None:
            progress = None
        elif callable(given):
            progress = given
        else:
            raise TypeError(f"progress: expected True, False or a callable, got {type(given).__name__}")
        self._mesh = mesh
        self._raw = _Locator(mesh._raw, backend, device, dict(options), progress)
        if self._raw.auto_note:
            warnings.warn(self._raw.auto_note, RuntimeWarning, stacklevel=2)

    @property
    def backend(self) -> str:
        """The backend in use: ``"cpu"``, ``"soft-bvh"``, ... (what ``"auto"`` chose)."""
        return self._raw.backend

    @property
    def stack(self) -> List[str]:
        """The backend and the layers around it, innermost first, e.g. ``["cpu",
        "FiniteOnly", "CellLocator", "WithTolerance"]``: what every front end builds for the
        same options (``TETLOC_EXPLAIN=1 tetloc locate ...`` says it for the CLI)."""
        return self._raw.stack

    @property
    def mesh(self) -> Mesh:
        """The mesh this locator answers for."""
        return self._mesh

    @property
    def build_seconds(self) -> float:
        """Seconds the build took."""
        return self._raw.build_seconds

    def memory(self) -> Dict[str, Any]:
        """Memory of the locator: ``{"on": "device" or "host", "final_bytes": ...,
        "peak_bytes": ..., "items": {name: bytes}}``. Final: resident after the build (mesh
        and search structure); peak: most memory alive at once during the build (GPU: device
        memory tracked by the backend; cpu: the extension's heap, measured)."""
        return self._raw.memory()

    def _sample64(
        self, points: PointsLike, comps: List[str]
    ) -> Optional[Tuple[npt.NDArray[np.int32], Values, Tuple[int, ...]]]:
        """float64 points at their precision: (ids, values (K, len(comps)), leading shape),
        or None for other points."""
        if not self._raw.takes_f64:
            return None
        p64 = as_points64(points)
        if p64 is None:
            return None
        flat, lead = p64
        # Beyond float32's range is beyond every mesh (whose float32 copy is finite).
        bad = int((~(np.abs(flat) <= np.finfo(np.float32).max)).any(axis=1).sum())
        if bad:
            warnings.warn(
                f"points: {bad} of {len(flat)} points have a NaN or infinite coordinate (or one beyond float32 range); "
                "they are answered -1 (and NaN values)",
                RuntimeWarning,
                stacklevel=3,
            )
        ids, values64 = self._raw.sample_many64(flat, comps)
        # float64 values where they carry more than float32 (precision="f64", or f64 data).
        values: Values = values64 if any(self._raw.values_f64(c) for c in comps) else values64.astype(np.float32)
        return ids, values, lead

    def locate(self, points: PointsLike) -> npt.NDArray[np.int32]:
        """Ids of the cells containing `points` (0-based, the mesh's cell order, not its
        ``tets``), -1 outside: an int32 array of the points' leading shape."""
        got = self._sample64(points, [])
        if got is not None:
            return got[0].reshape(got[2])
        flat, lead = as_points(points)
        return self._raw.locate(flat).reshape(lead)

    def sample(self, points: PointsLike, name: str, step: Optional[int] = None) -> Values:
        """Values of field `name` at `points`, NaN outside: float32 (float64 for float64 points
        on a float64 field or with ``precision="f64"``), shape (K,) for a scalar
        field, (K, k) for a k-component field. Point fields are interpolated with the cell's
        shape functions (barycentric in linear tets), cell fields are constant in each cell.
        (A k-component field is sampled one component at a time for now.)

        With `step` (an index into ``mesh.times``), the values of that time step, read from
        the file now: the points are located and their weights applied to the step's values
        (``weights``), in float64, returned as float64 for float64 data, else float32. To
        sample many steps at the same points, use ``step_weights(points)`` (on the GPU for a
        GPU backend), or build ``W = weights(points)`` once and apply it to each
        ``mesh.field(name, step=k)``."""
        if step is not None:
            return self._sample_step(points, name, step)
        comps, k = self._mesh._index.components(name)
        got = self._sample64(points, comps)
        if got is not None:
            _, values, lead = got
            values = values[:, 0] if k is None else values
            return values.reshape(lead + values.shape[1:])
        flat, lead = as_points(points)
        values = _fields.join([self._raw.sample(flat, c) for c in comps], k)
        return values.reshape(lead + values.shape[1:])

    def weights(self, points: PointsLike) -> Any:
        """The interpolation weights of `points`: a ``scipy.sparse.csr_matrix`` of shape
        (K, mesh.n_points), row i holding the weights of point i's cell (barycentrics in a
        linear tet, the cell's own shape functions on all its nodes for other cells and higher
        orders), so that ``W @ mesh.field(name)`` equals ``sample(points, name)`` for a point
        field, to rounding, at any time step: locate once, interpolate many. A point outside
        the mesh has an empty row (``W @ f`` gives 0 there, where ``sample`` gives NaN; the
        row's emptiness, ``W.getnnz(axis=1) == 0``, or ``locate``'s -1 tells them apart).
        Cell fields need no weights: index them with ``locate(points)``'s cell ids. Points
        are located as ``locate`` locates them (float64 points at their precision where
        ``locate`` keeps it). (K, 3) only; needs scipy."""
        import scipy.sparse

        indptr, indices, data, _ = self._weights(points)
        return scipy.sparse.csr_matrix((data, indices, indptr), shape=(len(indptr) - 1, self._mesh.n_points))

    def step_weights(self, points: PointsLike) -> StepWeights:
        """The weights of `points` (located once, as ``weights`` locates them) as a
        ``StepWeights``, ready to interpolate any number of time steps at those points:
        ``step_weights(points).sample("f")`` gives every step of ``f``, ``apply(values)``
        steps held in memory. On a GPU backend the weights stay on the device and each batch
        of steps is interpolated there. (K, 3) only."""
        return StepWeights(self._raw.step_weights(_rows64(points, "step_weights")), self._mesh)

    def _weights(
        self, points: PointsLike
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int32], npt.NDArray[np.float64], npt.NDArray[np.int32]]:
        return self._raw.weights(_rows64(points, "weights"))

    def _sample_step(self, points: PointsLike, name: str, step: int) -> Values:
        values = self._mesh.field(name, step=step)
        flat, lead = as_points(points)
        p64 = as_points64(points)
        p = np.ascontiguousarray(p64[0] if p64 is not None else flat, dtype=np.float64)
        indptr, indices, data, cells = self._raw.weights(p)
        v = values.reshape(values.shape[0], -1).astype(np.float64)
        if self._mesh.field_location(name) == "point":
            import scipy.sparse

            W = scipy.sparse.csr_matrix((data, indices, indptr), shape=(len(cells), self._mesh.n_points))
            out = np.asarray(W @ v)
        else:
            out = v[np.maximum(cells, 0)]
        out[cells < 0] = np.nan
        out = out.astype(np.float64 if values.dtype.kind == "f" and values.dtype.itemsize == 8 else np.float32)
        out = out[:, 0] if values.ndim == 1 else out
        return out.reshape(lead + out.shape[1:])

    def locate_and_sample(self, points: PointsLike, name: str) -> Tuple[npt.NDArray[np.int32], Values]:
        """``(locate(points), sample(points, name))`` in one pass (per component)."""
        comps, k = self._mesh._index.components(name)
        got = self._sample64(points, comps)
        if got is not None:
            ids, values, lead = got
            values = values[:, 0] if k is None else values
            return ids.reshape(lead), values.reshape(lead + values.shape[1:])
        flat, lead = as_points(points)
        ids, first = self._raw.locate_and_sample(flat, comps[0])
        values = _fields.join([first] + [self._raw.sample(flat, c) for c in comps[1:]], k)
        return ids.reshape(lead), values.reshape(lead + values.shape[1:])

    def __repr__(self) -> str:
        return f"tetloc.Locator(backend={self.backend!r}, {self._mesh!r})"


def _rows64(points: PointsLike, what: str) -> npt.NDArray[np.float64]:
    """(K, 3) points as C-contiguous float64 at their own precision, for `what` (weights are
    computed at the points as ``locate`` takes them); other shapes are a ValueError."""
    flat, lead = as_points(points)
    if len(lead) != 1:
        raise ValueError(f"points: shape {lead + (3,)}; {what} take (K, 3) points")
    p64 = as_points64(points)
    p = p64[0] if p64 is not None else np.asarray(flat, dtype=np.float64)
    return np.ascontiguousarray(p, dtype=np.float64)
