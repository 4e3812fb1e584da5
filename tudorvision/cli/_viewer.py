"""Where a long command's rerun recording goes: ``--rerun FILE``, ``--rerun-live [ADDR]``, ``--rerun-web [PORT]``.

One :class:`Viewer` per run holds a ``rerun.RecordingStream`` whose sinks
are any of

* a file (``--rerun FILE``, or the command's own default file such as
  ``servo.rrd``),
* a native viewer: ``--rerun-live`` alone connects to a viewer already
  listening on 127.0.0.1:9876 or spawns one (when a display and the ``rerun``
  executable exist); ``--rerun-live ADDR`` (``HOST:PORT``, a port, or a
  ``rerun+http://HOST:PORT/proxy`` URL) connects to a running viewer,
* the web viewer (``--rerun-web [PORT]``): a ``rerun --serve-web`` process
  bound to 127.0.0.1 only (HTTP on PORT, default 9090, gRPC on a free port);
  the URL is printed and the server keeps serving after the run until Ctrl-C.

A viewer that cannot be reached or spawned is a one-line warning on stderr;
the run goes on and the file, if any, is still written. rerun is imported on
demand so ``--help`` stays fast. The matching viewer version is the SDK's own
(``rerun --version`` equals ``rerun.__version__``).
"""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from urllib.parse import quote, urlparse

from .._checks import TudorVisionError

__all__ = ["Viewer", "add_viewer_arguments", "open_viewer", "viewer_requested"]

DEFAULT_VIEWER_PORT = 9876
DEFAULT_WEB_PORT = 9090


def add_viewer_arguments(parser, *, file_help: str = "write a rerun recording (.rrd) of the run") -> None:
    """Add ``--rerun FILE``, ``--rerun-live [ADDR]`` and ``--rerun-web [PORT]`` to ``parser``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.
    file_help : str
        Help text of ``--rerun``.

    Returns
    -------
    None
    """
    parser.add_argument("--rerun", metavar="RRD", help=file_help)
    parser.add_argument("--rerun-live", nargs="?", const="", default=None, metavar="ADDR",
                        help="stream to a rerun viewer: alone, connect to one on 127.0.0.1:9876 or spawn one; "
                             "ADDR (HOST:PORT, PORT or rerun+http://HOST:PORT/proxy) connects to a running viewer. "
                             "The viewer must be rerun's SDK version (pip install rerun-sdk==<the installed one>)")
    parser.add_argument("--rerun-web", nargs="?", const=DEFAULT_WEB_PORT, default=None, type=int, metavar="PORT",
                        help=f"serve the rerun web viewer on http://127.0.0.1:PORT (loopback only; default "
                             f"{DEFAULT_WEB_PORT}); it keeps serving after the run until Ctrl-C")


def viewer_requested(args) -> bool:
    """True when any of ``--rerun``, ``--rerun-live``, ``--rerun-web`` was given.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of a command set up with :func:`add_viewer_arguments`.

    Returns
    -------
    bool
    """
    return bool(getattr(args, "rerun", None)) or getattr(args, "rerun_live", None) is not None \
        or getattr(args, "rerun_web", None) is not None


def _warn(msg: str) -> None:
    print(f"warning: {msg}", file=sys.stderr)


def _rerun():
    try:
        import rerun as rr
    except ImportError:
        raise TudorVisionError("--rerun/--rerun-live/--rerun-web need the rerun SDK: pip install rerun-sdk") from None
    return rr


def _viewer_executable() -> str | None:
    """The ``rerun`` viewer binary: the one of the installed SDK (``rerun_cli``), else ``rerun`` on PATH.

    The SDK's own binary comes first: it is the matching version, and it is
    the process itself (the ``rerun`` script on PATH is a Python wrapper
    whose child would outlive a terminate).
    """
    try:
        import rerun_cli
    except ImportError:
        rerun_cli = None
    if rerun_cli is not None:
        for name in ("rerun", "rerun.exe"):
            cand = Path(rerun_cli.__file__).parent / name
            if cand.is_file():
                return str(cand)
    return shutil.which("rerun")


