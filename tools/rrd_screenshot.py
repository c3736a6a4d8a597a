"""Screenshot Rerun recordings as a person sees them: the Rerun web viewer in headless Chromium.

    python tools/rrd_screenshot.py RECORDING.rrd OUT.png [--chromium PATH] [--wait 40]
    python tools/rrd_screenshot.py --lessons [--chromium PATH]  # the course's screenshots

``rerun --web-viewer`` (installed with rerun-sdk) serves the recording and the viewer on
127.0.0.1; Chromium (``--chromium``, else ``chromium`` / ``chromium-browser`` /
``google-chrome`` on PATH) opens it headless with its software WebGL renderer
(SwiftShader: the native viewer needs a GPU, the web viewer does not) and the picture is
taken through the Chrome DevTools protocol after ``--wait`` seconds. Every process started
is stopped by its own id at the end.

``--lessons`` screenshots the recording each lesson wrote (``out/notebooks/NN_*.rrd``, made
by ``python notebooks/build_notebooks.py --render``) into
``docs/notebooks/recordings/<notebook>.png``, the picture its rendered page shows.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _find(names, given=None):
    if given:
        if not Path(given).is_file():
            raise SystemExit(f"error: no such file: {given}")
        return str(given)
    for n in names:
        p = shutil.which(n)
        if p:
            return p
    return None


def _rerun_exe():
    here = Path(sys.executable).parent / "rerun"
    exe = str(here) if here.is_file() else _find(["rerun"])
    if exe is None:
        raise SystemExit("error: the rerun executable was not found (install rerun-sdk)")
    return exe


def _wait_for(predicate, timeout, what):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if predicate():
            return
        time.sleep(0.25)
    raise SystemExit(f"error: timed out waiting for {what}")


def _cdp_screenshot(ws_url, width, height):
    """Capture the page behind ``ws_url`` (DevTools websocket) as PNG bytes."""
    from tornado.ioloop import IOLoop
    from tornado.websocket import websocket_connect

    async def run():
        conn = await websocket_connect(ws_url, max_message_size=1 << 28)
        calls = [
            (
                "Emulation.setDeviceMetricsOverride",
                {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
            ),
            ("Page.captureScreenshot", {"format": "png"}),
        ]
        result = None
        for i, (method, params) in enumerate(calls, 1):
            await conn.write_message(json.dumps({"id": i, "method": method, "params": params}))
            while True:
                msg = json.loads(await conn.read_message())
                if msg.get("id") == i:
                    if "error" in msg:
                        raise SystemExit(f"error: DevTools {method}: {msg['error']}")
                    result = msg.get("result")
                    break
        conn.close()
        return base64.b64decode(result["data"])

    return IOLoop.current().run_sync(run)


def screenshot(rrd, out, chromium=None, wait=40.0, size=(1600, 1000)):
    """Render ``rrd`` in the Rerun web viewer (headless Chromium) and write ``out`` (PNG)."""
    rrd, out = Path(rrd).resolve(), Path(out).resolve()
    if not rrd.is_file():
        raise SystemExit(f"error: no such recording: {rrd}")
    browser = _find(
        ["chromium", "chromium-browser", "google-chrome", "google-chrome-stable"], chromium
    )
    if browser is None:
        raise SystemExit(
            "error: no Chromium found: pass --chromium PATH (e.g. apt-get install chromium)"
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    grpc, web, devtools = _free_port(), _free_port(), _free_port()
    work = Path(tempfile.mkdtemp(prefix="rrd_screenshot_"))
    procs = []
    try:
        log = open(work / "rerun.log", "w")
        procs.append(
            subprocess.Popen(
                [
                    _rerun_exe(),
                    "--web-viewer",
                    "--renderer",
                    "webgl",
                    "--bind",
                    "127.0.0.1",
                    "--port",
                    str(grpc),
                    "--web-viewer-port",
                    str(web),
                    str(rrd),
                ],
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        )
        _wait_for(
            lambda: "Hosting a web-viewer" in (work / "rerun.log").read_text(),
            60,
            "the rerun web viewer",
        )
        source = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc}/proxy", safe="")
        url = f"http://127.0.0.1:{web}/?url={source}&renderer=webgl"
        procs.append(
            subprocess.Popen(
                [
                    browser,
                    "--headless=new",
                    "--no-sandbox",
                    "--no-first-run",
                    "--test-type",
                    f"--user-data-dir={work / 'profile'}",
                    f"--remote-debugging-port={devtools}",
                    "--remote-debugging-address=127.0.0.1",
                    "--use-angle=swiftshader",
                    "--enable-unsafe-swiftshader",
                    "--ignore-gpu-blocklist",
                    "--disable-dev-shm-usage",
                    f"--window-size={size[0]},{size[1]}",
                    url,
                ],
                stdout=subprocess.DEVNULL,
                stderr=open(work / "chromium.log", "w"),
                start_new_session=True,
            )
        )

        def pages():
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{devtools}/json", timeout=2) as r:
                    return [p for p in json.load(r) if p.get("type") == "page"]
            except OSError:
                return []

        _wait_for(lambda: bool(pages()), 60, "Chromium's DevTools endpoint")
        time.sleep(wait)  # the viewer loads its wasm, then the recording
        png = _cdp_screenshot(pages()[0]["webSocketDebuggerUrl"], *size)
        out.write_bytes(png)
    finally:
        for p in procs:
            try:
                os.killpg(p.pid, 15)
            except (ProcessLookupError, PermissionError):
                pass
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, 9)
        shutil.rmtree(work, ignore_errors=True)
    return out


def lessons(chromium=None, wait=40.0, size=(1400, 800)):
    """Screenshot each lesson's recording (``out/notebooks/NN_*.rrd``) for its page."""
    notebooks = {p.stem[:2]: p.stem for p in (ROOT / "notebooks" / "src").glob("[0-9][0-9]_*.py")}
    out_dir = ROOT / "docs" / "notebooks" / "recordings"
    for rrd in sorted((ROOT / "out" / "notebooks").glob("[0-9][0-9]_*.rrd")):
        name = notebooks.get(rrd.stem[:2])
        if name is not None:
            print("wrote", screenshot(rrd, out_dir / f"{name}.png", chromium, wait, size))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("rrd", nargs="?", help="recording (.rrd)")
    p.add_argument("out", nargs="?", help="PNG to write")
    p.add_argument(
        "--lessons",
        action="store_true",
        help="screenshot the lessons' recordings (docs/notebooks/recordings/*.png)",
    )
    p.add_argument("--chromium", help="Chromium executable (default: found on PATH)")
    p.add_argument(
        "--wait",
        type=float,
        default=40.0,
        help="seconds to let the viewer load before the capture (default 40)",
    )
    p.add_argument("--size", default="1600x1000", help="WIDTHxHEIGHT (default 1600x1000)")
    a = p.parse_args(argv)
    if a.lessons:
        lessons(a.chromium, a.wait)
        return 0
    if not (a.rrd and a.out):
        p.error("give RECORDING.rrd OUT.png, or --lessons")
    w, h = (int(x) for x in a.size.lower().split("x"))
    print("wrote", screenshot(a.rrd, a.out, a.chromium, a.wait, (w, h)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
