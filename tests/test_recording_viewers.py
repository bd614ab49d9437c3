"""Where a run's recording goes (cosim.recording.sinks, options, process): rerun's script flags on
``cosim run``, never a hang on a viewer that is not there, a real viewer receiving the stream,
stdout, --save PATH, --serve, and the files for the engines' own tools."""
import json
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from cosim.recording import read_back

ROOT = Path(__file__).resolve().parent.parent
COSIM = [sys.executable, "-m", "cosim.cli"]
SMALL = ["run", "crank_rocker_95rpm", "--engines", "tmm", "--revolutions", "0.25"]


def cosim(*args, timeout=300):
    return subprocess.run(COSIM + list(args), capture_output=True, cwd=ROOT, timeout=timeout)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def summary(folder):
    return json.loads((Path(folder) / "summary.json").read_text())


def test_connect_to_no_viewer_ends_with_a_warning_and_a_complete_file(tmp_path):
    url = f"rerun+http://127.0.0.1:{free_port()}/proxy"          # nothing listens there
    tic = time.monotonic()
    res = cosim(*SMALL, "--connect", url, "--viewer-timeout", "1", "--out", str(tmp_path / "r"), timeout=120)
    elapsed = time.monotonic() - tic
    err = res.stderr.decode()
    assert res.returncode == 0, err[-2000:]
    assert f"warning: --connect: no rerun viewer answers at {url}" in err
    assert elapsed < 60                                 # a hang was the bug: it never ended
    assert summary(tmp_path / "r")["status"] == "completed"
    assert read_back(tmp_path / "r" / "run.rrd")["/tmm/strain/coupler_mid"] > 10


