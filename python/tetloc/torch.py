"""``tetloc.torch``: point location and differentiable sampling on PyTorch tensors.

>>> import tetloc, tetloc.torch
>>> loc = tetloc.torch.Locator(tetloc.read("mesh.vtu"), device="cpu")
>>> ids = loc.locate(points)                  # (K, 3) tensor -> (K,) int32, -1 outside
>>> v = loc.sample(points, "f")               # a field of the mesh, NaN outside
>>> v = loc.sample(points, values)            # vertex values (n_points,) or (n_points, k)
>>> v.sum().backward()                        # gradients for `values` and `points`

``sample`` is a ``torch.autograd.Function``: the gradient with respect to the vertex values is
the transposed interpolation (the weights scattered into the cell's nodes), the gradient with
respect to the points is the interpolant's gradient in the cell (constant in a linear tet; the
cell's shape functions' gradients for other cells). Points outside get ``fill`` (NaN unless
given) and zero gradients.

The interpolation and both gradients run on the tensors' device. Ids come from one of two
paths (``Locator.path``):

- ``"zero-copy"``: CUDA tensors of float32 points on a mesh of linear tets, where the CUDA
  driver and the Vulkan extensions for sharing memory are there (``tetloc._tetloc.CudaLocator``):
  the points go from the tensor into Vulkan memory that CUDA imported, the soft-bvh kernel
  locates them there, and the ids come back into a tensor, all on the GPU, ordered on the
  current CUDA stream. For ``sample`` the kernel also writes each point's nodes and weights
  (its f32 barycentrics); the weights' gradients, for the points' gradient, are computed in
  torch only when the points require it.
- ``"host"``: everything else (CPU tensors, float64 points, other meshes, no driver): the
  locator answers on the host (any backend, as ``tetloc.Locator``); for CUDA tensors the
  points go to the host and the ids (and weights) come back.

Points and field values may be any DLPack array on the locator's device (CuPy, JAX, numpy
on the CPU: anything with ``__dlpack__``), taken with ``torch.from_dlpack`` without a copy;
the answers are torch tensors, which any DLPack consumer takes back the same way.

``host_copies()`` counts the host path's transfers (0 on the zero-copy path; tests hold it to
what they expect). Importing ``tetloc`` does not import torch; importing ``tetloc.torch`` does.
"""

from __future__ import annotations

import math
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np
import torch

from ._locator import Locator as _HostLocator
from ._mesh import Mesh
from . import _tetloc
from ._tetloc import interpolation_weights

_host_copies = 0


def host_copies() -> int:
    """Transfers between a CUDA device and the host made by this module so far (points down,
    ids and weights up): 0 while only CPU tensors are used."""
    return _host_copies


def _to_host(t: torch.Tensor) -> torch.Tensor:
    global _host_copies
    if t.device.type != "cpu":
        _host_copies += 1
        return t.cpu()
    return t


def _to_device(t: torch.Tensor, device: torch.device) -> torch.Tensor:
    global _host_copies
    if device.type != "cpu":
        _host_copies += 1
        return t.to(device, non_blocking=False)
    return t


def _from_dlpack(x: Any, arg: str) -> Any:
    """`x` as a torch tensor sharing its memory when it is a DLPack array that is not one
    already (CuPy, JAX, numpy); anything else as it is (the caller's checks name it)."""
    if isinstance(x, (torch.Tensor, str)) or not hasattr(x, "__dlpack__"):
        return x
    try:
        return torch.from_dlpack(x)
    except Exception as e:  # torch raises several types for arrays it cannot take
        raise TypeError(f"{arg}: cannot take this {type(x).__name__} through DLPack ({e})") from e


class _Weights:
    """Where the points are: ids, and the interpolation weights and their gradients per node."""

    def __init__(self, ids: torch.Tensor, nodes: torch.Tensor, weights: torch.Tensor, gradients: torch.Tensor,
                 inside: torch.Tensor) -> None:
        self.ids, self.nodes, self.weights, self.gradients, self.inside = ids, nodes, weights, gradients, inside


