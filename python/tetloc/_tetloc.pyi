"""Types of the extension module; the public API is in tetloc/__init__.py. `stubtest`
(scripts/test.sh) holds this file to the built extension: every name, parameter and default.
Other modules (a time series' `Mesh.times`, `tetloc.torch`) add theirs here as they come."""

from typing import Any, Callable, Dict, List, Optional, Tuple, Union, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "_Mesh",
    "_Locator",
    "read_mesh",
    "devices",
    "validation_errors",
    "vtk_cell_types",
    "gmsh_cell_type",
    "resample_to_image",
    "probe",
    "trace",
    "resolve",
    "interpolation_weights",
    "_StepWeights",
    "CudaLocator",
    "cuda_driver_available",
    "DeviceError",
    "BACKENDS",
    "__version__",
]

__version__: str
BACKENDS: List[str]

class DeviceError(RuntimeError):
    """A GPU (Vulkan) backend cannot be used."""

_Progress = Callable[[str, Optional[float], float], None]

@final
class _Mesh:
    # `connectivity`: linear tets, 4 ids each, without `celltypes`; else a VTK cell list
    # (cell i: celltypes[i], ids connectivity[offsets[i]:offsets[i + 1]]).
    def __new__(
        cls,
        points: npt.NDArray[np.float32],
        connectivity: npt.NDArray[np.uint32],
        fields: List[Tuple[str, str, Union[npt.NDArray[np.float32], npt.NDArray[np.float64]]]],
        source: str,
        points64: Optional[npt.NDArray[np.float64]] = None,
        celltypes: Optional[npt.NDArray[np.uint8]] = None,
        offsets: Optional[npt.NDArray[np.int64]] = None,
    ) -> _Mesh: ...
    @property
    def n_points(self) -> int: ...
    @property
    def n_cells(self) -> int: ...
    @property
    def n_tets(self) -> int: ...
    @property
    def bounds(self) -> Tuple[List[float], List[float]]: ...
    @property
    def source(self) -> str: ...
    def fields(self) -> List[Tuple[str, str]]: ...
    def field(self, name: str) -> npt.NDArray[Any]: ...  # float64 for f64 data, else float32
    @property
    def times(self) -> List[float]: ...
    def step_fields(self, names: List[str], step: int) -> List[npt.NDArray[Any]]: ...  # read from the file now
    def at_step(self, step: int) -> _Mesh: ...  # step `step`'s fields on this mesh's geometry
    def points(self) -> npt.NDArray[np.float32]: ...
    def points64(self) -> npt.NDArray[np.float64]: ...
    # (celltypes, offsets, connectivity): the cells as the input had them.
    def cell_list(self) -> Tuple[npt.NDArray[np.uint8], npt.NDArray[np.int64], npt.NDArray[np.int64]]: ...
    def cell_type_counts(self) -> Dict[str, int]: ...
    def tets(self) -> npt.NDArray[np.int64]: ...  # (T, 4): the tets located in
    def tet_cells(self) -> npt.NDArray[np.int64]: ...  # (T,): each tet's cell
    def info_json(self) -> str: ...

@final
class _Locator:
    def __new__(
        cls,
        mesh: _Mesh,
        backend: str = "auto",
        device: Optional[int] = None,
        options: Optional[Dict[str, Any]] = None,
        progress: Optional[_Progress] = None,
    ) -> _Locator: ...
    @property
    def backend(self) -> str: ...
    @property
    def build_seconds(self) -> float: ...
    @property
    def auto_note(self) -> Optional[str]: ...
    @property
    def stack(self) -> List[str]: ...
    @property
    def takes_f64(self) -> bool: ...
    @property
    def precision(self) -> str: ...
    def values_f64(self, name: str) -> bool: ...
    def sample_many64(
        self, points: npt.NDArray[np.float64], names: List[str]
    ) -> Tuple[npt.NDArray[np.int32], npt.NDArray[np.float64]]: ...
    def memory(self) -> Dict[str, Any]: ...
    def locate(self, points: npt.NDArray[np.float32]) -> npt.NDArray[np.int32]: ...
    def sample(self, points: npt.NDArray[np.float32], name: str) -> npt.NDArray[np.float32]: ...
    def locate_and_sample(
        self, points: npt.NDArray[np.float32], name: str
    ) -> Tuple[npt.NDArray[np.int32], npt.NDArray[np.float32]]: ...
    # CSR (indptr, indices, data) over the mesh's vertices, and each point's cell (-1: empty row).
    def weights(
        self, points: npt.NDArray[np.float64]
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int32], npt.NDArray[np.float64], npt.NDArray[np.int32]]: ...
    # The weights of the points for many time steps, on the locator's device for a GPU backend.
    def step_weights(self, points: npt.NDArray[np.float64]) -> _StepWeights: ...