@pytest.mark.filterwarnings("ignore:RRD file has no footer")      # the stand-in viewer is stopped, not closed
def test_connect_streams_to_a_running_viewer(tmp_path):
    """A headless rerun that saves what it receives stands in for the viewer."""
    from cosim.recording.sinks import reachable, rerun_executable
    port = free_port()
    received = tmp_path / "received.rrd"
    viewer = subprocess.Popen([rerun_executable(), "--port", str(port), "--save", str(received)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert reachable("127.0.0.1", port, 20.0)
        res = cosim(*SMALL, "--url", f"rerun+http://127.0.0.1:{port}/proxy", "--out", str(tmp_path / "r"))
        assert res.returncode == 0, res.stderr.decode()[-2000:]
        assert "warning" not in res.stderr.decode()
    finally:
        viewer.terminate()
        viewer.wait(timeout=30)
    mine = read_back(tmp_path / "r" / "run.rrd")
    theirs = read_back(received)
    assert theirs["/tmm/strain/coupler_mid"] == mine["/tmm/strain/coupler_mid"] > 10


def test_save_elsewhere_and_stdout(tmp_path):
    """--save PATH puts the recording there (named in the summary); --stdout writes it to stdout
    after the run, and the tables go to stderr."""
    target = tmp_path / "elsewhere" / "mine.rrd"
    res = cosim(*SMALL, "--save", str(target), "--stdout", "--out", str(tmp_path / "r"))
    assert res.returncode == 0, res.stderr.decode()[-2000:]
    assert summary(tmp_path / "r")["files"]["recording"] == str(target.resolve())
    assert not (tmp_path / "r" / "run.rrd").exists()
    assert read_back(target)["/tmm/strain/coupler_mid"] > 10
    assert res.stdout == target.read_bytes()
    assert b"written to" in res.stderr and b"coupler_mid" in res.stderr


@pytest.mark.parametrize("flags, message", [
    (["--url", "rerun+http://127.0.0.1:1/proxy", "--spawn"], "--url"),
    (["--connect", "http://127.0.0.1:9876"], "--connect 'http://127.0.0.1:9876'"),
    (["--no-record", "--stdout"], "--stdout"),
    (["--linkage-fps", "0"], "--linkage-fps"),
    (["--exaggeration", "-2"], "--exaggeration"),
    (["--viewer-timeout", "0"], "--viewer-timeout"),
])
def test_bad_viewer_flags_are_refused_naming_the_flag(tmp_path, flags, message):
    res = cosim(*SMALL, *flags, "--out", str(tmp_path / "r"))
    err = res.stderr.decode()
    assert res.returncode == 2 and err.startswith("error: ") and message in err, err


def test_rerun_script_flags_in_help():
    for sub in ("run", "sweep", "uncertainty"):
        text = cosim(sub, "--help").stdout.decode()
        for flag in ("--save", "--headless", "--spawn", "--connect", "--url", "--serve", "--serve-web", "--stdout",
                     "--no-record", "--viewer-timeout"):
            assert flag in text, (sub, flag)
    assert "--linkage-fps" in cosim("run", "--help").stdout.decode()


def test_serve_hosts_a_web_viewer_until_stopped(tmp_path):
    from cosim.recording import RecorderProcess, ViewerOptions
    from cosim.scenario import load
    from tests.test_recording import fake_steps, stations_of
    sc = load("crank_rocker_373rpm")
    grpc, web = free_port(), free_port()
    engines = stations_of(sc)
    rec = RecorderProcess(sc, engines, "prescribed", save_path=tmp_path / "run.rrd",
                          viewer=ViewerOptions("serve", grpc_port=grpc, web_port=web))
    try:
        for step in fake_steps(sc, engines, motor=False):
            rec.log_macro_step(step)
        assert rec.close() == []
        assert rec.serving == f"rerun+http://127.0.0.1:{grpc}/proxy"
        with urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=20) as page:
            assert page.status == 200 and b"Rerun" in page.read()
        if LISTENERS.exists():          # both servers listen on this machine only, never 0.0.0.0
            assert listening(grpc) == {"127.0.0.1"} and listening(web) == {"127.0.0.1"}
    finally:
        rec.stop_serving()
    assert read_back(tmp_path / "run.rrd")["/tmm/strain/coupler_mid"] > 10
    if LISTENERS.exists():              # and stop with the recording
        deadline = time.monotonic() + 10
        while (listening(grpc) or listening(web)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not listening(grpc) and not listening(web)


LISTENERS = Path("/proc/net/tcp")


def listening(port: int) -> set:
    """The IPv4 addresses a TCP port is listening on (Linux's /proc/net/tcp; state 0A = LISTEN)."""
    found = set()
    for line in LISTENERS.read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        host, hex_port = local.split(":")
        if state == "0A" and int(hex_port, 16) == port:
            found.add(socket.inet_ntoa(bytes.fromhex(host)[::-1]))
    return found


def test_serve_address_must_go_with_serve_and_be_an_address(tmp_path):
    res = cosim(*SMALL, "--serve-address", "0.0.0.0", "--out", str(tmp_path / "a"))
    assert res.returncode == 2 and b"needs --serve" in res.stderr
    res = cosim(*SMALL, "--serve", "--serve-address", "my-laptop", "--out", str(tmp_path / "b"))
    assert res.returncode == 2 and b"not an IP address" in res.stderr


def test_model_files_for_the_engines_own_tools(tmp_path):
    """MuJoCo's MJCF and exudyn's solution file in the run folder, named in the summary."""
    import exudyn.utilities as eu
    import mujoco
    res = cosim("run", "crank_rocker_95rpm", "--engines", "exudyn,mujoco", "--revolutions", "0.1", "--no-record",
                "--out", str(tmp_path / "r"))
    assert res.returncode == 0, res.stderr.decode()[-2000:]
    files = summary(tmp_path / "r")["files"]
    assert files["mujoco_model"] == "model.xml" and files["exudyn_solution"] == "exudyn_solution.txt"
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "r" / "model.xml"))
    assert model.ngeom > 0 and np.all(model.geom_contype == 0)       # visual capsules only
    solution = eu.LoadSolutionFile(str(tmp_path / "r" / "exudyn_solution.txt"), verbose=False)
    assert solution["nRows"] > 10 and solution["columnsExported"][0] > 0


def test_spawn_without_a_display_says_so_and_records(tmp_path):
    import os
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run(COSIM + SMALL + ["--spawn", "--out", str(tmp_path / "r")], capture_output=True, cwd=ROOT,
                         timeout=300, env=env)
    assert res.returncode == 0 and b"warning: --spawn: no display" in res.stderr, res.stderr.decode()[-2000:]
    assert read_back(tmp_path / "r" / "run.rrd")["/tmm/strain/coupler_mid"] > 10


