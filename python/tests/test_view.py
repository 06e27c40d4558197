"""`tetloc view` in a real browser: headless Chromium (Debian's `chromium`), driven through
the DevTools protocol by the small client below (over `websocket-client`), on a small
generated mesh, for the cpu backend and a GPU kernel (lavapipe in CI).

Images are decoded by the browser itself (a canvas), so the page's frame, `/frame.png` and
`tetloc render --state` of the exported state are compared as the same kind of pixels.
"""

from __future__ import annotations

import base64
import json
import os
import pathlib
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import urllib.error
import urllib.parse
import urllib.request
from typing import Any, Dict, Iterator, List, Optional, Tuple

import numpy as np
import pytest

from conftest import missing

MESH = "fusion:20k"
SIZE = "160x128"
TIMEOUT = 120.0


def chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    missing("no chromium (scripts/install-test-deps.sh installs it)")
    raise AssertionError


def websocket_module() -> Any:
    try:
        import websocket  # websocket-client
    except ImportError:
        missing("no websocket-client Python package")
    return websocket


class Page:
    """One browser tab over the DevTools protocol: calls, evaluation, mouse input."""

    def __init__(self, browser: "Browser", target: dict) -> None:
        self.browser, self.target_id = browser, target["id"]
        ws = websocket_module()
        self.ws = ws.create_connection(target["webSocketDebuggerUrl"], timeout=TIMEOUT, suppress_origin=True)
        self.next_id = 0

    def call(self, method: str, **params: Any) -> dict:
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            m = json.loads(self.ws.recv())
            if m.get("id") == self.next_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})

    def eval(self, expr: str) -> Any:
        r = self.call("Runtime.evaluate", expression=expr, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expr[:200]}: {r['exceptionDetails'].get('exception', {}).get('description')}")
        return r["result"].get("value")

    def wait(self, expr: str, timeout: float = TIMEOUT) -> Any:
        end = time.time() + timeout
        while time.time() < end:
            v = self.eval(expr)
            if v:
                return v
            time.sleep(0.05)
        raise AssertionError(f"timed out waiting for {expr}")

    def drag(self, selector: str, fx: float, fy: float, dx: float, dy: float, steps: int = 8) -> None:
        """Presses at fraction (fx, fy) of the element's box and moves by (dx, dy) pixels."""
        # Input goes to the tab in front (a hidden tab holds input events until it paints).
        self.call("Page.bringToFront")
        r = self.eval(f"(() => {{ const b = document.querySelector('{selector}').getBoundingClientRect(); return [b.left, b.top, b.width, b.height]; }})()")
        x, y = r[0] + fx * r[2], r[1] + fy * r[3]
        mouse = lambda kind, x, y, **kw: self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, **kw)
        mouse("mouseMoved", x, y)
        mouse("mousePressed", x, y, button="left", buttons=1, clickCount=1)
        for i in range(1, steps + 1):
            mouse("mouseMoved", x + dx * i / steps, y + dy * i / steps, button="left", buttons=1)
        mouse("mouseReleased", x + dx, y + dy, button="left", buttons=0, clickCount=1)

    def canvas(self) -> np.ndarray:
        """The frame the page shows, as RGB."""
        return self.pixels("(async () => document.getElementById('frame'))()")

    def image(self, png: bytes) -> np.ndarray:
        """A PNG file decoded by the browser, as the page decodes its frames."""
        b64 = base64.b64encode(png).decode()
        return self.pixels(f"createImageBitmap(new Blob([Uint8Array.from(atob('{b64}'), c => c.charCodeAt(0))]))")

    def pixels(self, source: str) -> np.ndarray:
        js = f"""(async () => {{
            const src = await {source};
            const c = new OffscreenCanvas(src.width, src.height), g = c.getContext('2d');
            g.drawImage(src, 0, 0);
            const d = g.getImageData(0, 0, src.width, src.height).data;
            let s = ''; for (let i = 0; i < d.length; i += 8192) s += String.fromCharCode(...d.subarray(i, i + 8192));
            return [src.width, src.height, btoa(s)];
        }})()"""
        w, h, data = self.eval(js)
        return np.frombuffer(base64.b64decode(data), np.uint8).reshape(h, w, 4)[:, :, :3].astype(float)

    def screenshot(self, path: str) -> None:
        data = self.call("Page.captureScreenshot", format="png")["data"]
        pathlib.Path(path).write_bytes(base64.b64decode(data))

    def close(self) -> None:
        self.ws.close()
        self.browser.http(f"/json/close/{self.target_id}")