def _gather(field: torch.Tensor, nodes: torch.Tensor) -> torch.Tensor:
    """field[nodes]: (K, W, k) of field (n, k) at nodes (K, W), int32 or int64."""
    return field.index_select(0, nodes.reshape(-1)).view(*nodes.shape, field.shape[1])


def _finite_or_far(points: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor]:
    """Which points are finite, and the points with the others moved far outside: the kernel
    gets those, and their ids are set to -1 afterwards."""
    finite = torch.isfinite(points).all(1)
    return finite, torch.where(finite.unsqueeze(1), points, torch.full_like(points, 3.0e38)).contiguous()


def _gradients_of_rows(rows: torch.Tensor, inside: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """The barycentrics' gradients (K, 4, 3) from the rows of the inverse edge matrices
    (K, 3, 3): ∇b_j is row j, ∇b_0 minus their sum; 0 outside."""
    gradients = torch.cat([-rows.sum(1, keepdim=True), rows], dim=1)
    zero = torch.zeros((), dtype=rows.dtype, device=rows.device)
    return torch.where(inside.view(-1, 1, 1), gradients, zero).to(dtype)


class _Sample(torch.autograd.Function):
    """values = Σ_j w_j · field[node_j]; d/dfield: scatter-add of the weights; d/dpoints:
    Σ_j ∇w_j · field[node_j]."""

    @staticmethod
    def forward(ctx: Any, points: torch.Tensor, field: torch.Tensor, nodes: torch.Tensor, weights: torch.Tensor,
                gradients: torch.Tensor, inside: torch.Tensor, fill: float) -> torch.Tensor:
        # field: (n_points, k); out: (K, k). index_select takes int32 nodes as they come.
        out = (weights.unsqueeze(-1) * _gather(field, nodes)).sum(1)
        out = torch.where(inside.unsqueeze(-1), out, torch.full_like(out, fill))
        ctx.save_for_backward(field, nodes, weights, gradients, inside)
        return out

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx: Any, grad: torch.Tensor) -> Tuple[Optional[torch.Tensor], ...]:
        field, nodes, weights, gradients, inside = ctx.saved_tensors
        grad = torch.where(inside.unsqueeze(-1), grad, torch.zeros_like(grad))  # outside: no gradient
        grad_points = grad_field = None
        if ctx.needs_input_grad[0]:
            # ∂out_k/∂x_c = Σ_j ∇w_j[c] · field[node_j, k], contracted with grad over k.
            along = (_gather(field, nodes) * grad.unsqueeze(1)).sum(-1)  # (K, W)
            grad_points = (gradients * along.unsqueeze(-1)).sum(1)
            # Outside, a NaN field value at a padding node must not make 0 · NaN.
            grad_points = torch.where(inside.unsqueeze(-1), grad_points, torch.zeros_like(grad_points))
        if ctx.needs_input_grad[1]:
            spread = weights.unsqueeze(-1) * grad.unsqueeze(1)  # (K, W, k)
            grad_field = torch.zeros_like(field).index_add_(0, nodes.reshape(-1), spread.reshape(-1, field.shape[1]))
        return grad_points, grad_field, None, None, None, None, None


