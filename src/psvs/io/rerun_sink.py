"""Recordings for Rerun (``.rrd``, the ``rerun-sdk`` package, an optional extra: ``pip install 'psvs[rerun]'``):
the channels of :class:`psvs.io.telemetry.Telemetry` (which Foxglove shows) on one Rerun timeline, ``time``
(s since the run's start), beside or instead of Foxglove's MCAP.

Entities (lengths in mm, psvs's units; the frames as in psvs.io.telemetry):

==============================  ==================================================================
entity                          what
==============================  ==================================================================
``<C>``                         the PSVS frame C (X right, Y down, Z along the optical axis: RDF)
``<C>/rig/...``                 with :meth:`RerunSink.rig` (static): the camera's centre, the four
                                glasses, the virtual cameras O1 and O2, a fan of field rays, the
                                working range's near and far fields (psvs.optics.layout3d)
``<C>/camera``                  the real camera as a pinhole (with the rig), the image under it
``<C>/camera/image``            the complex image (or a track run's sensor window), grey
``<C>/camera/edges``            matched edge pixels: the left view green, their twins magenta
``<C>/<topic>``                 point clouds (``points``: the tracked pair's, ``dense_points``: a dense map's)
``maps/<topic>``                depth maps (DepthImage, mm) and disparity maps (px), on their own grids
``views/left``, ``views/right`` the separated views
``records/<name>/<key>``        psvs's own records' numbers as time series (Scalars)
``log``                         status and log lines (TextLog)
==============================  ==================================================================

``<C>`` is ``psvs_optical_frame``, or with a robot (``robot=True``: ``track``, ``replay``)
``base_link/flange/psvs_optical_frame`` under the robot's base (Z up) and flange, whose poses come as
transforms; the torch is ``base_link/flange/torch`` and the seam's lines are under ``base_link``.

The file is written beside its place and moved there by :meth:`RerunSink.close` (an existing file is replaced
only then; on an error nothing is left behind).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from psvs.io.jsonsafe import json_safe
from psvs.io.telemetry import BASE_FRAME, CAMERA_FRAME, FLANGE_FRAME, TORCH_FRAME

#: How each frame id of psvs.io.telemetry is placed in Rerun's entity tree, with and without a robot.
ROBOT_PATHS = {BASE_FRAME: BASE_FRAME, FLANGE_FRAME: f"{BASE_FRAME}/{FLANGE_FRAME}",
               CAMERA_FRAME: f"{BASE_FRAME}/{FLANGE_FRAME}/{CAMERA_FRAME}",
               TORCH_FRAME: f"{BASE_FRAME}/{FLANGE_FRAME}/{TORCH_FRAME}"}
SENSOR_PATHS = {CAMERA_FRAME: CAMERA_FRAME}
LEVELS = {"debug": "DEBUG", "info": "INFO", "warning": "WARN", "error": "ERROR"}


def import_rerun():
    """The ``rerun`` module; ValueError in one line when the optional extra is not installed."""
    try:
        import rerun
    except ImportError:
        raise ValueError("--rerun needs the rerun-sdk package: pip install 'psvs[rerun]'") from None
    return rerun


def topic_name(topic: str) -> str:
    """A telemetry topic as an entity name: ``/psvs/dense/depth`` -> ``dense_depth``."""
    name = topic.removeprefix("/psvs/").strip("/").replace("/", "_")
    return name or "points"


class RerunSink:
    """The channels of :class:`psvs.io.telemetry.Telemetry` (the same methods) recorded to ``path`` (.rrd)
    and/or served to Rerun's web viewer, the one the rerun-sdk wheel ships (``serve_port``: its page on
    http://127.0.0.1:PORT, the data on gRPC at PORT + 1, both on the loopback); ``robot``: the entity tree of a
    robot run (module docstring). OSError naming the port when it cannot be bound. Used as a context, the file
    is moved into place when the block ends, or is ended by Ctrl-C if ``keep_on_interrupt`` (a live run, which
    Ctrl-C stops); a one-shot command's recording cut short is discarded, the earlier file kept."""

    def __init__(self, path=None, serve_port: int | None = None, robot: bool = False,
                 keep_on_interrupt: bool = True):
        rr = self._rr = import_rerun()
        self.keep_on_interrupt = keep_on_interrupt
        self.path = Path(path) if path is not None else None
        self.paths = ROBOT_PATHS if robot else SENSOR_PATHS
        self.camera = self.paths[CAMERA_FRAME]
        self.url = None
        self._pinhole_size = None
        self._tmp = None
        self.rec = rr.RecordingStream("psvs", send_properties=False)
        sinks = []
        if self.path is not None:
            if not self.path.parent.is_dir():
                raise FileNotFoundError(f"output folder does not exist: {self.path.parent}")
            self._tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
            sinks.append(rr.FileSink(str(self._tmp)))
        try:
            if serve_port is not None:           # Rerun's server reports a taken port only on its own stderr
                for port in (int(serve_port), int(serve_port) + 1):
                    _check_free(port)
                grpc = rr.GrpcServerSink(bind_ip="127.0.0.1", port=int(serve_port) + 1)
                sinks.append(grpc)
            self.rec.set_sinks(*sinks)
            if serve_port is not None:
                rr.serve_web_viewer(web_port=int(serve_port), open_browser=False, connect_to=grpc.uri)
                self.url = f"http://127.0.0.1:{int(serve_port)}/?url={grpc.uri}"
        except Exception as exc:                  # a port in use: said in one line
            self.close(keep=False)
            if serve_port is None:
                raise
            raise OSError(f"cannot serve Rerun's viewer on ports {serve_port} and {int(serve_port) + 1}: "
                          f"{str(exc).splitlines()[0]}") from None
        self.rec.log(self.camera, rr.ViewCoordinates.RDF, static=True)
        if robot:
            self.rec.log(BASE_FRAME, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def _at(self, t_s: float) -> None:
        self.rec.set_time("time", duration=float(t_s))

    def rig(self, rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> None:
        """The rig in 3-D (static, frame C) and the real camera as a pinhole, so that the complex image stands
        in its field (psvs.optics.layout3d.rig_layout)."""
        from psvs.optics.layout3d import rig_layout
        rr, c = self._rr, self.camera
        lay = rig_layout(rig, near_mm, far_mm)
        glass = [np.vstack([g["corners_mm"], g["corners_mm"][:1]]) for g in lay["glasses"]]
        self.rec.log(f"{c}/rig/glasses", rr.LineStrips3D(glass, labels=[g["name"] for g in lay["glasses"]]),
                     static=True)
        centres = [lay["camera"], lay["virtual"]["left"], lay["virtual"]["right"]]
        self.rec.log(f"{c}/rig/centres", rr.Points3D(centres, labels=["O", "O1", "O2"], radii=2.0), static=True)
        for view, rays in lay["rays"].items():
            self.rec.log(f"{c}/rig/rays/{view}", rr.LineStrips3D(rays), static=True)
        for view, field in lay["field"].items():
            quads = [np.vstack([q, q[:1]]) for q in (field["near"], field["far"]) if q is not None]
            if quads:
                self.rec.log(f"{c}/rig/field/{view}", rr.LineStrips3D(quads), static=True)
        cam = rig.camera
        w, h = (int(x) for x in cam.image_size_px)
        fx, fy = cam.focal_length_mm / np.asarray(cam.pixel_pitch_mm, float)
        cx, cy = cam.principal_point_px
        self.rec.log(f"{c}/camera", rr.Pinhole(focal_length=[fx, fy], principal_point=[cx + 0.5, cy + 0.5],
                                               resolution=[w, h], image_plane_distance=near_mm), static=True)
        self._pinhole_size = (h, w)

    def image(self, t_s: float, image: np.ndarray, frame_id: str = CAMERA_FRAME) -> None:
        """The (H, W) uint8 image: under the camera's pinhole when it is the camera's whole frame."""
        self._at(t_s)
        img = np.ascontiguousarray(image, np.uint8)
        where = f"{self.camera}/camera/image" if img.shape == self._pinhole_size else f"{self.camera}/image"
        self.rec.log(where, self._rr.Image(img, color_model="L"))

    def edges(self, t_s: float, left_px: np.ndarray, right_px: np.ndarray) -> None:
        """Matched edge pixels (N, 2) (u, v) of each view (Rerun's pixel centres are at +0.5)."""
        self._at(t_s)
        uv = [np.asarray(p, float).reshape(-1, 2) for p in (left_px, right_px)]
        uv = [p[np.all(np.isfinite(p), axis=1)] + 0.5 for p in uv]
        colours = [[25, 230, 50]] * len(uv[0]) + [[230, 50, 230]] * len(uv[1])
        self.rec.log(f"{self.camera}/camera/edges", self._rr.Points2D(np.vstack(uv), colors=colours))

    def depth_image(self, t_s: float, depth_mm: np.ndarray, topic: str, frame_id: str = CAMERA_FRAME) -> None:
        """A depth map (H, W) mm (NaN: none) on its own grid, ``maps/<topic>``."""
        self._at(t_s)
        z = np.ascontiguousarray(depth_mm, np.float32)
        self.rec.log(f"maps/{topic_name(topic)}", self._rr.DepthImage(z, meter=1000.0))

    def disparity(self, t_s: float, disparity_px: np.ndarray, name: str = "disparity") -> None:
        """A disparity map (H, W) px (NaN: none), ``maps/<name>``."""
        self._at(t_s)
        d = np.ascontiguousarray(disparity_px, np.float32)
        self.rec.log(f"maps/{name}", self._rr.DepthImage(d, meter=1.0, colormap="viridis"))

    def views(self, t_s: float, left: np.ndarray, right: np.ndarray) -> None:
        """The separated views (H, W) grey (any real dtype; shown as grey levels)."""
        self._at(t_s)
        for name, v in (("left", left), ("right", right)):
            self.rec.log(f"views/{name}", self._rr.Image(np.ascontiguousarray(v, np.float32), color_model="L"))

    def points(self, t_s: float, points_mm: np.ndarray, frame_id: str = CAMERA_FRAME,
               topic: str = "/psvs/points") -> None:
        """Points (N, 3) mm in ``frame_id`` (NaN rows dropped)."""
        self._at(t_s)
        p = np.asarray(points_mm, float).reshape(-1, 3)
        p = p[np.all(np.isfinite(p), axis=1)]
        self.rec.log(f"{self.paths.get(frame_id, frame_id)}/{topic_name(topic)}", self._rr.Points3D(p))

    def transforms(self, t_s: float, parent_child_T: list[tuple[str, str, np.ndarray]]) -> None:
        """Frames (parent, child, child2parent (4, 4) mm), each on its child's entity."""
        self._at(t_s)
        for _, child, T in parent_child_T:
            T = np.asarray(T, float)
            self.rec.log(self.paths.get(child, child), self._rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]))

    def lines(self, t_s: float, lines: dict[str, np.ndarray], frame_id: str = BASE_FRAME) -> None:
        """Polylines {id: (N, 3) mm} in ``frame_id``, one entity each (replacing the last of that id)."""
        self._at(t_s)
        for eid, pts in lines.items():
            p = np.asarray(pts, float).reshape(-1, 3)
            p = p[np.all(np.isfinite(p), axis=1)]
            self.rec.log(f"{self.paths.get(frame_id, frame_id)}/lines/{eid}", self._rr.LineStrips3D([p]))

    def record(self, name: str, t_s: float, data: dict) -> None:
        """psvs's own record: each finite number a time series ``records/<name>/<key>`` (a bool as 0/1)."""
        self._at(t_s)
        for key, v in json_safe(data).items():
            if isinstance(v, bool | int | float) and v is not None and np.isfinite(float(v)):
                self.rec.log(f"records/{name}/{key}", self._rr.Scalars(float(v)))

    def log(self, t_s: float, message: str, level: str = "info") -> None:
        """A status or log line."""
        self._at(t_s)
        self.rec.log("log", self._rr.TextLog(str(message), level=LEVELS[level]))

    def text(self, name: str, data: dict) -> None:
        """A static document (e.g. the run's settings) as JSON, ``text/<name>``."""
        self.rec.log(f"text/{name}", self._rr.TextDocument(json.dumps(json_safe(data), indent=1)), static=True)

    def close(self, keep: bool = True) -> None:
        """Finish the file and move it into place (``keep=False``: discard it); no temporary file stays behind
        even when finishing it fails."""
        try:
            if self.rec is not None:
                rec, self.rec = self.rec, None
                rec.flush()
                rec.disconnect()
                if keep and self._tmp is not None:
                    os.replace(self._tmp, self.path)
        finally:
            if self._tmp is not None:
                self._tmp.unlink(missing_ok=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        self.close(keep=exc_type is None or (exc_type is KeyboardInterrupt and self.keep_on_interrupt))


def _check_free(port: int) -> None:
    """OSError when ``port`` cannot be bound on the loopback (e.g. in use)."""
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", port))


class Tee:
    """Several sinks (Telemetry, RerunSink) as one: each call goes to every sink that has the method."""

    def __init__(self, sinks: list):
        self.sinks = list(sinks)

    def __getattr__(self, name: str):
        found = [getattr(s, name) for s in self.sinks if hasattr(s, name)]
        if not found:
            raise AttributeError(name)

        def call(*args, **kwargs):
            for f in found:
                f(*args, **kwargs)
        return call