class Browser:
    def __init__(self) -> None:
        self.dir = tempfile.mkdtemp(prefix="tetloc-chromium-")
        self.proc = subprocess.Popen(
            [chromium(), "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run", "--remote-debugging-port=0",
             "--remote-allow-origins=*", f"--user-data-dir={self.dir}",
             # Pages in background tabs keep their timers (two pages at once).
             "--disable-background-timer-throttling", "--disable-renderer-backgrounding", "--disable-backgrounding-occluded-windows", "--window-size=1000,800", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            if "DevTools listening on ws://" in line:
                self.port = int(line.split("ws://", 1)[1].split("/", 1)[0].rsplit(":", 1)[1])
                break
        else:
            raise AssertionError("chromium did not start its DevTools server")

    def http(self, path: str, method: str = "GET") -> Any:
        req = urllib.request.Request(f"http://127.0.0.1:{self.port}{path}", method=method)
        with urllib.request.urlopen(req, timeout=30) as r:
            body = r.read()
        try:
            return json.loads(body)
        except ValueError:
            return body

    def open(self, url: str) -> Page:
        page = Page(self, self.http("/json/new?" + urllib.parse.quote(url, safe=":/?=&"), method="PUT"))
        page.call("Runtime.enable")
        return page

    def quit(self) -> None:
        self.proc.kill()
        self.proc.wait()
        shutil.rmtree(self.dir, ignore_errors=True)


class Server:
    """`tetloc view` on a free port; its URL from its one line on stdout."""

    def __init__(self, cli: str, *args: str) -> None:
        self.proc = subprocess.Popen([cli, "view", *args, "--port", "0", "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        self.url = self.proc.stdout.readline().strip()
        if not self.url.startswith("http://127.0.0.1:"):
            self.proc.kill()
            raise AssertionError(f"no URL from tetloc view: {self.url!r}; stderr: {self.proc.stderr.read() if self.proc.stderr else ''}")
        self.base, self.token = self.url.split("/?token=")

    def arg(self, name: str) -> str:
        args = [str(a) for a in self.proc.args]  # type: ignore[union-attr]
        return str(args[args.index(name) + 1])

    def get(self, path: str, token: Optional[str] = None) -> tuple[int, bytes]:
        sep = "&" if "?" in path else "?"
        try:
            with urllib.request.urlopen(f"{self.base}{path}{sep}token={token if token is not None else self.token}", timeout=TIMEOUT) as r:
                return r.status, r.read()
        except urllib.error.HTTPError as e:
            return e.code, e.read()

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGINT)
        return self.proc.wait(timeout=30)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    assert a.shape == b.shape, (a.shape, b.shape)
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    b = Browser()
    yield b
    b.quit()


@pytest.fixture(scope="module", params=["cpu", "soft-bvh"])
def server(request: pytest.FixtureRequest, cli: str) -> Iterator[Server]:
    if request.param != "cpu":
        request.getfixturevalue("vulkan")
    s = Server(cli, MESH, "--backend", request.param, "--size", SIZE)
    yield s
    if s.proc.poll() is None:
        s.proc.kill()
        s.proc.wait()


def open_page(browser: Browser, server: Server) -> Page:
    page = browser.open(server.url)
    page.wait("window.tetloc && window.tetloc.stills > 0")
    return page


def still_after(page: Page, frames: int) -> None:
    """Waits for the still frame of the page's newest state, after `frames` frames."""
    page.wait(f"tetloc.frames > {frames} && tetloc.settled()")


def test_page_shows_a_frame_and_follows_a_drag_and_a_tf_edit(browser: Browser, server: Server) -> None:
    page = open_page(browser, server)
    if os.environ.get("TETLOC_VIEW_SCREENSHOT"):
        page.screenshot(os.environ["TETLOC_VIEW_SCREENSHOT"])
    first = page.canvas()
    assert first.std() > 5, "the first frame is not blank"
    assert page.eval("document.getElementById('timebox').hidden"), "a snapshot has no time slider"
    n = page.eval("tetloc.frames")
    page.drag("#frame", 0.5, 0.5, 60, 20)
    still_after(page, n)
    turned = page.canvas()
    assert np.abs(turned - first).mean() > 2, "a drag turns the view"
    # A TF edit: another colormap, then the top opacity point dragged down.
    n = page.eval("tetloc.frames")
    page.eval("(() => { const s = document.getElementById('cmap'); s.value = 'plasma'; s.dispatchEvent(new Event('change')); return 1; })()")
    still_after(page, n)
    recoloured = page.canvas()
    assert np.abs(recoloured - turned).mean() > 2, "another colormap recolours the frame"
    opacity_before = page.eval("tetloc.state.tf.opacity[1][1]")
    n = page.eval("tetloc.frames")
    page.drag("#tf", 0.98, 0.08, 0, 60)
    still_after(page, n)
    assert page.eval("tetloc.state.tf.opacity[1][1]") < opacity_before - 0.2
    assert np.abs(page.canvas() - recoloured).mean() > 1, "a lower opacity changes the frame"
    page.close()


def test_page_frame_png_and_render_state_agree(browser: Browser, server: Server, cli: str, tmp_path: pathlib.Path) -> None:
    page = open_page(browser, server)
    n = page.eval("tetloc.frames")
    page.drag("#frame", 0.4, 0.5, -40, 30)
    still_after(page, n)
    shown = page.canvas()
    status, png = server.get("/frame.png")
    assert status == 200 and png[:8] == b"\x89PNG\r\n\x1a\n"
    served = page.image(png)
    assert psnr(shown, served) >= 40
    # The state the page exports, rendered offline.
    state = tmp_path / "view.json"
    state.write_text(page.eval("JSON.stringify(tetloc.state)"))
    out = tmp_path / "offline.png"
    backend = server.arg("--backend")
    subprocess.run([cli, "render", MESH, "--state", str(state), "--backend", backend, "-o", str(out), "--quiet"], check=True, timeout=TIMEOUT)
    offline = page.image(out.read_bytes())
    assert psnr(shown, offline) >= 40, psnr(shown, offline)
    # ... and opened again by a second viewer.
    again = Server(cli, MESH, "--backend", backend, "--state", str(state))
    try:
        status, png2 = again.get("/frame.png")
        assert status == 200
        reopened = page.image(png2)
        assert psnr(shown, reopened) >= 40
    finally:
        assert again.stop() == 0
    page.close()


def gmsh_series(path: pathlib.Path, times: List[float], n: int = 6) -> None:
    """A Kuhn cube of n³ cubes whose vertex field f is x + k·y at step k of `times`."""
    ijk = [(i, j, k) for k in range(n + 1) for j in range(n + 1) for i in range(n + 1)]
    vid = {c: 1 + m for m, c in enumerate(ijk)}
    tets = []
    for c in [(i, j, k) for k in range(n) for j in range(n) for i in range(n)]:
        for axes in [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]:
            v, tet = list(c), [vid[c]]
            for a in axes:
                v[a] += 1
                tet.append(vid[(v[0], v[1], v[2])])
            tets.append(tet)
    xyz = [[x / n for x in c] for c in ijk]
    lines = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$Nodes", f"1 {len(ijk)} 1 {len(ijk)}", f"3 1 0 {len(ijk)}"]
    lines += [str(m + 1) for m in range(len(ijk))] + [f"{p[0]!r} {p[1]!r} {p[2]!r}" for p in xyz]
    lines += ["$EndNodes", "$Elements", f"1 {len(tets)} 1 {len(tets)}", f"3 1 4 {len(tets)}"]
    lines += [f"{e + 1} {' '.join(map(str, t))}" for e, t in enumerate(tets)] + ["$EndElements"]
    for step, t in enumerate(times):
        lines += ["$NodeData", "1", '"f"', "1", repr(float(t)), "3", str(step), "1", str(len(ijk))]
        lines += [f"{m + 1} {p[0] + step * p[1]!r}" for m, p in enumerate(xyz)] + ["$EndNodeData"]
    path.write_text("\n".join(lines) + "\n")


def test_page_moves_through_time(browser: Browser, server: Server, cli: str, tmp_path: pathlib.Path) -> None:
    """The time slider shows each step of a series, keeping the colours' range; the exported
    state renders offline to the frame shown; play moves on and wraps around."""
    series = tmp_path / "steps.msh"
    gmsh_series(series, [0.0, 0.25, 1.0])
    backend = server.arg("--backend")
    s = Server(cli, str(series), "--backend", backend, "--size", SIZE)
    try:
        page = open_page(browser, s)
        assert not page.eval("document.getElementById('timebox').hidden")
        assert page.eval("document.getElementById('time').max") == "2"
        assert page.eval("document.getElementById('timeval').textContent") == "step 0 (0 to 2), t = 0"
        first, drawn = page.canvas(), page.eval("tetloc.header.range")
        n = page.eval("tetloc.frames")
        page.eval("(() => { const t = document.getElementById('time'); t.value = 2; t.dispatchEvent(new Event('input')); return 1; })()")
        still_after(page, n)
        assert page.eval("tetloc.state.time_step") == 2
        assert page.eval("tetloc.state.tf.range") == pytest.approx(drawn), "the range is kept through time"
        assert page.eval("tetloc.header.range") == pytest.approx(drawn)
        last = page.canvas()
        assert np.abs(last - first).mean() > 2, "step 2 differs from step 0"
        state = tmp_path / "view.json"
        state.write_text(page.eval("JSON.stringify(tetloc.state)"))
        out = tmp_path / "offline.png"
        subprocess.run([cli, "render", str(series), "--state", str(state), "--backend", backend, "-o", str(out), "--quiet"], check=True, timeout=TIMEOUT)
        assert psnr(last, page.image(out.read_bytes())) >= 40
        # Play: step 2 wraps to 0, then 1; pause stops it. Play moves on every 30 ms once a
        # step is still, so the step paused at is read in the same script as the click.
        page.eval("document.getElementById('play').click()")
        page.wait("tetloc.state.time_step === 1")
        paused_at = page.eval("(() => { document.getElementById('play').click(); return tetloc.state.time_step; })()")
        assert page.eval("document.getElementById('play').textContent") == "play"
        page.wait("tetloc.settled()")
        time.sleep(0.3)
        assert page.eval("tetloc.settled()") and page.eval("tetloc.state.time_step") == paused_at
        page.close()
    finally:
        assert s.stop() == 0


def test_play_stops_at_a_step_that_cannot_be_read(browser: Browser, cli: str, tmp_path: pathlib.Path) -> None:
    """Playing a series whose last step's file is cut short: the page shows the error,
    naming the file, and the play stops there."""
    s = Server(cli, str(cut_series(cli, tmp_path)), "--backend", "cpu", "--size", SIZE)
    try:
        page = open_page(browser, s)
        page.eval("document.getElementById('play').click()")
        page.wait("tetloc.errors.length > 0")
        assert "cut.vtu" in page.eval("tetloc.errors[0]")
        assert page.eval("document.getElementById('play').textContent") == "play"
        assert page.eval("tetloc.state.time_step") == 2
        page.close()
    finally:
        assert s.stop() == 0


def test_two_pages_update_and_one_closing_leaves_the_other(browser: Browser, server: Server) -> None:
    a, b = open_page(browser, server), open_page(browser, server)
    na, nb = a.eval("tetloc.frames"), b.eval("tetloc.frames")
    a.drag("#frame", 0.5, 0.5, 50, 0)
    still_after(a, na)
    b.wait(f"tetloc.header.gen >= {a.eval('tetloc.header.gen')} && tetloc.settled()")
    assert psnr(a.canvas(), b.canvas()) >= 40, "both pages show the same view"
    ca, cb = a.eval("tetloc.state.camera"), b.eval("tetloc.state.camera")
    assert all(np.allclose(ca[k], cb[k], rtol=1e-12) for k in ("eye", "target", "up")), (ca, cb)
    a.close()
    nb = b.eval("tetloc.frames")
    b.drag("#frame", 0.5, 0.5, -50, 10)
    still_after(b, nb)
    b.close()


def raw_request(server: Server, head: str) -> bytes:
    host, port = server.base.removeprefix("http://").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=30) as s:
        s.sendall(head.encode())
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    return data


def test_wrong_token_gets_403_and_no_image(browser: Browser, server: Server) -> None:
    for path in ["/", "/frame.png", "/state.json", "/ws", "/no/such/file", "/../../etc/passwd"]:
        for token in ["", "wrong", server.token[:-1]]:
            assert server.get(path, token)[0] == 403, (path, token)
    upgrade = "GET /ws?token=bad HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    assert raw_request(server, upgrade).startswith(b"HTTP/1.1 403")
    assert server.get("/no/such/file")[0] == 404, "with the token, still no file"
    page = browser.open(f"{server.base}/?token=wrong")
    page.wait("document.readyState === 'complete'")
    assert page.eval("document.querySelectorAll('canvas, img').length") == 0
    assert "403" in page.eval("document.body.innerText")
    page.close()


def test_hostile_clients_are_closed_alone(browser: Browser, server: Server) -> None:
    ws_mod = websocket_module()
    page = open_page(browser, server)
    url = server.base.replace("http://", "ws://") + f"/ws?token={server.token}"
    for bad in ["not json", json.dumps({"type": "open", "path": "/etc/passwd"}), "x" * (300 * 1024)]:
        c = ws_mod.create_connection(url, timeout=30, suppress_origin=True)
        assert json.loads(c.recv())["type"] == "hello"
        c.send(bad)
        with pytest.raises(Exception):
            while True:  # frames may arrive before the close
                if c.recv_data()[0] == ws_mod.ABNF.OPCODE_CLOSE:
                    raise ConnectionError("closed")
        c.close()
    # A flood is cut off too.
    c = ws_mod.create_connection(url, timeout=30, suppress_origin=True)
    c.recv()
    with pytest.raises(Exception):
        for i in range(5000):
            c.send(json.dumps({"type": "ack", "seq": i}))
        while c.recv_data()[0] != ws_mod.ABNF.OPCODE_CLOSE:
            pass
        raise ConnectionError("closed")
    c.close()
    # A client gone mid-frame: connect, ask for frames, vanish.
    c = ws_mod.create_connection(url, timeout=30, suppress_origin=True)
    state = json.loads(c.recv())["state"]
    c.send(json.dumps({"type": "state", "state": state, "moving": True}))
    c.sock.close()
    n = page.eval("tetloc.frames")
    page.drag("#frame", 0.5, 0.5, 30, 30)
    still_after(page, n)
    page.close()


def test_sigint_ends_the_server_with_exit_0(cli: str) -> None:
    s = Server(cli, "fusion:2k", "--backend", "cpu", "--size", "32x32")
    assert s.get("/frame.png")[0] == 200
    assert s.stop() == 0


def test_python_view_handle(cli: str) -> None:
    import tetloc

    with tetloc.view("fusion:2k", "f", backend="cpu", size=(48, 40), cli=cli) as v:
        assert v._repr_html_().startswith("<iframe") and v.token in v._repr_html_()
        first = v.frame()
        assert first.shape == (40, 48, 3) and first.dtype == np.uint8 and first.std() > 1
        s = v.state()
        v.set_camera((np.array(s["camera"]["eye"]) * 1.5).tolist(), s["camera"]["target"], s["camera"]["up"])
        farther = v.frame()
        assert np.abs(farther.astype(float) - first).mean() > 1
        v.set_tf(colormap="plasma", opacity=[(0, 0), (1, 0.5)], range=(-1, 1))
        assert v.state()["tf"]["colormap"] == "plasma"
        assert np.abs(v.frame().astype(float) - farther).mean() > 1
        with pytest.raises(ValueError, match="no-such-field"):
            v.set_field("no-such-field")
        assert v.times == []
    assert v._proc.returncode == 0


def test_python_view_refuses_bad_arguments_by_type(cli: str, tmp_path: pathlib.Path) -> None:
    """Hostile test: every argument error came back as a RuntimeError from the command (a port
    of -1 as clap's usage text), and a stopped viewer's methods raised urllib's URLError."""
    import tetloc

    bad: List[Tuple[Dict[str, Any], type, str]] = [
        (dict(port=-1), ValueError, "port"),
        (dict(port=70000), ValueError, "port"),
        (dict(port="80"), TypeError, "port"),
        (dict(time_step=-1), ValueError, "time_step"),
        (dict(time_step=1.0), TypeError, "time_step"),
        (dict(size=(0, 10)), ValueError, "size"),
        (dict(size="64x64"), TypeError, "size"),
        (dict(field=3), TypeError, "field"),
        (dict(state=tmp_path / "none.json"), FileNotFoundError, "none.json"),
        (dict(field="no-such-field"), ValueError, "no-such-field"),
        (dict(backend="no-such-backend"), ValueError, "no-such-backend"),
    ]
    for kw, error, match in bad:
        with pytest.raises(error, match=match):
            tetloc.view("fusion:2k", cli=cli, **kw)
    with pytest.raises(FileNotFoundError, match="absent.vtu"):
        tetloc.view(tmp_path / "absent.vtu", cli=cli)
    v = tetloc.view("fusion:2k", "f", backend="cpu", size=(16, 16), cli=cli)
    with pytest.raises(TypeError):
        v.set_time_step(True)
    with pytest.raises(TypeError, match="field"):
        v.set_field(None)  # type: ignore[arg-type]
    assert v.stop() == 0
    for call in (v.frame, v.state, lambda: v.times):
        with pytest.raises(RuntimeError, match="the server has stopped"):
            call()


def test_python_view_handle_moves_through_time(cli: str, tmp_path: pathlib.Path) -> None:
    import tetloc

    series = tmp_path / "steps.msh"
    gmsh_series(series, [0.0, 0.5, 2.0], n=4)
    with tetloc.view(series, "f", backend="cpu", size=(48, 40), time_step=1, cli=cli) as v:
        assert v.times == [0.0, 0.5, 2.0]
        assert v.state()["time_step"] == 1
        second = v.frame()
        drawn = json.loads(v._request("/frame.json"))["range"]
        v.set_time_step(2)
        assert v.state()["time_step"] == 2 and v.state()["tf"]["range"] == pytest.approx(drawn)
        assert np.abs(v.frame().astype(float) - second).mean() > 1
        with pytest.raises(ValueError, match="time step 3 is out of range"):
            v.set_time_step(3)
        out = tmp_path / "offline.png"
        (tmp_path / "view.json").write_text(json.dumps(v.state()))
        subprocess.run([cli, "render", str(series), "--state", str(tmp_path / "view.json"), "--backend", "cpu", "-o", str(out), "--quiet"], check=True, timeout=TIMEOUT)
        assert np.array_equal(v.frame(), tetloc._view._decode_png(out.read_bytes()))


def cut_series(cli: str, tmp_path: pathlib.Path) -> pathlib.Path:
    """A .pvd of three steps whose last step's file is cut short."""
    subprocess.run([cli, "gen", "fusion", "--tets", "2000", "-o", str(tmp_path / "s.vtu"), "-q"], check=True, timeout=TIMEOUT)
    whole = (tmp_path / "s.vtu").read_bytes()
    (tmp_path / "cut.vtu").write_bytes(whole[: len(whole) // 2])
    sets = "".join(f'<DataSet timestep="{k}" file="{f}"/>' for k, f in enumerate(["s.vtu", "s.vtu", "cut.vtu"]))
    series = tmp_path / "series.pvd"
    series.write_text(f'<?xml version="1.0"?><VTKFile type="Collection" version="0.1"><Collection>{sets}</Collection></VTKFile>')
    return series


def test_a_step_that_cannot_be_read_is_an_error_not_an_older_frame(cli: str, tmp_path: pathlib.Path) -> None:
    """A series whose last step's file is cut short: showing that step raises, naming the
    file, and so does the frame (the still of another step is not served in its place); the
    viewer goes on with the other steps."""
    import tetloc

    series = cut_series(cli, tmp_path)
    with tetloc.view(series, "f", backend="cpu", size=(48, 40), cli=cli) as v:
        first = v.frame()
        with pytest.raises(ValueError, match="cut.vtu"):
            v.set_time_step(2)
        with pytest.raises(ValueError, match="cut.vtu"):
            v.frame()
        v.set_time_step(1)
        assert v.state()["time_step"] == 1 and np.array_equal(v.frame(), first)