class Locator:
    """A ``tetloc.Locator`` for tensors on one torch device.

    Parameters
    ----------
    mesh : tetloc.Mesh or pyvista dataset
    device : str or torch.device
        Where the tensors live (``"cpu"``, ``"cuda:0"``): points must be there, and answers
        come back there.
    backend, vulkan_device, **options
        What ``tetloc.Locator`` takes (``backend="auto"``; ``vulkan_device`` is its ``device``,
        the Vulkan device index).
    zero_copy : bool, optional
        For a CUDA device: ``None`` (default) uses the zero-copy path where it is available
        (else the host path; ``zero_copy_error`` says why not), ``True`` requires it (raises
        ``tetloc.DeviceError`` when unavailable), ``False`` always uses the host path.
    """

    def __init__(self, mesh: Mesh, device: Union[str, torch.device] = "cpu", backend: str = "auto",
                 vulkan_device: Optional[int] = None, zero_copy: Optional[bool] = None, **options: Any) -> None:
        self.device = torch.device(device)
        if self.device.type == "cuda" and self.device.index is None:
            self.device = torch.device("cuda", torch.cuda.current_device())
        self._host = _HostLocator(mesh, backend=backend, device=vulkan_device, **options)
        #: Why a CUDA locator runs on the host path (``None`` on the zero-copy path or the CPU).
        self.zero_copy_error: Optional[str] = None
        self._cuda: Optional[_tetloc.CudaLocator] = None
        plain = not options and backend in ("auto", "soft-bvh")
        if self.device.type == "cuda" and zero_copy is not False and not plain:
            # The zero-copy path is the soft-bvh kernel as is: options (a tolerance, ...) and
            # other backends answer through the host path.
            self.zero_copy_error = f"backend {backend!r} with options {sorted(options)}: the host path answers"
            if zero_copy:
                raise ValueError(f"zero_copy=True: {self.zero_copy_error}; pass backend='auto' and no options")
        elif self.device.type == "cuda" and zero_copy is not False:
            try:
                assert self.device.index is not None
                self._cuda = _tetloc.CudaLocator(self.mesh._raw, self.device.index, vulkan_device)
            except _tetloc.DeviceError as e:
                if zero_copy:
                    raise
                self.zero_copy_error = str(e)
        self._fields: Dict[Tuple[str, torch.dtype], Tuple[torch.Tensor, bool, bool]] = {}
        # On a GPU, a mesh of linear tets keeps its tets and vertices there: the weights are
        # computed beside the points, and only the ids cross from the host.
        self._tets: Optional[torch.Tensor] = None
        self._vertices: Optional[torch.Tensor] = None
        linear_tets = self.mesh.n_cells == self.mesh.n_tets and bool((self.mesh.celltypes == 10).all())
        if self.device.type != "cpu" and linear_tets:
            self._tets = _to_device(torch.from_numpy(self.mesh.tets), self.device)
            self._vertices = _to_device(torch.from_numpy(self.mesh.points64), self.device)

    @property
    def mesh(self) -> Mesh:
        return self._host.mesh

    @property
    def path(self) -> str:
        """``"zero-copy"`` when float32 points of this CUDA device are located on the GPU
        without host copies, else ``"host"`` (see the module's documentation)."""
        return "zero-copy" if self._cuda is not None else "host"

    @property
    def backend(self) -> str:
        """The backend that locates (``tetloc.Locator.backend``)."""
        return self._host.backend

    def _check_points(self, points: Any) -> torch.Tensor:
        points = _from_dlpack(points, "points")
        if not isinstance(points, torch.Tensor):
            raise TypeError(
                f"points: expected a torch.Tensor (or a DLPack array) of shape (K, 3), got {type(points).__name__}"
            )
        if points.device != self.device:
            raise ValueError(f"points: on {points.device}, but this Locator is on {self.device} (move them with .to())")
        if points.dtype not in (torch.float32, torch.float64):
            raise TypeError(f"points: dtype {points.dtype}; expected torch.float32 or torch.float64")
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points: shape {tuple(points.shape)}; expected (K, 3)")
        if not points.is_contiguous():
            raise ValueError("points: not contiguous; pass points.contiguous()")
        return points

    def _locate(self, host: torch.Tensor) -> torch.Tensor:
        """int32 ids on the host of points on the host."""
        return torch.from_numpy(self._host.locate(host.numpy()))

    def _locate_cuda(self, points: torch.Tensor) -> torch.Tensor:
        """int32 ids on this CUDA device of float32 points there: the zero-copy path."""
        assert self._cuda is not None
        finite, safe = _finite_or_far(points)
        ids = torch.empty(points.shape[0], dtype=torch.int32, device=self.device)
        stream = torch.cuda.current_stream(self.device).cuda_stream
        self._cuda.locate(safe.data_ptr(), points.shape[0], ids.data_ptr(), stream)
        return ids.masked_fill_(~finite, -1)

    def _ids(self, points: torch.Tensor) -> torch.Tensor:
        """int32 ids on this device of points checked by `_check_points`."""
        if self._cuda is not None and points.dtype == torch.float32:
            return self._locate_cuda(points.detach())
        return _to_device(self._locate(_to_host(points.detach())), self.device)

    def locate(self, points: torch.Tensor) -> torch.Tensor:
        """Ids of the cells containing `points` ((K, 3) float32 or float64 on this device), -1
        outside: (K,) int32 on this device."""
        return self._ids(self._check_points(points))

    def _weights(self, points: torch.Tensor, dtype: torch.dtype, gradients: bool) -> _Weights:
        """Where `points` are and how values are interpolated there; the weights' gradients
        (for the points' gradient) only when `gradients` (else an empty tensor)."""
        if self._cuda is not None and points.dtype == torch.float32:
            return self._cuda_weights(points.detach(), dtype, gradients)
        if self._tets is not None:
            return self._tet_weights(points, self._ids(points), dtype, gradients)
        host = _to_host(points.detach())
        ids = self._locate(host)
        host64 = host.to(torch.float64).numpy()
        nodes, weights, grads, found = interpolation_weights(self.mesh._raw, host64, ids.numpy())
        arrays = [torch.from_numpy(a) for a in (nodes, weights, grads, found)]
        arrays[1], arrays[2] = arrays[1].to(dtype), arrays[2].to(dtype)
        nodes_t, weights_t, gradients_t, found_t = (_to_device(a, self.device) for a in arrays)
        return _Weights(ids, nodes_t, weights_t, gradients_t, found_t)

    def _cuda_weights(self, points: torch.Tensor, dtype: torch.dtype, gradients: bool) -> _Weights:
        """The zero-copy path's weights: the kernel writes each point's id, its tet's nodes and
        their weights (its f32 barycentrics, those its own values use) beside the points."""
        assert self._cuda is not None
        n = points.shape[0]
        finite, safe = _finite_or_far(points)
        ids = torch.empty(n, dtype=torch.int32, device=self.device)
        nodes = torch.empty((n, 4), dtype=torch.int32, device=self.device)
        weights = torch.empty((n, 4), dtype=torch.float32, device=self.device)
        stream = torch.cuda.current_stream(self.device).cuda_stream
        self._cuda.weights(safe.data_ptr(), n, ids.data_ptr(), nodes.data_ptr(), weights.data_ptr(), stream)
        ids.masked_fill_(~finite, -1)
        inside = ids >= 0
        weights = weights.to(dtype)
        if gradients:
            grads = self._tet_gradients(nodes, inside, dtype)
        else:
            grads = torch.empty(0, dtype=dtype, device=self.device)
        return _Weights(ids, nodes, weights, grads, inside)

    def _edge_rows(self, nodes: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor]:
        """The corners x (K, 4, 3) of linear tets `nodes` (f64, the file's vertices) and the
        rows of the inverse of their edge matrices [e1 e2 e3] (K, 3, 3): r_i · e_j = δ_ij."""
        assert self._vertices is not None
        x = self._vertices[nodes.long()]  # (K, 4, 3)
        e1, e2, e3 = (x[:, j] - x[:, 0] for j in (1, 2, 3))
        n1, n2, n3 = torch.linalg.cross(e2, e3), torch.linalg.cross(e3, e1), torch.linalg.cross(e1, e2)
        det = (e1 * n1).sum(1, keepdim=True)
        det = torch.where(det == 0, torch.ones_like(det), det)  # zero-volume tets hold no point
        return x, torch.stack([n1, n2, n3], dim=1) / det.unsqueeze(-1)

    def _tet_gradients(self, nodes: torch.Tensor, inside: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
        """The weights' gradients in linear tets `nodes` (K, 4, 3); 0 outside."""
        return _gradients_of_rows(self._edge_rows(nodes)[1], inside, dtype)

    def _tet_weights(self, points: torch.Tensor, ids: torch.Tensor, dtype: torch.dtype, gradients: bool) -> _Weights:
        """Barycentric weights in linear tets, on the points' device: those of
        ``tetloc_core::geom::bary64`` (f64, on the file's vertices, clamped to 0 and
        normalised), and (when `gradients`) their gradients."""
        assert self._tets is not None
        inside = ids >= 0
        nodes = self._tets[ids.clamp(min=0).long()]  # (K, 4)
        x, rows = self._edge_rows(nodes)
        b = (rows * (points.detach().to(torch.float64) - x[:, 0]).unsqueeze(1)).sum(-1)
        weights = torch.cat([1 - b.sum(1, keepdim=True), b], dim=1).clamp(min=0)
        weights = weights / weights.sum(1, keepdim=True)
        zero = torch.zeros((), dtype=torch.float64, device=points.device)
        weights = torch.where(inside.unsqueeze(-1), weights, zero)
        if gradients:
            grads = _gradients_of_rows(rows, inside, dtype)
        else:
            grads = torch.empty(0, dtype=dtype, device=points.device)
        return _Weights(ids, nodes, weights.to(dtype), grads, inside)

    def _mesh_field(self, name: str, dtype: torch.dtype) -> Tuple[torch.Tensor, bool, bool]:
        """Field `name` on this device as (values (n, k), per point?, scalar?), kept between
        calls."""
        key = (name, dtype)
        if key not in self._fields:
            _, k = self.mesh._index.components(name)
            values = torch.from_numpy(np.ascontiguousarray(self.mesh.field(name))).to(dtype)
            values = _to_device(values.reshape(values.shape[0], -1), self.device)
            self._fields[key] = (values, name in self.mesh.point_data, k is None)
        return self._fields[key]

    def _check_field(self, field: torch.Tensor) -> torch.Tensor:
        n = self.mesh.n_points
        if field.device != self.device:
            raise ValueError(f"field: on {field.device}, but this Locator is on {self.device} (move it with .to())")
        if field.dtype not in (torch.float32, torch.float64):
            raise TypeError(f"field: dtype {field.dtype}; expected torch.float32 or torch.float64")
        if field.ndim not in (1, 2) or field.shape[0] != n:
            raise ValueError(
                f"field: shape {tuple(field.shape)}; expected vertex values ({n},) or ({n}, k) "
                f"for this mesh's {n} points"
            )
        if not field.is_contiguous():
            raise ValueError("field: not contiguous; pass field.contiguous()")
        return field

    def sample(self, points: torch.Tensor, field: Union[str, torch.Tensor], fill: float = math.nan) -> torch.Tensor:
        """Values of `field` at `points` ((K, 3) float32 or float64 on this device): (K,) for a
        scalar field, (K, k) for a k-component one; `fill` (NaN) outside.

        `field` is the name of a field of the mesh (point fields are interpolated, cell fields
        are constant in each cell) or a tensor of vertex values on this device, (n_points,) or
        (n_points, k), float32 or float64. Values are in the wider dtype of the points and the
        field. Differentiable with respect to the points and a field tensor."""
        points = self._check_points(points)
        field = _from_dlpack(field, "field")
        if isinstance(field, str):
            values, per_point, scalar = self._mesh_field(field, points.dtype)
        elif isinstance(field, torch.Tensor):
            values, per_point = self._check_field(field), True
            scalar = field.ndim == 1
        else:
            raise TypeError(f"field: expected a field name or a torch.Tensor, got {type(field).__name__}")
        dtype = torch.promote_types(points.dtype, values.dtype)
        values = values.reshape(values.shape[0], -1).to(dtype)
        if per_point:
            # The points' gradient needs the weights' gradients; most callers (fitting values)
            # do not ask for it.
            w = self._weights(points, dtype, gradients=points.requires_grad and torch.is_grad_enabled())
            out: torch.Tensor = _Sample.apply(points, values, w.nodes, w.weights, w.gradients, w.inside, float(fill))
        else:
            ids = self._ids(points).to(torch.int64)
            outside = torch.full((1,), fill, dtype=dtype, device=self.device)
            out = torch.where((ids >= 0).unsqueeze(-1), values[ids.clamp(min=0)], outside)
        return out[:, 0] if scalar else out

    def __repr__(self) -> str:
        return (f"tetloc.torch.Locator(device={str(self.device)!r}, backend={self.backend!r}, "
                f"path={self.path!r}, {self.mesh!r})")


__all__ = ["Locator", "host_copies"]
