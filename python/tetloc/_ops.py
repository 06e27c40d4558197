"""``tetloc.resample_to_image``, ``tetloc.probe`` and ``tetloc.trace``: ParaView's Resample To
Image, Resample With Dataset and Stream Tracer, on the core's operations (the CLI's
``tetloc resample``, ``probe`` and ``trace``). numpy out by default; pyvista objects when asked
(``as_pyvista=True``) or when the input is a pyvista dataset, with ParaView's array names
(``vtkValidPointMask``, ``IntegrationTime``, ``ReasonForTermination``, ``SeedIds``)."""

from __future__ import annotations

import warnings
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _tetloc
from ._args import whole
from ._locator import Locator
from ._mesh import Mesh
from ._points import as_points, as_points64
from ._progress import ProgressBar

ArrayLike = Any
MeshLike = Any  # tetloc.Mesh, tetloc.Locator or a pyvista dataset
VALID_MASK = "vtkValidPointMask"

#: ``ReasonForTermination`` codes, as vtkStreamTracer's (7: the integration time reached
#: ``max_time``, a limit VTK does not have).
REASONS = {1: "OUT_OF_DOMAIN", 2: "NOT_INITIALIZED", 3: "UNEXPECTED_VALUE", 4: "OUT_OF_LENGTH",
           5: "OUT_OF_STEPS", 6: "STAGNATION", 7: "OUT_OF_TIME"}


def _is_pyvista(obj: Any) -> bool:
    pv = __import__("sys").modules.get("pyvista")
    return pv is not None and isinstance(obj, pv.DataSet)


def _mesh_of(mesh: MeshLike, arg: str) -> Mesh:
    if isinstance(mesh, Locator):
        return mesh.mesh
    if isinstance(mesh, Mesh):
        return mesh
    if _is_pyvista(mesh):
        return Mesh.from_pyvista(mesh)
    raise TypeError(f"{arg}: expected a tetloc.Mesh, a tetloc.Locator or a pyvista dataset, got {type(mesh).__name__}")


def _locator(mesh: MeshLike, backend: str, device: Optional[int], arg: str, **options: Any) -> Locator:
    if isinstance(mesh, Locator):
        return mesh
    return Locator(_mesh_of(mesh, arg), backend=backend, device=device, **options)


def _progress(progress: Any, title: str) -> Any:
    if progress is True:
        return ProgressBar(title)
    if progress is False or progress is None:
        return None
    if not callable(progress):
        raise TypeError(f"progress: expected True, False or a callable, got {type(progress).__name__}")
    return progress


def _names(fields: Union[None, str, Sequence[str]]) -> Tuple[List[str], bool]:
    """(field names, whether one field was named as a string)."""
    if fields is None:
        return [], False
    if isinstance(fields, str):
        return [fields], True
    names = list(fields)
    if not all(isinstance(n, str) for n in names):
        raise TypeError(f"fields: expected a field name or a list of names, got {fields!r}")
    return names, False


def _shaped(values: np.ndarray, k: int, lead: Tuple[int, ...]) -> np.ndarray:
    return values.reshape(lead) if k == 1 else values.reshape(lead + (k,))


