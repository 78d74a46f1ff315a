"""``psvs serve``: the browser UI (FastAPI + uvicorn) on a complex image, a video, a camera or a simulated scene.

The command binds its listening socket itself and hands it to uvicorn, so an address that cannot be listened on
(a port in use, a host that does not resolve or is not this machine's) is refused in one line, exit 2, before
uvicorn starts. uvicorn's own log stays off the terminal: a request the app could not answer (an exception in
a route) is one line, ``psvs serve: internal error: ...``; ``PSVS_DEBUG=1`` shows uvicorn's log as it is.
"""
from __future__ import annotations

import asyncio
import errno
import logging
import os
import socket
import sys

from psvs.cli.camera_args import CAMERA_HELP, add_acquisition_arguments
from psvs.cli.common import add_rig_argument, load_scene_spec, rig_from_args
from psvs.io.images import read_grey


def add_parser(sub) -> None:
    p = sub.add_parser("serve", help="interactive web UI: pipeline, double-click matching, live mode",
                       description="A local web app: the complex image, the image pipeline with live previews, "
                                   "double-click an edge to match it (the paper's algorithm) and read its "
                                   "disparity and depth, pair every edge automatically, export CSV/JSON/PLY, and "
                                   "track the selected edge live. Open the printed address in a browser.")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--image", metavar="F", help="complex image (PNG, grey)")
    src.add_argument("--video", metavar="F", help="video file (live mode plays it in a loop)")
    src.add_argument("--camera", metavar="N|basler:SERIAL", help=CAMERA_HELP)
    src.add_argument("--scene", metavar="S", help="simulated scene: a built-in (e.g. fig5b) or a scene file "
                                                  "(the default is fig5b)")
    add_rig_argument(p, required=False)
    add_acquisition_arguments(p)
    p.add_argument("--true-rig", metavar="RIG", help="with --scene: render through this rig, the build as it "
                                                     "is (name or file), while matching uses --rig")
    p.add_argument("--target", metavar="TARGET.toml", help="the card of the capture panel (docs/calibration.md)")
    p.add_argument("--capture-to", metavar="DIR", help="with --target: the folder the capture panel saves views "
                                                     "to (created; must not hold images or target.toml yet)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0 picks a free one)")
    p.add_argument("--allow-host", metavar="NAME[:PORT]", action="append", default=[],
                   help="also answer requests naming the server NAME (its Host header; e.g. a DNS name of this "
                        "machine with --host 0.0.0.0), on its port or PORT (an SSH tunnel's); repeatable. "
                        "Other names are refused (docs/web.md#security)")
    p.set_defaults(run=run)


def make_source(args, rig):
    from psvs.io.params import load_rig
    from psvs.web import sources
    true_rig = getattr(args, "true_rig", None)
    if true_rig and (args.image or args.video or args.camera is not None):
        raise ValueError("--true-rig renders a simulated scene: use it with --scene (or no source)")
    if true_rig:
        true_rig = load_rig(true_rig)
        if true_rig.camera.image_size_px != rig.camera.image_size_px:
            raise ValueError(f"--true-rig's camera is {true_rig.camera.image_size_px} px but --rig's is "
                             f"{rig.camera.image_size_px} px: one camera")
    from psvs.cli.camera_args import check_source_arguments
    spec, acquisition = check_source_arguments(args)    # acquisition settings without --camera: refused
    if args.image:
        return sources.image_source(args.image, read_grey(args.image, expect_size=rig.camera.image_size_px))
    if args.video:
        return sources.video_source(args.video)
    if spec is not None:
        return sources.camera_source(spec, acquisition)
    spec = args.scene or "fig5b"
    return sources.scene_source(spec, load_scene_spec(spec), true_rig or rig)


def capture_setup(args):
    """The capture panel's card and folder (--target and --capture-to, both or neither), checked now."""
    if (args.target is None) != (args.capture_to is None):
        raise ValueError("--target and --capture-to go together: the card, and the folder for its views")
    if args.target is None:
        return None
    from pathlib import Path

    from psvs.calibrate.capture import check_capture_folder
    from psvs.cli.common import check_distinct
    from psvs.io.atomic import check_output_folder
    from psvs.targets.target_file import load_target
    from psvs.web.capture_runner import CaptureSetup
    folder = check_output_folder(args.capture_to, "--capture-to folder")
    check_capture_folder(folder)
    check_distinct({"--capture-to (its target.toml)": folder / "target.toml"}, {"--target": args.target})
    return CaptureSetup(load_target(args.target), Path(args.target).read_bytes(), str(folder))


