"""The recordings as a person sees them: rerun's web viewer in headless Chromium (opt-in:
``pytest -m browser``; skipped without Chromium, Debian's package ``chromium``).

Each recording is served with ``rerun --serve-web FILE`` on localhost and screenshotted; the plot
regions of the default layout must not be blank. Chromium's ``--screenshot`` fires at the page's
load event, long before the viewer (WebAssembly, software rendering) has drawn anything, so the
page shot is a wrapper: the viewer in an iframe plus a hidden image that this test's own server
answers only after ``WAIT_S`` seconds, which holds the load event back in real time.
"""
import http.server
import shutil
import subprocess
import threading
import time
from pathlib import Path
from urllib.parse import quote

import numpy as np
import pytest

pytestmark = pytest.mark.browser
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
WAIT_S = 25.0
WINDOW = (1600, 1000)


def free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Wrapper(http.server.BaseHTTPRequestHandler):
    viewer_url = ""

    def do_GET(self):
        if self.path.startswith("/slow"):
            time.sleep(WAIT_S)
            body, kind = b"GIF89a\x01\x00\x01\x00\x00\x00\x00;", "image/gif"
        else:
            body = (f'<html><body style="margin:0"><iframe src="{self.viewer_url}" style="border:0;width:100vw;'
                    f'height:100vh"></iframe><img src="/slow" style="display:none"></body></html>').encode()
            kind = "text/html"
        self.send_response(200)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


def screenshot(rrd: Path, png: Path, tmp: Path) -> np.ndarray:
    """The recording in rerun's web viewer, as an (h, w) grey image in [0, 1]."""
    from matplotlib.image import imread

    from cosim.recording.sinks import reachable, rerun_executable
    grpc, web = free_port(), free_port()
    server = subprocess.Popen([rerun_executable(), "--serve-web", str(rrd), "--port", str(grpc),
                               "--web-viewer-port", str(web)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    handler = type("Handler", (_Wrapper,), {"viewer_url": f"http://127.0.0.1:{web}/?url="
                                            + quote(f"rerun+http://127.0.0.1:{grpc}/proxy", safe="")})
    page = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=page.serve_forever, daemon=True).start()
    try:
        assert reachable("127.0.0.1", web, 30.0), "rerun --serve-web did not start"
        subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
                        "--disable-quic", "--no-first-run", "--disable-background-networking",
                        "--disable-component-update", "--disable-sync", f"--user-data-dir={tmp / 'chromium'}",
                        f"--screenshot={png}", f"--window-size={WINDOW[0]},{WINDOW[1]}",
                        f"http://127.0.0.1:{page.server_address[1]}/"],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=WAIT_S + 120, check=True)
    finally:
        page.shutdown()
        server.terminate()
        server.wait(timeout=30)
    image = imread(png)
    return image[..., :3].mean(axis=-1)


def assert_not_blank(image, regions: dict) -> None:
    """Each region (fractions x0, x1, y0, y1 of the window) holds a drawing: its pixels vary
    (a blank or loading panel is one flat colour) and some stand out from its background."""
    h, w = image.shape
    for name, (x0, x1, y0, y1) in regions.items():
        tile = image[int(y0 * h):int(y1 * h), int(x0 * w):int(x1 * w)]
        background = np.median(tile)
        drawn = np.mean(np.abs(tile - background) > 0.1)
        assert tile.std() > 0.02 and drawn > 0.005, f"{name}: blank (std {tile.std():.3f}, drawn {drawn:.4f})"


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium)")
    return tmp_path_factory.mktemp("browser")


def test_run_recording_shows_its_plots_and_the_linkage(work):
    from cosim.runs import RunOptions, run_scenario
    res = run_scenario("crank_rocker_95rpm", RunOptions(engines=("tmm", "mujoco"), revolutions=0.5, progress=False,
                                                        out=work / "run", figures=False))
    image = screenshot(work / "run" / "run.rrd", work / "run.png", work)
    # Layout (cosim.recording.blueprint): gauge plots on the left 3/5, the linkage top right.
    assert_not_blank(image, {"first gauge plot": (0.03, 0.58, 0.08, 0.33),
                             "second gauge plot": (0.03, 0.58, 0.42, 0.68),
                             "linkage": (0.62, 0.98, 0.08, 0.55)})
    assert res.summary["status"] == "completed"


def test_sweep_recording_shows_every_chart(work):
    """Two real sweep points; the natural-frequency map at 6 crank angles instead of the sweep's 36
    (minutes of eigenvalue searches on a busy machine), drawn by the sweep's own recorder."""
    from cosim.recording.summaries import sweep_recording
    from cosim.resonance import frequency_map
    from cosim.scenario import load
    from cosim.sweeps import run_sweep
    folder, summary = run_sweep("crank_rocker_95rpm", "90,100", ("tmm",), revolutions=0.5, workers=1,
                                out=work / "sweep", progress=False, record=False, resonance=False)
    fmap = frequency_map(load("crank_rocker_95rpm"), n_angles=6)
    sweep_recording(folder / "sweep.rrd", "crank_rocker_95rpm", summary["points"], fmap, (90.0, 100.0),
                    summary["records_peaks"])
    image = screenshot(folder / "sweep.rrd", work / "sweep.png", work)
    # Two columns of 2D charts: peaks and Floquet on the left, Campbell and frequencies on the right.
    assert_not_blank(image, {"peaks": (0.05, 0.45, 0.06, 0.30), "floquet": (0.05, 0.45, 0.72, 0.95),
                             "campbell": (0.55, 0.95, 0.06, 0.45), "frequencies": (0.55, 0.95, 0.55, 0.95)})


def test_uncertainty_recording_shows_the_band(work):
    from cosim.uncertainty import run_uncertainty
    folder, summary = run_uncertainty("crank_rocker_95rpm", samples=2, out=work / "band", progress=False,
                                      sensitivity=False, workers=1)
    image = screenshot(folder / "uncertainty.rrd", work / "band.png", work)
    assert_not_blank(image, {"first gauge": (0.2, 0.65, 0.08, 0.45), "second gauge": (0.2, 0.65, 0.55, 0.92)})
