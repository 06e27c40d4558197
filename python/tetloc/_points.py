"""Query points in: any array-like of shape (..., 3), float32 or float64 (integers are taken
as float64), C or Fortran order, numpy arrays, lists, and CPU tensors (DLPack or ``__array__``, e.g. torch).

float32 points are located as they are (a C-contiguous float32 array is handed over without
a copy); float64 points keep their precision (exact decisions on the CPU; the GPU kernels
search them in the mesh's working frame, centred on meshes far from the origin).
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from typing import Any, Tuple

import numpy as np


def _to_numpy(points: Any, arg: str) -> np.ndarray:
    if isinstance(points, np.ndarray):
        return points
    if points is None or isinstance(points, (str, bytes, numbers.Number, Mapping)):
        raise TypeError(
            f"{arg}: expected an array-like of points of shape (K, 3) or (3,) (numpy array, list, tensor), "
            f"got {type(points).__name__}"
        )
    if hasattr(points, "__dlpack__"):
        try:
            return np.from_dlpack(points)  # zero-copy for CPU tensors
        except (BufferError, RuntimeError, TypeError, ValueError) as e:
            if not hasattr(points, "__array__"):
                raise ValueError(
                    f"{arg}: cannot read this {type(points).__name__} through DLPack ({e}); "
                    "pass a CPU array (for a GPU tensor: .cpu())"
                ) from None
    if hasattr(points, "__array__"):
        return np.asarray(points)
    # Plain sequences: numbers become float64, so [[0, 0, 0]] is a point too.
    try:
        return np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{arg}: not an array of numbers of shape (..., 3) ({e})") from None


def as_points(points: Any, arg: str = "points") -> Tuple[np.ndarray, Tuple[int, ...]]:
    """(a (K, 3) float32 C-contiguous array, the leading shape of the input).

    Results take the leading shape: (K,) for (K, 3) points, () for one point (3,).
    """
    a = _to_numpy(points, arg)
    if a.dtype.kind in "biu":
        a = a.astype(np.float64)  # integers are numbers, as numpy takes them (exact up to 2^53)
    if a.dtype.kind != "f" or a.dtype.itemsize not in (4, 8):
        raise ValueError(
            f"{arg}: dtype {a.dtype}; expected float32 or float64 (convert with .astype(np.float32))"
        )
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"{arg}: shape {a.shape}; expected (K, 3) (or (..., 3))")
    lead = a.shape[:-1]
    flat = a if a.ndim == 2 else a.reshape(-1, 3)  # a view unless the layout forbids it
    with np.errstate(over="ignore"):  # beyond float32 range: inf, answered -1 / NaN
        return np.ascontiguousarray(flat, dtype=np.float32), lead


def as_points64(points: Any, arg: str = "points") -> Tuple[np.ndarray, Tuple[int, ...]] | None:
    """(a (K, 3) float64 C-contiguous array, the leading shape) when `points` is float64
    (located exactly at that precision), else None (use :func:`as_points`)."""
    a = _to_numpy(points, arg)
    if a.dtype.kind in "biu":
        a = a.astype(np.float64)
    # By kind and size, not `== np.float64`: big-endian '>f8' holds the same digits.
    if a.dtype.kind != "f" or a.dtype.itemsize != 8 or a.ndim == 0 or a.shape[-1] != 3:
        return None
    lead = a.shape[:-1]
    flat = a if a.ndim == 2 else a.reshape(-1, 3)
    return np.ascontiguousarray(flat, dtype=np.float64), lead