def resample_to_image(
    mesh: MeshLike,
    fields: Union[None, str, Sequence[str]] = None,
    dims: Sequence[int] = (64, 64, 64),
    bounds: Optional[Sequence[float]] = None,
    *,
    backend: str = "auto",
    device: Optional[int] = None,
    as_pyvista: Optional[bool] = None,
    progress: Any = False,
) -> Any:
    """Samples fields of `mesh` on a regular grid (vtkResampleToImage): `dims` = (NX, NY, NZ)
    points spanning `bounds` (xmin, xmax, ymin, ymax, zmin, zmax; by default the mesh's,
    nudged inwards by 1e-6 of their size as VTK does), points on both ends of each axis.

    Returns, for one field named as a string, a float32 array of shape (NZ, NY, NX) or
    (NZ, NY, NX, k) (x fastest), NaN outside the mesh; for a list of names (or all fields,
    the default) a dict of such arrays plus ``"vtkValidPointMask"`` (uint8, 1 inside). With
    ``as_pyvista=True`` (the default for a pyvista input) a ``pyvista.ImageData`` with the
    fields and ``vtkValidPointMask`` as point data. `mesh` is a tetloc.Mesh, a pyvista dataset
    or a tetloc.Locator (reused, with its backend).
    """
    names, one = _names(fields)
    d = tuple(int(x) for x in np.asarray(dims).ravel())
    if len(d) != 3 or min(d) < 1:
        raise ValueError(f"dims: expected three counts (NX, NY, NZ), each at least 1; got {tuple(dims)}")
    b = None
    if bounds is not None:
        b = [float(x) for x in np.asarray(bounds, dtype=np.float64).ravel()]
        if len(b) != 6:
            raise ValueError(f"bounds: expected six numbers (xmin, xmax, ymin, ymax, zmin, zmax), got {len(b)}")
    pyvista_out = _is_pyvista(mesh) if as_pyvista is None else as_pyvista
    # The CPU rasterizes the grid: its search is built only if a grid point needs it.
    loc = _locator(mesh, backend, device, "mesh", deferred=True)
    arrays, mask, origin, spacing = _tetloc.resample_to_image(
        loc._raw, names, d, b, _progress(progress, "tetloc resample")
    )
    lead = (d[2], d[1], d[0])
    if pyvista_out:
        import pyvista as pv

        img = pv.ImageData(dimensions=d, origin=origin, spacing=spacing)
        return _with_arrays(img, arrays, mask)
    return _numpy_result(arrays, mask, lead, one)



def _with_arrays(dataset: Any, arrays: Any, mask: np.ndarray) -> Any:
    """`dataset` with the sampled arrays and vtkValidPointMask as point data (ParaView's names)."""
    for name, k, values in arrays:
        dataset.point_data[name] = values if k == 1 else values.reshape(-1, k)
    dataset.point_data[VALID_MASK] = mask
    return dataset


def _numpy_result(arrays: Any, mask: np.ndarray, lead: Tuple[int, ...], one: bool) -> Any:
    """One array when one field was asked for as a string, else a dict with the mask too."""
    out = {name: _shaped(values, k, lead) for name, k, values in arrays}
    if one:
        return out[arrays[0][0]]
    out[VALID_MASK] = mask.reshape(lead)
    return out


def probe(
    source: MeshLike,
    target: Any,
    fields: Union[None, str, Sequence[str]] = None,
    *,
    backend: str = "auto",
    device: Optional[int] = None,
    as_pyvista: Optional[bool] = None,
    progress: Any = False,
) -> Any:
    """Samples fields of `source` at the points of `target` (vtkResampleWithDataSet).

    `target` is a (K, 3) array of points (or (..., 3)), a tetloc.Mesh (its vertices) or a
    pyvista dataset (its points). Returns, for one field named as a string, its values
    ((K,) or (K, k), NaN where a point is outside `source`; float64 for a field `source`
    holds in float64, sampled in f64 as the CLI's probe writes it, else float32); else a dict of the
    fields' values plus ``"vtkValidPointMask"``. For a pyvista target (or ``as_pyvista=True``)
    a copy of the target (a ``pyvista.PolyData`` of the points for an array target) with the
    probed arrays and ``vtkValidPointMask`` as point data; probed arrays replace arrays of the
    same name, as VTK's. `source` is a tetloc.Mesh, a pyvista dataset or a tetloc.Locator
    (reused: its backend and tolerance).
    """
    names, one = _names(fields)
    # The target's points at their precision: float64 ones (a mesh's file coordinates) keep
    # every digit, so targets far from the origin are probed where they are.
    lead: Tuple[int, ...]
    if isinstance(target, Mesh):
        pts, lead = target.points64, (target.n_points,)
    else:
        given = np.asarray(target.points) if _is_pyvista(target) else target
        pts, lead = as_points64(given, "target") or as_points(given, "target")
    pyvista_out = _is_pyvista(target) if as_pyvista is None else as_pyvista
    # cpu: the probe's batches search bins; the BVH is built only if a point lands on a face.
    loc = _locator(source, backend, device, "source", deferred=True)
    arrays, mask = _tetloc.probe(loc._raw, pts, names, _progress(progress, "tetloc probe"))
    if pyvista_out:
        import pyvista as pv

        if _is_pyvista(target):
            out = target.copy()
        elif isinstance(target, Mesh):
            out = target.to_pyvista()
        else:
            out = pv.PolyData(pts)
        return _with_arrays(out, arrays, mask)
    return _numpy_result(arrays, mask, lead, one)