def run(args) -> int:
    if not 0 <= args.port <= 65535:
        raise ValueError(f"--port must be 0-65535, got {args.port}")
    from psvs.web.guard import Access
    allow = tuple(args.allow_host)
    Access.for_bind(args.host, allow=allow, token="check")      # --host and --allow-host well-formed
    sock = listen_socket(args.host, args.port)                   # the address first: refused at once
    try:
        import uvicorn

        from psvs.cli.main import DEBUG_ENV
        from psvs.web.app import create_app
        rig = rig_from_args(args)
        capture = capture_setup(args)
        address, port = sock.getsockname()[:2]
        access = Access.for_bind(args.host, address, allow)
        app = create_app(make_source(args, rig), rig, args.rig or "default rig", capture, access)
    except BaseException:
        sock.close()
        raise
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"psvs serve: warning: listening on {args.host}: anyone who can reach it can use the UI")
    debug = os.environ.get(DEBUG_ENV, "").strip() not in ("", "0")
    if debug:
        config = uvicorn.Config(app, log_level="warning", timeout_graceful_shutdown=GRACE_S)
    else:
        config = uvicorn.Config(app, log_config=None, log_level="error", access_log=False,
                                timeout_graceful_shutdown=GRACE_S)
        uvicorn_in_one_line()
    server = uvicorn.Server(config)

    def announce():
        print(f"psvs serve: open http://{_url_host(address)}:{port}/?token={access.token} (Ctrl-C stops)",
              flush=True)
    _run_announced(server, sock, announce)
    return 0


def listen_socket(host: str, port: int) -> socket.socket:
    """A TCP socket bound to ``host`` (a name or an IP address; IPv6 when it holds a colon, as uvicorn reads
    it) and ``port`` (0: a free one), for uvicorn to listen on. ValueError in one line when the host does not
    resolve, is not an address of this machine, or the port is taken or not allowed."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    try:
        infos = socket.getaddrinfo(host or None, port, family, socket.SOCK_STREAM, 0, socket.AI_PASSIVE)
    except (socket.gaierror, UnicodeError) as exc:
        raise ValueError(f"--host {host!r} does not resolve ({getattr(exc, 'strerror', None) or exc})") from None
    sockaddr = infos[0][4]
    where = f"{_url_host(sockaddr[0])}:{port}" + ("" if sockaddr[0] == host else f" ({host})")
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        if os.name != "nt":      # a restart may reuse the port at once; on Windows the option would share it
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(sockaddr)
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            raise ValueError(f"cannot listen on {where}: the port is in use (another psvs serve?); choose "
                             f"another --port, or --port 0 for a free one") from None
        if exc.errno == errno.EADDRNOTAVAIL:
            raise ValueError(f"cannot listen on {where}: --host is not an address of this machine") from None
        if exc.errno == errno.EACCES:
            raise ValueError(f"cannot listen on {where}: permission denied (ports below 1024 need "
                             f"privileges)") from None
        raise ValueError(f"cannot listen on {where}: {exc.strerror or exc}") from None
    return sock


def _url_host(address: str) -> str:
    """An address as a URL's host: a wildcard bind as its loopback address (the one to open on this
    machine), an IPv6 address in brackets."""
    address = {"0.0.0.0": "127.0.0.1", "::": "::1"}.get(address, address)
    return f"[{address}]" if ":" in address else address


class _OneLineLog(logging.Handler):
    """uvicorn's errors (an exception a route did not turn into an answer) as one line each on stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        exc = record.exc_info[1] if record.exc_info else None
        if isinstance(exc, asyncio.CancelledError) or "graceful shutdown exceeded" in record.getMessage():
            return      # a request still open when the stop's grace ran out: cut, as the stop asked
        if exc is not None:
            text = str(exc).strip()
            what = f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__
            line = f"internal error: {what} (PSVS_DEBUG=1 shows the traceback)"
        else:
            line = (record.getMessage().strip().splitlines() or [""])[0]
        print(f"psvs serve: {line}"[:300], file=sys.stderr, flush=True)


def uvicorn_in_one_line() -> None:
    """uvicorn's loggers: its access log and its warnings (a malformed request, which gets its 400) off, its
    errors in one line (:class:`_OneLineLog`), nothing passed on to the root logger."""
    for name in ("uvicorn", "uvicorn.error", "uvicorn.access", "uvicorn.asgi"):
        log = logging.getLogger(name)      # a handler, so that logging's last resort does not print either
        log.handlers, log.propagate = [logging.NullHandler()], False
    logging.getLogger("uvicorn.error").handlers = [_OneLineLog(logging.ERROR)]


#: s a stop waits for the requests in progress (a client that holds a request open does not hold the server).
GRACE_S = 3.0


def _run_announced(server, sock, announce) -> None:
    """Run the uvicorn server on ``sock``, printing the address once it listens. Ctrl-C, its documented stop,
    ends it as a success; SIGTERM and SIGHUP (uvicorn stops gracefully, then raises them again) as any command
    they end, with 128 + their number."""
    from psvs.cli.main import Terminated

    async def main():
        task = asyncio.create_task(server.serve(sockets=[sock]))
        while not server.started and not task.done():
            await asyncio.sleep(0.05)
        if server.started:
            announce()
        await task
    try:
        asyncio.run(main())
    except Terminated:
        raise
    except KeyboardInterrupt:
        pass
    except SystemExit:          # uvicorn's exit when its start-up fails (the app's lifespan)
        raise OSError("the web server did not start") from None
    finally:
        sock.close()
