"""The recording flags of ``cosim run``, ``sweep`` and ``uncertainty`` (argparse), after rerun's
script conventions (``rr.script_add_args`` in rerun 0.41: ``--headless``, ``--connect``,
``--serve``, ``--url``, ``--save PATH``, ``--stdout``), with the bench's differences said in
``--help``:

* the recording file is always written (``--save`` without PATH: the default file; rerun's
  ``--save`` needs a path and replaces the viewer);
* ``--connect`` takes the URL as an optional value (``--url URL`` works too, as in rerun);
* ``--serve`` is also spelled ``--serve-web`` (the rerun viewer's flag); no browser is opened,
  the address is printed;
* ``--stdout`` writes the finished file after the run, not a live stream, and the tables go to
  stderr;
* ``--headless`` is the default (rerun's scripts spawn a viewer unless told otherwise).

Owns: the viewer flags (argparse) and ``ViewerOptions`` from them. Boundaries: no recording.
"""
from __future__ import annotations

from pathlib import Path

from .sinks import DEFAULT_URL, LOCALHOST, ViewerOptions

VIEWER_FLAGS = ("--save", "--overwrite", "--headless", "--spawn", "--connect", "--url", "--serve", "--serve-web",
                "--serve-address", "--stdout", "--no-record", "--viewer-timeout")


def add_viewer_arguments(parser, file: str, run: bool = False) -> None:
    """The viewer flags; ``file``: the recording's default file name (run.rrd, sweep.rrd, ...)."""
    g = parser.add_argument_group("recording and viewer (rerun's script flags; the file is always written)")
    g.add_argument("--save", nargs="?", const="", default=None, metavar="PATH",
                   help=f"write the recording to PATH {'instead of' if run else 'as well as'} <folder>/{file} "
                        f"(without PATH: {file}, the default)")
    view = g.add_mutually_exclusive_group()
    view.add_argument("--headless", dest="viewer", action="store_const", const="save",
                      help="no viewer: the file only (the default here; rerun's scripts spawn one unless told)")
    view.add_argument("--spawn", dest="viewer", action="store_const", const="spawn",
                      help="also start a native rerun viewer" + (" and stream to it" if run else " on the file") +
                           " (needs a display)")
    view.add_argument("--connect", dest="connect", nargs="?", const=DEFAULT_URL, metavar="URL",
                      help=f"also {'stream' if run else 'send the file'} to a running rerun viewer (default URL "
                           f"{DEFAULT_URL}); an unreachable one is a warning after --viewer-timeout, never a hang")
    view.add_argument("--serve", "--serve-web", dest="viewer", action="store_const", const="serve",
                      help="also serve the recording over gRPC and a web viewer (ports 9876, 9090) to this machine "
                           "only; prints the address, keeps serving after the run until Ctrl-C")
    view.add_argument("--no-record", dest="viewer", action="store_const", const="none",
                      help="no rerun recording at all")
    g.add_argument("--overwrite", action="store_true",
                   help="let --save PATH replace an existing file (by default an existing file is refused)")
    g.add_argument("--serve-address", metavar="IP", default=LOCALHOST,
                   help=f"with --serve: the address its servers listen on (default {LOCALHOST}, this machine only; "
                        "0.0.0.0 exposes the recording to everyone on the network)")
    g.add_argument("--url", metavar="URL", help="the viewer URL for --connect (rerun's spelling; implies --connect)")
    g.add_argument("--stdout", action="store_true",
                   help="write the finished recording to stdout after the run (pipe into `rerun -`); the tables "
                        "then go to stderr (rerun streams live; a file sink cannot be teed to stdout in rerun 0.41)")
    g.add_argument("--viewer-timeout", type=float, default=5.0, metavar="S",
                   help="seconds to wait for a viewer to answer or to take the data (default 5)")
    if run:
        g.add_argument("--exaggeration", type=float, default=None,
                       help="factor on each link's deformation in the linkage drawing (default: chosen from the "
                            "largest deformation, said in the view's title)")
        g.add_argument("--linkage-fps", type=float, default=60.0, metavar="FPS",
                       help="linkage frames per simulated second in the recording (default 60, display rate; "
                            "strains and torques keep every sample)")
        g.add_argument("--animation", action="store_true",
                       help="also write linkage.gif, an animation of the last revolution (matplotlib)")


def viewer_from_args(args) -> tuple:
    """(ViewerOptions or None for --no-record, the --save path or None); errors name the flag."""
    connect = getattr(args, "connect", None)
    url = getattr(args, "url", None)
    viewer = getattr(args, "viewer", None)
    if url is not None:
        if connect not in (None, DEFAULT_URL, url):
            raise ValueError(f"--connect {connect} and --url {url}: give the viewer's URL once")
        if viewer not in (None, "save") and viewer != "connect":
            raise ValueError(f"--url {url} is for --connect; it cannot go with --{viewer}")
        connect = url
    if connect is not None:
        viewer = "connect"
    viewer = viewer or "save"
    save = getattr(args, "save", None)
    stdout = bool(getattr(args, "stdout", False))
    if viewer == "none":
        for flag, given in (("--save PATH", bool(save)), ("--stdout", stdout)):
            if given:
                raise ValueError(f"{flag} writes a recording; it cannot go with --no-record")
        return None, None
    if save:
        _check_save_path(Path(save), bool(getattr(args, "overwrite", False)))
    timeout = getattr(args, "viewer_timeout", 5.0)
    if not (timeout and timeout > 0):
        raise ValueError(f"--viewer-timeout must be a positive number of seconds, got {timeout!r}")
    bind = getattr(args, "serve_address", LOCALHOST)
    if bind != LOCALHOST and viewer != "serve":
        raise ValueError(f"--serve-address {bind}: is the address of --serve's servers; it needs --serve")
    return (ViewerOptions(viewer, url=connect, stdout=stdout, timeout_s=timeout, bind=bind),
            Path(save) if save else None)


def _check_save_path(path: Path, overwrite: bool) -> None:
    """``--save PATH`` writes a rerun recording: PATH must name a ``.rrd`` file (so it can never be
    a run's traces.csv or summary.json) and must not exist unless ``--overwrite`` is given."""
    if path.suffix != ".rrd":
        raise ValueError(f"--save {path}: a recording is written to a .rrd file; give a path ending in .rrd")
    if path.is_dir():
        raise ValueError(f"--save {path}: is a folder; give a file path ending in .rrd")
    if (path.exists() or path.is_symlink()) and not overwrite:
        raise ValueError(f"--save {path}: already exists; give another path, or --overwrite to replace it")