def _port_open(host: str, port: int, timeout_s: float = 0.5) -> bool:
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return True
    except OSError:
        return False


def _free_loopback_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def grpc_url(addr: str) -> str:
    """A viewer address as rerun's gRPC URL: ``PORT``, ``HOST:PORT`` or a ``rerun+http://`` URL.

    Parameters
    ----------
    addr : str
        User input of ``--rerun-live``.

    Returns
    -------
    str
        ``rerun+http://HOST:PORT/proxy``.
    """
    a = addr.strip()
    if a.isdigit():
        return f"rerun+http://127.0.0.1:{int(a)}/proxy"
    if "://" in a:
        u = urlparse(a)
        if u.scheme not in ("rerun", "rerun+http", "rerun+https") or not u.hostname:
            raise TudorVisionError(f"--rerun-live: expected HOST:PORT, PORT or rerun+http://HOST:PORT/proxy, "
                                   f"got {addr!r}")
        return a
    host, sep, port = a.rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise TudorVisionError(f"--rerun-live: expected HOST:PORT, PORT or rerun+http://HOST:PORT/proxy, got {addr!r}")
    return f"rerun+http://{host}:{int(port)}/proxy"


class Viewer:
    """A run's rerun recording stream and the web viewer process serving it, if any.

    Parameters
    ----------
    recording : rerun.RecordingStream
        The stream the command logs to (:attr:`rec`).
    files : list of Path
        Files the stream writes.
    web_process : subprocess.Popen, optional
        The ``rerun --serve-web`` process.
    web_url : str, optional
        The printed web viewer URL.
    """

    def __init__(self, recording, files=(), web_process=None, web_url=None):
        self.rec = recording
        self.files = [Path(f) for f in files]
        self.web_process = web_process
        self.web_url = web_url

    def close(self, *, hold: bool = True) -> None:
        """Flush the stream; with a web viewer, keep serving until Ctrl-C, then stop it.

        Parameters
        ----------
        hold : bool
            Keep the web viewer serving until Ctrl-C (False stops it at once).

        Returns
        -------
        None
        """
        try:
            self.rec.flush()
        finally:
            try:
                if self.web_process is not None and hold and self.web_process.poll() is None:
                    try:
                        print(f"rerun web viewer keeps serving at {self.web_url} (Ctrl-C to stop)", flush=True)
                        # short waits, not one blocking waitpid: Ctrl-C delivered to one of rerun's threads does
                        # not interrupt the main thread's system call, only its next bytecode sees it
                        while self.web_process.poll() is None:
                            time.sleep(0.1)
                    except KeyboardInterrupt:
                        pass
            finally:
                self.rec.disconnect()
                if self.web_process is not None and self.web_process.poll() is None:
                    self.web_process.terminate()
                    try:
                        self.web_process.wait(timeout=5)
                    except subprocess.TimeoutExpired:
                        self.web_process.kill()
                        self.web_process.wait()
        for f in self.files:
            print(f"wrote {f}")