def trace(
    mesh: MeshLike,
    vector: str,
    seeds: Any,
    *,
    step: Optional[float] = None,
    max_steps: int = 2000,
    max_length: Optional[float] = None,
    max_time: Optional[float] = None,
    direction: str = "forward",
    integrator: str = "rk4",
    max_error: float = 1e-6,
    min_step: Optional[float] = None,
    max_step: Optional[float] = None,
    terminal_speed: float = 1e-12,
    backend: str = "auto",
    device: Optional[int] = None,
    as_pyvista: Optional[bool] = None,
    progress: Any = False,
    unsteady: bool = False,
    start_time: Optional[float] = None,
    end_time: Optional[float] = None,
    reinject_every: int = 0,
    streaklines: bool = False,
    every_output_time: bool = False,
    vorticity: bool = False,
) -> Any:
    """Streamlines of the 3-component field `vector` from `seeds` (vtkStreamTracer with steps
    in length units): `integrator` ``"rk4"`` (fixed `step`), ``"rk45"`` (adaptive,
    Dormand-Prince 5(4)) or ``"cash-karp"`` (adaptive, VTK's vtkRungeKutta45 tableau); the
    adaptive ones start with `step` and keep each step's error estimate within `max_error`
    between `min_step` and `max_step` (by default step / 50 and 2 step). `step` defaults to a
    tenth of the mean edge. A line stops when it leaves the mesh, stagnates (speed at most
    `terminal_speed`), after `max_steps` + 1 steps, or when its length or integration time
    reaches `max_length` / `max_time` (the last step shortened to land on it). `direction`:
    ``"forward"``, ``"backward"`` or ``"both"`` (all forward lines, then all backward ones).
    Seeds outside the mesh give no line (as VTK), with a ``RuntimeWarning`` counting them.
    `vector` is a point field of 3 components (``tetloc gen SHAPE --vector`` makes meshes with
    one, ``v``; ``Mesh(points, cells, point_data={"v": (N, 3) array})`` adds one).

    `mesh` is a tetloc.Mesh, a tetloc.Locator or a pyvista dataset; `seeds` is a (K, 3) array
    of points or a pyvista dataset (its points). On ``cpu`` each
    particle walks from its last tet; on a GPU backend all particles advance together, one
    batched lookup per Runge-Kutta stage (the same lines up to float32 rounding).

    Returns a dict of numpy arrays: ``points`` (P, 3) float32 (line after line), ``offsets``
    (L + 1,) int64 (line i is ``points[offsets[i]:offsets[i+1]]``), ``IntegrationTime`` (P,)
    float64, ``ReasonForTermination`` and ``SeedIds`` (L,) int32 (codes in
    ``tetloc.REASONS``), and the mesh's point fields at the points under their names. With
    ``as_pyvista=True`` (the default for a pyvista mesh) a ``pyvista.PolyData`` of lines with
    those point and cell arrays, as ParaView's Stream Tracer outputs.

    ``vorticity=True`` (ParaView's "Compute Vorticity", vtkStreamTracer's arrays, float64):
    ``Vorticity`` (P, 3), the curl of `vector` in the cell holding each point (a vector stored
    per cell has none: zeros); ``AngularVelocity`` (P,), the vorticity along the unit
    velocity; ``Rotation`` (P,), the angular velocity integrated along the line by the
    trapezoid rule in ``IntegrationTime``; ``Normals`` (P, 3), vtkPolyLine's sliding normals
    turned by the rotation, which ribbon and tube filters orient by. With ``unsteady=True``
    the first three, as vtkParticlePathFilter's "Compute Vorticity" gives them, the curl and
    the velocity interpolated in time at each point and the rotation integrated in simulation
    time from 0 at the particle's injection (VTK takes the later step's curl alone: between
    two steps, as at a `start_time` off the steps, the two differ; at a step's time they agree).

    ``unsteady=True``: pathlines, as ParaView's Particle Path filter (vtkParticlePathFilter),
    through the time steps of `mesh` (read from an Exodus file with steps or a ``.pvd``):
    particles injected at `seeds` at `start_time` (the first step's by default) move through
    the velocity interpolated linearly in time between the two steps around each moment, time
    being the integration variable, until `end_time` (the last step's by default) or until they
    leave the mesh. `step` is then a time (by default half of each interval between output
    times, as VTK), as are `min_step` and `max_step`; `direction`, `max_steps`, `max_length`
    and `max_time` do not apply. Each line has one point per output time (the start time, each
    step's time between, the end time); ``IntegrationTime`` is the simulation time there,
    ``SeedIds`` the particle's index in `seeds`, ``ReasonForTermination`` 1 (left the mesh),
    6 (stagnated) or 7 (reached `end_time`), and the point fields are interpolated in time too.
    Each point also carries its particle as vtkParticlePathFilter writes it: ``ParticleId``
    int32 (its index among the particles its injection put inside the mesh; it starts again at
    each injection, as VTK's), ``InjectedPointId`` int64 (its seed), ``InjectionStepId`` int32
    (its injection's output time: 0 for `start_time`), ``ParticleAge`` float32 (streaklines:
    their time array is the age, in float64), and VTK's ``ErrorCode`` int32 and
    ``ParticleSourceId`` int8, 0 at every point (points are recorded where a step succeeded,
    and the seeds are one source).
    Only two steps' fields are held in memory at a time. ``reinject_every=N`` injects the seeds
    again at every N-th output time after `start_time` (ParaView's "Force Reinjection Every
    NSteps"): each injection's particles are lines of their own, injection after injection,
    each line's first ``IntegrationTime`` its injection time. ``streaklines=True`` (ParaView's
    Streak Line filter): instead of the pathlines, one line a seed through its particles'
    points at `end_time`, the oldest first and the one injected at `end_time` (at the seed)
    last, with ``ParticleAge`` (the time since injection) in place of ``IntegrationTime``; the
    seeds are then injected at every output time unless `reinject_every` says otherwise.
    ``every_output_time=True``: a list of ``(time, lines)``, one for each output time after
    `start_time`, each what the filter shows at that time (the pathlines up to it, a particle
    that goes on after it ending there with reason 7, or the streaklines at it): the same as a
    run with that `end_time`, for an animation.
    """
    if not isinstance(vector, str):
        raise TypeError(f"vector: expected a field name, got {type(vector).__name__}")
    reinject_every = whole("reinject_every", reinject_every)
    max_steps = whole("max_steps", max_steps)
    if (reinject_every or streaklines or every_output_time) and not unsteady:
        raise ValueError("reinject_every, streaklines and every_output_time apply to pathlines (unsteady=True)")
    m = _mesh_of(mesh, "mesh")
    pts, _ = as_points(np.asarray(seeds.points) if _is_pyvista(seeds) else seeds, "seeds")
    pyvista_out = _is_pyvista(mesh) if as_pyvista is None else as_pyvista
    if isinstance(mesh, Locator):
        raw_loc = mesh._raw
    elif _tetloc.resolve(backend, device) == "cpu":
        raw_loc = None  # each particle walks from its last tet
    else:
        raw_loc = Locator(m, backend=backend, device=device)._raw
    out = _tetloc.trace(
        m._raw, raw_loc, vector, pts, step, max_steps, max_length, max_time, direction, integrator,
        float(max_error), min_step, max_step, float(terminal_speed), _progress(progress, "tetloc trace"),
        bool(unsteady), start_time, end_time, reinject_every, bool(streaklines), bool(every_output_time),
        bool(vorticity),
    )
    # As the CLI: seeds that give no line are counted (VTK makes none for them either).
    injections = out.pop("injections", 1)
    n_lines = len(pts) * (1 if streaklines else injections if unsteady else 2 if direction == "both" else 1)
    frames = out.pop("frames", None)
    last = frames[-1][1] if frames else out
    without = n_lines - (len(last["offsets"]) - 1)
    if without > 0:
        # The CLI's words for each kind of line.
        if streaklines:
            why = (f"{without} of {n_lines} seeds make no streakline (fewer than two of their particles are "
                   "in the mesh at the end time)")
        elif unsteady:
            why = (f"{without} of {n_lines} particles make no line (injected outside the mesh, or gone before "
                   "the next output time)")
        else:
            why = (f"{without} of {n_lines} lines have no step inside the mesh (their seed is outside it, "
                   "or on its boundary going out); VTK makes no line for them either")
        warnings.warn(f"trace: {why}", RuntimeWarning, stacklevel=2)
    if frames is not None:
        return [(t, _lines(lines, streaklines, pyvista_out)) for t, lines in frames]
    return _lines(out, streaklines, pyvista_out)