def test_the_writer_process_imports_this_cosim_whatever_the_working_directory(tmp_path, monkeypatch):
    """A run started in a folder holding another ``cosim`` package (another checkout) still records:
    the child process does not put the working directory first on its path."""
    from cosim.recording import RecorderProcess
    from cosim.scenario import load
    from tests.test_recording import fake_steps, stations_of
    other = tmp_path / "elsewhere" / "cosim"
    (other / "recording").mkdir(parents=True)
    (other / "__init__.py").write_text("raise ImportError('the wrong cosim was imported')\n")
    (other / "recording" / "__init__.py").write_text("")
    monkeypatch.chdir(tmp_path / "elsewhere")
    sc = load("crank_rocker_373rpm")
    engines = stations_of(sc)
    rec = RecorderProcess(sc, engines, "prescribed", save_path=tmp_path / "run.rrd")
    for step in fake_steps(sc, engines, motor=False):
        rec.log_macro_step(step)
    assert rec.close() == []
    assert read_back(tmp_path / "run.rrd")["/tmm/strain/coupler_mid"] > 10


# -- issue 31: `-q --serve-web` still prints the viewer's address ----------------------------------
# Rerun's servers are replaced by stand-ins: these tests open no port.
WEB_ADDRESS = "http://127.0.0.1:9090/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9876%2Fproxy"


class _Stream:
    """A stand-in for a rerun RecordingStream: keeps the sinks it is given."""
    sinks = ()

    def set_sinks(self, *sinks):
        self.sinks = sinks


def test_quiet_serve_of_a_run_still_prints_the_address(monkeypatch, capsys):
    import rerun as rr

    from cosim.cli import setup_logging
    from cosim.recording.sinks import ViewerOptions, attach
    from cosim.recording import sinks
    served = []
    monkeypatch.setattr(rr, "GrpcServerSink", lambda bind_ip, port: ("grpc server", bind_ip, port))
    monkeypatch.setattr(sinks, "start_web_viewer", lambda options, url: served.append((options, url)))
    setup_logging(quiet=True)
    try:
        urls = attach(_Stream(), None, ViewerOptions("serve"))
    finally:
        setup_logging()
    assert urls == ["rerun+http://127.0.0.1:9876/proxy"] and served[0][0].web_port == 9090
    assert WEB_ADDRESS in capsys.readouterr().err


def test_quiet_serve_of_a_sweep_file_still_prints_the_address(monkeypatch, capsys, tmp_path):
    from cosim.cli import setup_logging
    from cosim.recording import sinks
    started = []

    class Viewer:                          # `rerun --serve-web FILE` that ends at once
        def __init__(self, argv, **kw):
            started.append(argv)

        def wait(self, timeout=None):
            return 0

        def poll(self):
            return 0
    monkeypatch.setattr(sinks, "rerun_executable", lambda: "rerun")
    monkeypatch.setattr(subprocess, "Popen", Viewer)
    setup_logging(quiet=True)
    try:
        assert sinks.show_file(tmp_path / "sweep.rrd", sinks.ViewerOptions("serve")) == []
    finally:
        setup_logging()
    assert started and "--serve-web" in started[0]
    assert WEB_ADDRESS in capsys.readouterr().err


@pytest.mark.skipif(not LISTENERS.exists(), reason="needs Linux /proc/net/tcp")
def test_a_served_file_stops_listening_when_its_command_is_killed(tmp_path):
    """`cosim sweep --serve` hosts its file with the rerun binary; a SIGKILL of the command used
    to leave that server listening. It ends with its parent now (and listens on localhost)."""
    import signal

    import rerun as rr
    path = tmp_path / "tiny.rrd"
    rec = rr.RecordingStream("flexlink-bench-test", recording_id="tiny")
    rec.set_sinks(rr.FileSink(str(path)))
    rec.log("x", rr.Scalars([1.0]))
    rec.disconnect()
    grpc, web = free_port(), free_port()
    code = ("import sys\nfrom pathlib import Path\nfrom cosim.recording.sinks import ViewerOptions, show_file\n"
            f"show_file(Path({str(path)!r}), ViewerOptions('serve', grpc_port={grpc}, web_port={web}))\n")
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not listening(web) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert listening(web) == {"127.0.0.1"} and listening(grpc) == {"127.0.0.1"}
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        deadline = time.monotonic() + 10
        while (listening(web) or listening(grpc)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not listening(web) and not listening(grpc)
    finally:
        if proc.poll() is None:
            proc.kill()