def _live_sink(rr, rec, addr: str):
    """The gRPC sink to a native viewer, or None (with a warning) when there is none to reach."""
    if addr:
        url = grpc_url(addr)
        u = urlparse(url)
        if not _port_open(u.hostname, u.port or DEFAULT_VIEWER_PORT):
            _warn(f"--rerun-live: no rerun viewer answers at {url}; continuing without the live view")
            return None
        print(f"rerun: streaming to the viewer at {url}")
        return rr.GrpcSink(url)
    url = f"rerun+http://127.0.0.1:{DEFAULT_VIEWER_PORT}/proxy"
    if _port_open("127.0.0.1", DEFAULT_VIEWER_PORT):
        print(f"rerun: streaming to the running viewer at {url}")
        return rr.GrpcSink(url)
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        _warn("--rerun-live: no display to open a rerun viewer on (headless); continuing without the live view "
              "(use --rerun-web PORT, or --rerun-live HOST:PORT of a running viewer)")
        return None
    exe = _viewer_executable()
    if exe is None:
        _warn("--rerun-live: no rerun viewer installed (pip install rerun-sdk); continuing without the live view")
        return None
    try:
        rr.spawn(port=DEFAULT_VIEWER_PORT, connect=False, executable_path=exe, recording=rec)
    except Exception as exc:  # noqa: BLE001 - any spawn failure is only a warning
        _warn(f"--rerun-live: could not spawn the rerun viewer ({exc}); continuing without the live view")
        return None
    if not _port_open("127.0.0.1", DEFAULT_VIEWER_PORT):
        _warn("--rerun-live: the spawned rerun viewer did not start; continuing without the live view")
        return None
    print(f"rerun: spawned a viewer, streaming to {url}")
    return rr.GrpcSink(url)


def _web_server(port: int):
    """Start ``rerun --serve-web`` on 127.0.0.1; return (process, grpc URL, page URL) or None with a warning."""
    if not 0 < port < 65536:
        raise TudorVisionError(f"--rerun-web: expected a port 1..65535, got {port}")
    exe = _viewer_executable()
    if exe is None:
        _warn("--rerun-web: no rerun executable found (pip install rerun-sdk); continuing without the web viewer")
        return None
    if _port_open("127.0.0.1", port):
        _warn(f"--rerun-web: port {port} is already in use on 127.0.0.1; continuing without the web viewer")
        return None
    gport = _free_loopback_port()
    proc = subprocess.Popen([exe, "--serve-web", "--bind", "127.0.0.1", "--port", str(gport),
                             "--web-viewer-port", str(port)],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    grpc = f"rerun+http://127.0.0.1:{gport}/proxy"
    page = f"http://127.0.0.1:{port}/?url={quote(grpc, safe='')}"
    deadline = time.monotonic() + 15.0
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=1.0) as r:
                if r.status == 200 and _port_open("127.0.0.1", gport):
                    return proc, grpc, page
        except OSError:
            pass
        time.sleep(0.1)
    if proc.poll() is None:
        proc.terminate()
        proc.wait()
    _warn(f"--rerun-web: the rerun web viewer did not start on 127.0.0.1:{port}; continuing without it")
    return None


def open_viewer(args, application_id: str, *, default_file=None) -> Viewer | None:
    """Open the rerun recording stream that ``--rerun``/``--rerun-live``/``--rerun-web`` ask for.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments (see :func:`add_viewer_arguments`).
    application_id : str
        rerun application id, e.g. ``"tudorvision_servo"``.
    default_file : str or Path, optional
        File the command always records to when ``--rerun`` is not given
        (e.g. ``servo.rrd`` of ``servo --sim``).

    Returns
    -------
    Viewer or None
        None when nothing was asked for, or when every sink failed (warned).
    """
    path = getattr(args, "rerun", None) or default_file
    live = getattr(args, "rerun_live", None)
    web = getattr(args, "rerun_web", None)
    if not path and live is None and web is None:
        return None
    rr = _rerun()
    rec = rr.RecordingStream(application_id)
    sinks, files, proc, page = [], [], None, None
    if path:
        p = Path(path)
        if p.is_dir():
            raise TudorVisionError(f"--rerun: {p} is a directory, expected a .rrd file")
        p.parent.mkdir(parents=True, exist_ok=True)
        sinks.append(rr.FileSink(str(p)))
        files.append(p)
    if live is not None:
        s = _live_sink(rr, rec, live)
        if s is not None:
            sinks.append(s)
    if web is not None:
        started = _web_server(int(web))
        if started is not None:
            proc, grpc, page = started
            sinks.append(rr.GrpcSink(grpc))
            print(f"rerun web viewer: {page}", flush=True)
    if not sinks:
        return None
    rec.set_sinks(*sinks)
    return Viewer(rec, files, proc, page)