#: The point arrays pathlines and streaklines add, as vtkParticlePathFilter writes them.
PARTICLE_ARRAYS = ("ParticleId", "InjectedPointId", "InjectionStepId", "ErrorCode", "ParticleAge", "ParticleSourceId")
#: The point arrays ``vorticity=True`` adds, as vtkStreamTracer's ComputeVorticity writes them
#: (pathlines and streaklines: no ``Normals``).
VORTICITY_ARRAYS = ("Vorticity", "Rotation", "AngularVelocity", "Normals")


def _lines(out: Dict[str, Any], streaklines: bool, pyvista_out: bool) -> Any:
    """`_tetloc.trace`'s lines as `trace` returns them: the fields under their names, or a
    ``pyvista.PolyData`` of lines."""
    fields = out.pop("fields")
    n = len(out["points"])
    if "ParticleId" in out:
        # VTK's two constant arrays: a point is recorded only where its step succeeded, and
        # the seeds are one source (np.zeros' pages stay unallocated until written).
        out["ErrorCode"] = np.zeros(n, np.int32)
        out["ParticleSourceId"] = np.zeros(n, np.int8)
    for name, k, values in fields:
        out[name] = _shaped(values, k, (n,))
    if not pyvista_out:
        return out
    import pyvista as pv

    if n == 0:
        return pv.PolyData()  # no line (pyvista refuses empty arrays)
    offsets = out["offsets"]
    sizes = np.diff(offsets)
    cells = np.insert(np.arange(n, dtype=np.int64), offsets[:-1], sizes) if n else np.zeros(0, np.int64)
    poly = pv.PolyData(out["points"], lines=cells)
    for name, _, _ in fields:
        poly.point_data[name] = out[name]
    time = "ParticleAge" if streaklines else "IntegrationTime"
    poly.point_data[time] = out[time]
    for name in PARTICLE_ARRAYS + VORTICITY_ARRAYS:
        if name in out and name != time:
            poly.point_data[name] = out[name]
    poly.cell_data["ReasonForTermination"] = out["ReasonForTermination"]
    poly.cell_data["SeedIds"] = out["SeedIds"]
    return poly


__all__ = ["REASONS", "probe", "resample_to_image", "trace"]
