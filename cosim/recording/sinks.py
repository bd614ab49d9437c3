"""Where a recording goes: always its file, and at most one viewer; never an unbounded wait.

Viewer choices (:class:`ViewerOptions`, the ``cosim`` flags in brackets; they follow rerun's
script conventions, ``rr.script_add_args``):

``save`` (default, ``--save [PATH]``, ``--headless``)
    the file only.
``spawn`` (``--spawn``)
    also start a native viewer and stream to it. Needs a display; without one (no ``DISPLAY``
    or ``WAYLAND_DISPLAY``) no viewer is started and a warning says so.
``connect`` (``--connect [URL]``, ``--url URL``)
    also stream to a viewer that is already running.
``serve`` (``--serve``, ``--serve-web``)
    also host the stream over gRPC and a web viewer on this machine; the process keeps serving
    after the run until it is interrupted (Ctrl-C).
``stdout`` (``--stdout``)
    the finished file is written to standard output after the run (rerun's ``--stdout`` streams
    live; a run also keeps its file, and a file sink cannot be teed with stdout in rerun 0.41).

A viewer that cannot be reached is *checked before* it becomes a sink (a TCP connection with a
timeout), because rerun's gRPC sink blocks ``send`` for seconds and ``flush`` without limit while
it retries (found here: a run with ``--connect`` to a closed port never ended). The stream then
goes to the file alone, with a warning naming the URL. Flushing to a viewer that goes away later
is bounded by ``timeout_s``; rerun's own disconnect waits at most 5 s for a last attempt.

Owns: the file and at most one viewer, with bounded waits. Boundaries: never waits without a
bound.
"""
from __future__ import annotations

import contextlib
import ctypes
import ipaddress
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote, urlparse

from ..files import clear_link
from ..children import stop_process

VIEWERS = ("save", "spawn", "connect", "serve", "none")
DEFAULT_URL = "rerun+http://127.0.0.1:9876/proxy"
#: The servers of --serve listen here unless --serve-address names another address.
LOCALHOST = "127.0.0.1"
SCHEMES = ("rerun", "rerun+http", "rerun+https")
log = logging.getLogger("cosim.recording")


@dataclass(frozen=True)
class ViewerOptions:
    """How a recording is shown besides its file (see the module docstring)."""

    viewer: str = "save"
    url: str | None = None          # connect: the running viewer's address
    stdout: bool = False
    timeout_s: float = 5.0          # connecting to and flushing to a viewer
    grpc_port: int = 9876           # spawn and serve
    web_port: int = 9090            # serve
    bind: str = LOCALHOST           # serve: the address the servers listen on (this machine only)

    def __post_init__(self):
        if self.viewer not in VIEWERS:
            raise ValueError(f"viewer must be one of {', '.join(VIEWERS)}, got {self.viewer!r}")
        if self.viewer == "connect":
            viewer_address(self.url or DEFAULT_URL)
        try:
            ipaddress.ip_address(self.bind)
        except ValueError:
            raise ValueError(f"--serve-address {self.bind!r}: not an IP address (127.0.0.1 serves this machine "
                             "only; 0.0.0.0 every network interface)") from None
        if not (isinstance(self.timeout_s, (int, float)) and self.timeout_s > 0):
            raise ValueError(f"viewer timeout must be a positive number of seconds, got {self.timeout_s!r}")

    @property
    def connect_url(self) -> str:
        return self.url or DEFAULT_URL

    @property
    def served_host(self) -> str:
        """Where this machine reaches the servers: the bind address, or localhost for a wildcard."""
        return LOCALHOST if ipaddress.ip_address(self.bind).is_unspecified else self.bind

    @property
    def served_url(self) -> str:
        """The gRPC address of ``serve`` as this machine reaches it."""
        return f"rerun+http://{self.served_host}:{self.grpc_port}/proxy"

    @property
    def exposed(self) -> bool:
        """Whether the servers listen beyond this machine (any address but a loopback one)."""
        return not ipaddress.ip_address(self.bind).is_loopback


def viewer_address(url: str) -> tuple:
    """(host, port) of a viewer URL ``rerun+http://host:port/proxy``; an error names ``--connect``."""
    p = urlparse(str(url))
    if p.scheme not in SCHEMES or not p.hostname or p.port is None:
        raise ValueError(f"--connect {url!r}: expected a rerun viewer URL such as {DEFAULT_URL} "
                         f"(scheme {', '.join(SCHEMES)}, a host and a port)")
    return p.hostname, p.port


