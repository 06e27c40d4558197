"""``tetloc.StepWeights``: locate once, interpolate many time steps (``Locator.step_weights``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable, Optional, Tuple

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ._mesh import Mesh
    from ._tetloc import _StepWeights

#: Bytes of one batch of steps' values read and applied together (bounded memory for any
#: number of steps; the GPU gets one upload and one dispatch a batch).
BATCH_BYTES = 256 << 20


class StepWeights:
    """The interpolation weights of fixed points, made once by ``Locator.step_weights(points)``
    and applied to any number of time steps of a point field: ``apply`` takes steps held in
    memory, ``sample`` reads the mesh's steps from its file. On a GPU locator the weights live
    on its device and the steps are interpolated there, a batch of steps an upload; on
    ``cpu`` they run on the host's cores. Values come back as float32 (summed in float64: the
    same bits on the host and on a device with float64), NaN for points outside the mesh.
    ``matrix`` is the same map as ``Locator.weights``' ``scipy.sparse.csr_matrix``.
    Cell fields need no weights: ``sample`` indexes them by each point's cell (``cells``)."""

    def __init__(self, raw: _StepWeights, mesh: Mesh) -> None:
        self._raw = raw
        self._mesh = mesh

    @property
    def device(self) -> str:
        """Where ``apply`` runs: ``"cpu"`` or the Vulkan device's name."""
        return self._raw.device

    @property
    def n_points(self) -> int:
        return self._raw.n_points

    @property
    def cells(self) -> npt.NDArray[np.int32]:
        """Each point's cell id, -1 outside."""
        return self._raw.cells()

    @property
    def matrix(self) -> Any:
        """The weights as a ``scipy.sparse.csr_matrix`` of shape (n_points, mesh.n_points)."""
        import scipy.sparse

        indptr, indices, data = self._raw.csr()
        return scipy.sparse.csr_matrix((data, indices, indptr), shape=(self.n_points, self._mesh.n_points))

    def apply(self, values: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """One step or many of a point field at the points. `values`: (S, n_vertices) or
        (S, n_vertices, k) for S steps, step first: (S, n_points) or (S, n_points, k) float32.
        For one step, pass ``values[None]`` and take ``[0]``."""
        v = np.asarray(values)
        if v.dtype.kind not in "biuf":
            # (Complex values would lose their imaginary parts, objects and text fail late.)
            raise TypeError(f"values: expected real numbers, got dtype {v.dtype}")
        if v.ndim not in (2, 3) or v.shape[1] != self._mesh.n_points:
            raise ValueError(
                f"values: shape {v.shape}; expected (steps, {self._mesh.n_points}) or "
                f"(steps, {self._mesh.n_points}, components): the steps of a point field"
            )
        if v.shape[0] == 0 and (v.ndim == 2 or v.shape[2] > 0):
            return np.empty((0, self.n_points) + v.shape[2:], np.float32)  # no step: nothing to apply
        three = np.ascontiguousarray(v.reshape(v.shape[0], v.shape[1], -1), dtype=np.float32)
        out = self._raw.apply(three)
        return out[:, :, 0] if v.ndim == 2 else out

    def sample(self, name: str, steps: Optional[Iterable[int]] = None) -> npt.NDArray[np.float32]:
        """Field `name` at the points at each of `steps` (indices into ``mesh.times``; every
        step when None, or the mesh's one snapshot), read from the file a batch of steps at a
        time: (S, n_points) for a scalar field, (S, n_points, k) for k components, float32,
        NaN outside. A step out of range is a ``ValueError``."""
        mesh = self._mesh
        snapshot = steps is None and not mesh.times
        wanted = [0] if snapshot else list(range(len(mesh.times))) if steps is None else list(steps)

        def read(step: int) -> npt.NDArray[Any]:
            return mesh.field(name) if snapshot else mesh.field(name, step=step)

        comps = mesh.field(name).shape[1:]
        out = np.empty((len(wanted), self.n_points) + comps, dtype=np.float32)
        if mesh.field_location(name) != "point":
            cells = self.cells
            for i, s in enumerate(wanted):
                out[i] = read(s)[np.maximum(cells, 0)]
                out[i][cells < 0] = np.nan
            return out
        per_step = max(1, mesh.n_points * int(np.prod(comps, dtype=np.int64)) * 4)
        batch = max(1, BATCH_BYTES // per_step)
        for start in range(0, len(wanted), batch):
            group = wanted[start : start + batch]
            out[start : start + len(group)] = self.apply(np.stack([read(s) for s in group]))
        return out

    def __repr__(self) -> str:
        shape: Tuple[int, int] = (self.n_points, self._mesh.n_points)
        return f"<tetloc.StepWeights {shape[0]} points over {shape[1]} vertices on {self.device}>"
