"""Vector fields over the core's scalar fields.

The core mesh model holds scalar fields only: a k-component array becomes the fields
``NAME[0]`` .. ``NAME[k-1]``. This module is the one place that maps between the two
views; when the core gains k-component fields, it is the one place to change.
"""

from __future__ import annotations

import re
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

_COMPONENT = re.compile(r"^(.*)\[(\d+)\]$")


def component_name(name: str, i: int) -> str:
    return f"{name}[{i}]"


class FieldIndex:
    """The fields of a mesh as the user sees them: name -> (location, component names).

    A scalar field has one component, its own name, and ``k is None``; a vector field
    ``v`` with k components has the core names ``v[0]`` .. ``v[k-1]``.
    """

    def __init__(self, core_fields: Sequence[Tuple[str, str]]):
        location = dict(core_fields)
        self.fields: Dict[str, Tuple[str, List[str], Optional[int]]] = {}
        # Components group into a vector when 0..k-1 are all there, on one location, and
        # no scalar field has the vector's name; anything else keeps its literal name.
        groups: Dict[str, Dict[int, str]] = {}
        for name, _ in core_fields:
            m = _COMPONENT.match(name)
            if m and m.group(1) not in location:
                groups.setdefault(m.group(1), {})[int(m.group(2))] = name
        vectors = {
            base: [comps[i] for i in range(len(comps))]
            for base, comps in groups.items()
            if sorted(comps) == list(range(len(comps))) and len({location[c] for c in comps.values()}) == 1
        }
        for name, loc in core_fields:
            m = _COMPONENT.match(name)
            base = m.group(1) if m else None
            if base in vectors:
                if base not in self.fields:
                    self.fields[base] = (loc, vectors[base], len(vectors[base]))
            else:
                self.fields[name] = (loc, [name], None)

    def shapes(self, location: str, n: int) -> Dict[str, Tuple[int, ...]]:
        """name -> array shape of the fields at `location` ("point" or "cell")."""
        return {
            name: (n,) if k is None else (n, k)
            for name, (loc, _, k) in self.fields.items()
            if loc == location
        }

    def components(self, name: str) -> Tuple[List[str], Optional[int]]:
        """The core names of field `name` and its component count (None: scalar)."""
        if not isinstance(name, str):
            raise TypeError(f"field name: expected a str, got {type(name).__name__} ({name!r})")
        if name not in self.fields:
            have = ", ".join(
                f"'{n}' ({loc}{'' if k is None else f', {k} components'})"
                for n, (loc, _, k) in self.fields.items()
            )
            raise ValueError(f"no field named '{name}' (the mesh has: {have or 'none'})")
        _, comps, k = self.fields[name]
        return comps, k


def split(
    data: Optional[Mapping[str, object]], location: str, n: int, arg: str
) -> List[Tuple[str, str, np.ndarray]]:
    """The core fields of a user's `point_data` or `cell_data` dict: (name, location,
    values) per component, float64 for float64 data (kept where float32 would round it),
    float32 otherwise. `n` is the number of points or cells."""
    out: List[Tuple[str, str, np.ndarray]] = []
    for name, values in (data or {}).items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"{arg}: field names must be non-empty strings, got {name!r}")
        a = np.asarray(values)
        if a.dtype.kind not in "biuf":
            raise ValueError(f"{arg}['{name}']: dtype {a.dtype}; expected numbers")
        if a.ndim > 2:  # tensors (N, 3, 3) become 9 components, as in VTK
            a = a.reshape(a.shape[0], -1)
        if a.ndim == 0 or a.shape[0] != n:
            raise ValueError(
                f"{arg}['{name}']: shape {a.shape}; expected ({n},) or ({n}, k), one row per {location}"
            )
        dtype = np.float64 if a.dtype.kind == "f" and a.dtype.itemsize == 8 else np.float32  # '>f8' too
        if a.ndim == 1:
            out.append((name, location, np.ascontiguousarray(a, dtype=dtype)))
        else:
            for i in range(a.shape[1]):
                out.append((component_name(name, i), location, np.ascontiguousarray(a[:, i], dtype=dtype)))
    return out


def join(columns: Sequence[np.ndarray], k: Optional[int]) -> np.ndarray:
    """One field's values from its components' values: (K,) for a scalar, (K, k) for a vector."""
    return columns[0] if k is None else np.stack(columns, axis=-1)