def reachable(host: str, port: int, timeout_s: float) -> bool:
    """Whether something accepts TCP connections at host:port within ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with socket.create_connection((host, port), timeout=max(0.05, min(1.0, deadline - time.monotonic()))):
                return True
        except OSError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.1)


def rerun_executable() -> str | None:
    """The ``rerun`` viewer binary of the installed rerun-sdk (``rerun_cli/rerun``: the script
    ``.venv/bin/rerun`` only wraps it in a second process, which a terminate would not stop),
    else the script next to this Python, else ``rerun`` on PATH."""
    try:
        import rerun_cli
        binary = Path(rerun_cli.__file__).with_name("rerun")
        if binary.exists():
            return str(binary)
    except ImportError:
        pass
    here = Path(sys.executable).with_name("rerun")
    return str(here) if here.exists() else shutil.which("rerun")


def attach(rec, file_path, options: ViewerOptions) -> list:
    """Give ``rec`` its sinks: the file (if any) and the viewer the options ask for, if it can be
    reached. Returns the viewer URLs attached (empty: the file alone)."""
    import rerun as rr
    if file_path is not None:
        Path(file_path).parent.mkdir(parents=True, exist_ok=True)
    sinks = [rr.FileSink(str(clear_link(file_path)))] if file_path is not None else []
    urls = []
    if options.viewer == "spawn":
        url = f"rerun+http://127.0.0.1:{options.grpc_port}/proxy"
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            log.warning("--spawn: no display (DISPLAY and WAYLAND_DISPLAY are unset), so no viewer was started; "
                        "the recording goes to %s only (--serve shows it in a browser)", file_path)
        else:
            exe = rerun_executable()
            rr.spawn(port=options.grpc_port, connect=False, hide_welcome_screen=True, recording=rec,
                     **({"executable_path": exe} if exe else {}))
            # A viewer that cannot open a window listens for a moment and exits: check it stays.
            if reachable("127.0.0.1", options.grpc_port, options.timeout_s) and (time.sleep(0.5) or
                                                                                  reachable("127.0.0.1", options.grpc_port, 0.5)):
                urls.append(url)
            else:
                log.warning("--spawn: the rerun viewer did not start listening at %s within %g s; the recording goes "
                            "to %s only", url, options.timeout_s, file_path)
    elif options.viewer == "connect":
        url = options.connect_url
        if reachable(*viewer_address(url), options.timeout_s):
            urls.append(url)
        else:
            log.warning("--connect: no rerun viewer answers at %s (waited %g s); the recording goes to %s only",
                        url, options.timeout_s, file_path)
    if options.viewer in ("spawn", "connect"):
        sinks += [rr.GrpcSink(u) for u in urls]
    elif options.viewer == "serve":
        try:
            sinks.append(rr.GrpcServerSink(bind_ip=options.bind, port=options.grpc_port))
        except Exception as exc:       # e.g. the port is taken
            log.warning("--serve: cannot serve on port %d (%s); the recording goes to %s only",
                        options.grpc_port, exc, file_path)
        else:
            url = options.served_url
            # The SDK's own web server listens on every interface and takes no address (rerun
            # issue 5882): the viewer binary serves the page instead, bound as asked.
            start_web_viewer(options, url)
            urls.append(url)
            announce_serving("the recording", options, url)
    rec.set_sinks(*sinks)
    return urls


def web_viewer_address(options: ViewerOptions, grpc_url: str) -> str:
    """The browser address of the web viewer served on ``options.web_port`` showing the stream
    at ``grpc_url``."""
    return f"http://{options.served_host}:{options.web_port}/?url={quote(grpc_url, safe='')}"


def announce_serving(what: str, options: ViewerOptions, grpc_url: str, tail: str = "") -> None:
    """Say where the served recording is, on stderr, and who can reach it. Printed, not logged:
    ``-q`` (logging at WARNING) must still show it, as it is the one thing a user of ``--serve``
    needs."""
    reach = (f"listening on {options.bind}: anyone on the network can read this recording" if options.exposed
             else "this machine only")
    print(f"serving {what} ({reach}): open {web_viewer_address(options, grpc_url)} in a browser, or run "
          f"`rerun {grpc_url}`{tail}", file=sys.stderr, flush=True)


PR_SET_PDEATHSIG = 1          # linux/prctl.h


def _end_with_parent() -> None:
    """In a server's child process before it starts (Linux): SIGTERM when the process that
    started it ends, however it ends (SIGKILL included), so no listener outlives its run."""
    with contextlib.suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


# A server's process ends with the process that started it (Linux; elsewhere the watchdogs of
# the run and the recorder are all there is).
_SERVER_START = {"preexec_fn": _end_with_parent} if sys.platform.startswith("linux") else {}


def start_web_viewer(options: ViewerOptions, grpc_url: str):
    """The web viewer's page served by the rerun binary on ``options.bind``:``options.web_port``
    for the stream at ``grpc_url`` (a web server only: the data stays with its gRPC server).
    Returns the process (it ends with this one), or None with a warning when it cannot start."""
    exe = rerun_executable()
    if exe is None:
        log.warning("--serve: no `rerun` executable found to serve the web viewer; connect a viewer to %s", grpc_url)
        return None
    proc = subprocess.Popen([exe, "--serve-web", "--bind", options.bind, "--web-viewer-port", str(options.web_port),
                             grpc_url], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, **_SERVER_START)
    if not reachable(options.served_host, options.web_port, options.timeout_s):
        log.warning("--serve: the web viewer did not start on port %d within %g s; connect a viewer to %s",
                    options.web_port, options.timeout_s, grpc_url)
    return proc


def finish(rec, urls: list, timeout_s: float) -> list:
    """Flush (bounded by ``timeout_s`` when a viewer is attached) and close every sink; the file
    gets its footer. Returns warnings (a viewer that did not take everything)."""
    warnings = []
    try:
        rec.flush(timeout_sec=timeout_s if urls else 1e9)
    except RuntimeError as exc:
        if urls:                        # the viewer went away or is too slow: the file is still finished
            warnings.append(f"the viewer at {', '.join(urls)} did not take the whole recording within "
                            f"{timeout_s:g} s ({exc}); the file is complete")
        else:                           # the file itself failed (a full disk, a file-size limit)
            warnings.append(f"the recording file could not be written whole ({exc}): it is cut short")
    rec.disconnect()                    # closes the file (footer) and the gRPC connections
    return warnings


def serve_until_interrupted(parent: int | None = None) -> None:
    """Keep this process (and its gRPC and web servers) alive until Ctrl-C or SIGTERM, or until
    the process ``parent`` is gone (a child never outlives the run that started it)."""
    try:
        while parent is None or os.getppid() == parent:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass


def show_file(path, options: ViewerOptions, save_copy=None) -> list:
    """Show a finished recording file as ``options`` say (the sweep and uncertainty recordings,
    written when their results are complete): ``spawn`` starts a viewer on the file, ``connect``
    sends it to a running viewer (``log_file_from_path`` forwards the data and the layout),
    ``serve`` hosts it with ``rerun --serve-web`` until Ctrl-C, ``stdout`` writes it to standard
    output; ``save_copy``: also copy it there. Returns warnings (also logged)."""
    warnings = []
    if save_copy:
        shutil.copyfile(path, clear_link(save_copy))
    exe = rerun_executable()
    if options.viewer in ("spawn", "serve") and exe is None:
        warnings.append(f"--{options.viewer}: no `rerun` executable found; open {path} yourself")
    elif options.viewer == "spawn":
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            warnings.append(f"--spawn: no display (DISPLAY and WAYLAND_DISPLAY are unset); open {path} elsewhere, or "
                            "use --serve to view it in a browser")
        else:
            subprocess.Popen([exe, str(path)], start_new_session=True, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    elif options.viewer == "connect":
        url = options.connect_url
        if not reachable(*viewer_address(url), options.timeout_s):
            warnings.append(f"--connect: no rerun viewer answers at {url} (waited {options.timeout_s:g} s); "
                            f"the recording is in {path}")
        else:
            import rerun as rr
            from rerun.chunk import RrdReader
            store = RrdReader(str(path)).recordings()[0]
            rec = rr.RecordingStream(store.application_id, recording_id=store.recording_id)
            rec.set_sinks(rr.GrpcSink(url))
            rec.log_file_from_path(str(path))
            warnings += finish(rec, [url], options.timeout_s)
    elif options.viewer == "serve":
        url = options.served_url
        announce_serving(str(path), options, url, "; Ctrl-C stops")
        proc = subprocess.Popen([exe, "--serve-web", str(path), "--bind", options.bind, "--port", str(options.grpc_port),
                                 "--web-viewer-port", str(options.web_port)], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, **_SERVER_START)
        try:
            proc.wait()
        except KeyboardInterrupt:
            pass
        finally:
            stop_process(proc, grace_s=10)
    if options.stdout:
        copy_to_stdout(path)
    for w in warnings:
        log.warning("%s", w)
    return warnings


def copy_to_stdout(path) -> None:
    """The finished recording file to standard output (pipe it into ``rerun -``)."""
    out = sys.stdout.buffer
    with open(path, "rb") as f:
        shutil.copyfileobj(f, out)
    out.flush()