def read_mesh(path: str, format: Optional[str] = None, allow_outside_pieces: bool = False) -> _Mesh: ...

_FieldArrays = List[Tuple[str, int, npt.NDArray[np.float32]]]
# float64 for fields of f64 data sampled on the f64 path.
_ProbedArrays = List[Tuple[str, int, Union[npt.NDArray[np.float32], npt.NDArray[np.float64]]]]

def resample_to_image(
    locator: _Locator,
    names: List[str],
    dims: Tuple[int, int, int],
    bounds: Optional[List[float]] = None,
    progress: Optional[_Progress] = None,
) -> Tuple[_FieldArrays, npt.NDArray[np.uint8], List[float], List[float]]: ...
def probe(
    locator: _Locator,
    points: Union[npt.NDArray[np.float32], npt.NDArray[np.float64]],
    names: List[str],
    progress: Optional[_Progress] = None,
) -> Tuple[_ProbedArrays, npt.NDArray[np.uint8]]: ...
def trace(
    mesh: _Mesh,
    locator: Optional[_Locator],
    vector: str,
    seeds: npt.NDArray[np.float32],
    step: Optional[float],
    max_steps: int,
    max_length: Optional[float],
    max_time: Optional[float],
    direction: str,
    integrator: str,
    max_error: float,
    min_step: Optional[float],
    max_step: Optional[float],
    terminal_speed: float,
    progress: Optional[_Progress] = None,
    unsteady: bool = False,
    start_time: Optional[float] = None,
    end_time: Optional[float] = None,
    reinject_every: int = 0,
    streaklines: bool = False,
    every_output_time: bool = False,
    vorticity: bool = False,
) -> Dict[str, Any]: ...
def resolve(name: str, device: Optional[int] = None) -> str: ...
def devices() -> List[Dict[str, Any]]: ...
def validation_errors() -> int: ...
def vtk_cell_types() -> List[Tuple[int, int, str]]: ...  # (VTK code, points, name) tetloc reads
# (VTK code, Gmsh nodes, VTK node i = Gmsh node vtk_from_gmsh[i]) of a Gmsh element type
def gmsh_cell_type(code: int) -> Optional[Tuple[int, int, List[int]]]: ...
# (nodes (K, W) int64, weights (K, W), gradients (K, W, 3), found (K,) bool) of points in cells `ids`
def interpolation_weights(
    mesh: _Mesh, points: np.ndarray, ids: np.ndarray
) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]: ...

@final
class _StepWeights:
    @property
    def device(self) -> str: ...
    @property
    def n_points(self) -> int: ...
    @property
    def n_vertices(self) -> int: ...
    def cells(self) -> npt.NDArray[np.int32]: ...
    def csr(self) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int32], npt.NDArray[np.float64]]: ...
    # (S, n_vertices, k) float32 -> (S, n_points, k) float32, NaN outside.
    def apply(self, values: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]: ...

@final
class CudaLocator:
    """A soft-bvh locator on the Vulkan device of one CUDA device: the zero-copy path of
    ``tetloc.torch`` (raises DeviceError without a CUDA driver, on another GPU, without the
    Vulkan extensions for sharing memory, or for a mesh other than linear tets)."""

    def __new__(
        cls, mesh: _Mesh, cuda_device: int, vulkan_device: Optional[int] = None, validation: Optional[bool] = None
    ) -> CudaLocator: ...
    # n float32 points at CUDA address `points` -> n int32 ids at `ids`, on CUDA stream `stream`
    def locate(self, points: int, n: int, ids: int, stream: int) -> None: ...
    # ... and 4 n int32 node ids at `nodes`, 4 n float32 weights at `weights` (0 outside)
    def weights(self, points: int, n: int, ids: int, nodes: int, weights: int, stream: int) -> None: ...
    @property
    def cuda_device(self) -> int: ...
    @property
    def semaphores(self) -> str: ...
    @property
    def capacity(self) -> int: ...
    def validation_errors(self) -> int: ...

def cuda_driver_available() -> bool: ...
