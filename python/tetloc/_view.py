"""``tetloc.view``: the browser volume viewer (``tetloc view``) started in the background.

The server is the ``tetloc`` command's own (found as ``cli=``, ``$TETLOC_CLI`` or on the
``PATH``), on 127.0.0.1 with a random token. In Jupyter the returned :class:`Viewer` shows
the page inline (an IFrame); from code it sets the camera and transfer function, fetches
the current frame as a numpy array, and stops the server::

    v = tetloc.view("mesh.vtu", "temperature", size=(640, 480))
    v.set_tf(colormap="plasma", range=(0.0, 300.0))
    img = v.frame()          # (480, 640, 3) uint8, the lossless still frame
    v.set_time_step(3)       # a series' step 3, 0-based (v.times: each step's time)
    v.stop()
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import urllib.error
import urllib.request
import zlib
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from ._args import whole

PathLike = Union[str, "os.PathLike[str]"]


def _cli(cli: Optional[str]) -> str:
    for candidate in (cli, os.environ.get("TETLOC_CLI"), shutil.which("tetloc")):
        if candidate and os.path.isfile(candidate):
            return candidate
    raise FileNotFoundError("no tetloc command: pass cli=, set TETLOC_CLI, or put tetloc on the PATH")


class Viewer:
    """A running ``tetloc view`` server; see :func:`view`."""

    def __init__(self, proc: "subprocess.Popen[str]", url: str) -> None:
        self._proc = proc
        self.url = url
        self.base, self.token = url.split("/?token=")

    def _request(self, path: str, method: str = "GET", body: Optional[bytes] = None) -> bytes:
        self._check_running()
        req = urllib.request.Request(f"{self.base}{path}?token={self.token}", data=body, method=method)
        if body is not None:
            req.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(req, timeout=600) as r:
                return bytes(r.read())
        except urllib.error.HTTPError as e:
            # The server's own words: a state it refuses (400) or cannot draw (422: a step's
            # file it cannot read, say) is the caller's ValueError.
            why = e.read().decode("utf-8", "replace").strip()
            raise (ValueError if e.code in (400, 422) else RuntimeError)(f"tetloc view: {why}") from None
        except urllib.error.URLError as e:
            self._check_running()
            raise RuntimeError(f"tetloc view: the server at {self.base} did not answer ({e.reason})") from None

    def _check_running(self) -> None:
        """A ``RuntimeError`` once the server has stopped (:meth:`stop`, or it ended)."""
        code = self._proc.poll()
        if code is not None:
            raise RuntimeError(f"tetloc view: the server has stopped (exit code {code}); start another with tetloc.view")

    def _repr_html_(self) -> str:
        return f'<iframe src="{self.url}" width="100%" height="720" style="border:0"></iframe>'

    def state(self) -> Dict[str, Any]:
        """The view state (camera, transfer function, field, options), as ``render --state`` reads it."""
        return dict(json.loads(self._request("/state.json")))

    def set_state(self, state: Dict[str, Any]) -> None:
        self._request("/state.json", "PUT", json.dumps(state).encode())

    def set_camera(self, eye: Sequence[float], target: Sequence[float], up: Sequence[float], zoom: Optional[float] = None) -> None:
        """Places the camera (the mesh file's coordinates)."""
        s = self.state()
        s["camera"].update(eye=list(map(float, eye)), target=list(map(float, target)), up=list(map(float, up)))
        if zoom is not None:
            s["camera"]["zoom"] = float(zoom)
        self.set_state(s)

    def set_tf(
        self,
        colormap: Optional[str] = None,
        opacity: Optional[Sequence[Tuple[float, float]]] = None,
        range: Optional[Tuple[float, float]] = None,
        scale: Optional[float] = None,
    ) -> None:
        """A built-in colormap, opacity points ``(x, opacity)`` over [0, 1], the value range
        (``None`` leaves it), and the opacity scale."""
        s = self.state()
        tf = s["tf"]
        if colormap is not None:
            tf.update(colormap=colormap, colors=[], space="RGB")
        if opacity is not None:
            tf["opacity"] = [[float(x), float(o), 0.5, 0.0] for x, o in opacity]
        if range is not None:
            tf["range"] = [float(range[0]), float(range[1])]
        if scale is not None:
            tf["scale"] = float(scale)
        self.set_state(s)

    def set_time_step(self, k: int) -> None:
        """Shows time step ``k`` (0-based) of a series, as the page's time slider does. A
        range left to the field's is first pinned to the one drawn with, so the colours mean
        the same values at every step (``set_tf(range=...)`` sets another). Returns once
        the step is shown; a step whose file cannot be read raises ``ValueError`` naming it."""
        k = whole("time step", k)
        s = self.state()
        if s["tf"]["range"] is None:
            s["tf"]["range"] = list(self._range())
        s["time_step"] = k
        self.set_state(s)
        self._range()

    def _range(self) -> Tuple[float, float]:
        """The range the current still frame was drawn with."""
        lo, hi = json.loads(self._request("/frame.json"))["range"]
        return float(lo), float(hi)

    @property
    def times(self) -> List[float]:
        """Each time step's time (empty for a single snapshot)."""
        return [float(t) for t in json.loads(self._request("/mesh.json"))["times"]]

    def set_field(self, field: str) -> None:
        if not isinstance(field, str):
            raise TypeError(f"field: expected a field name, got {type(field).__name__}")
        s = self.state()
        s["field"], s["tf"]["range"] = field, None
        self.set_state(s)

    def frame(self) -> np.ndarray:
        """The current view's lossless still frame, (height, width, 3) uint8 sRGB
        (``ValueError`` where the current view cannot be drawn, saying why)."""
        return _decode_png(self._request("/frame.png"))

    def stop(self) -> int:
        """Stops the server (as Ctrl-C does) and returns its exit code."""
        if self._proc.poll() is None:
            self._proc.send_signal(signal.SIGINT)
        return self._proc.wait(timeout=60)

    def __enter__(self) -> "Viewer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()


def view(
    mesh: PathLike,
    field: Optional[str] = None,
    *,
    backend: str = "auto",
    size: Tuple[int, int] = (768, 768),
    port: int = 0,
    state: Optional[PathLike] = None,
    time_step: Optional[int] = None,
    cli: Optional[str] = None,
) -> Viewer:
    """Starts ``tetloc view`` on ``mesh`` (a file, or ``SHAPE:N``) in the background and
    returns once it serves; ``port=0`` picks a free port. ``time_step``: the step of a series
    shown first (see :meth:`Viewer.set_time_step`). Arguments of the wrong type raise
    ``TypeError``, and values out of range ``ValueError``, before anything starts; a mesh or
    state file that does not exist ``FileNotFoundError``; a server that refuses to start (a
    field the mesh lacks, a file it cannot read) ``ValueError`` with its message."""
    for name, value in (("field", field), ("backend", backend)):
        if value is not None and not isinstance(value, str):
            raise TypeError(f"{name}: expected a string, got {type(value).__name__}")
    if not (isinstance(size, (tuple, list)) and len(size) == 2):
        raise TypeError(f"size: expected (width, height) in pixels, got {size!r}")
    size = (whole("size", size[0], least=1), whole("size", size[1], least=1))
    if not 0 <= whole("port", port) <= 65535:
        raise ValueError(f"port: expected 0 (any free port) to 65535, got {port}")
    if time_step is not None:
        time_step = whole("time_step", time_step)
    for name, path in (("mesh", mesh), ("state", state)):
        # (A mesh may also be SHAPE:N, generated: only a path with a folder or a file
        # extension is checked here.)
        if path is not None and not os.path.exists(os.fspath(path)) and (name == "state" or _looks_like_a_path(path)):
            raise FileNotFoundError(f"{name}: {os.fspath(path)}: no such file")
    args: List[str] = [_cli(cli), "view", os.fspath(mesh), "--backend", backend, "--size", f"{size[0]}x{size[1]}", "--port", str(port), "--quiet"]
    if field is not None:
        args += ["--field", field]
    if state is not None:
        args += ["--state", os.fspath(state)]
    if time_step is not None:
        args += ["--time-step", str(int(time_step))]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stderr is not None
    url = proc.stdout.readline().strip()
    if not url.startswith("http://"):
        code = proc.wait()
        why = proc.stderr.read().strip()
        # The command's own refusal of its inputs (it says "error: ..." and exits 1 or 2).
        raise (ValueError if code in (1, 2) and why.startswith("error:") else RuntimeError)(
            f"tetloc view did not start: {why or f'exit code {code}'}"
        )
    return Viewer(proc, url)


def _looks_like_a_path(mesh: PathLike) -> bool:
    """Whether `mesh` names a file rather than a generated shape (``SHAPE:N``, as
    ``fusion:1.4M``)."""
    return re.fullmatch(r"[A-Za-z][\w-]*:[0-9.eE+]+[kKmMgG]?", os.fspath(mesh)) is None


def _decode_png(data: bytes) -> np.ndarray:
    """An 8-bit RGB or RGBA, non-interlaced PNG (what the viewer serves) as an array."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, width = 8, b"", 0
    height = depth = color = 0
    while pos < len(data):
        n = int.from_bytes(data[pos : pos + 4], "big")
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            width, height = int.from_bytes(body[:4], "big"), int.from_bytes(body[4:8], "big")
            depth, color = body[8], body[9]
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    if depth != 8 or color not in (2, 6):
        raise ValueError(f"unsupported PNG (bit depth {depth}, colour type {color})")
    bpp = 3 if color == 2 else 4
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, 1 + width * bpp)
    out = np.zeros((height, width * bpp), np.int32)
    for y in range(height):
        f, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        up = out[y - 1] if y else np.zeros_like(line)
        if f == 0:
            out[y] = line
        elif f == 1:  # Sub: a running sum along the row, per channel
            out[y] = (np.cumsum(line.reshape(width, bpp), axis=0) & 255).reshape(-1)
        elif f == 2:
            out[y] = (line + up) & 255
        else:  # Average, Paeth depend on the pixel to the left: byte by byte
            row = out[y]
            for i in range(line.size):
                left = row[i - bpp] if i >= bpp else 0
                ul = up[i - bpp] if i >= bpp else 0
                if f == 3:
                    pred = (left + up[i]) >> 1
                else:
                    p = left + up[i] - ul
                    pa, pb, pc = abs(p - left), abs(p - up[i]), abs(p - ul)
                    pred = left if pa <= pb and pa <= pc else (up[i] if pb <= pc else ul)
                row[i] = (line[i] + pred) & 255
    return out.astype(np.uint8).reshape(height, width, bpp)[:, :, :3]
