"""Live views and recordings in Foxglove's formats (the ``foxglove-sdk`` package): one set of channels, sent
to a Foxglove WebSocket server (``ws://HOST:PORT``; Foxglove's WebSocket protocol, which foxglove-sdk
0.30 names ``foxglove.sdk.v1``; open it in Foxglove with "Open connection") and/or written to an MCAP file
(open it in Foxglove, or read it with the ``mcap`` package).

Channels (Foxglove's schemas, protobuf-encoded, unless said otherwise):

=================  =========================  ==============================================================
topic              schema                     what
=================  =========================  ==============================================================
/psvs/image        foxglove.RawImage          the complex image (or the sensor window), mono8, CAMERA_FRAME
/psvs/edges        foxglove.ImageAnnotations  matched edge pixels on it: left view green, twins magenta
/psvs/points       foxglove.PointCloud        the points of the cycle, x y z float64, metres
/tf                foxglove.FrameTransforms   base_link -> flange -> psvs_optical_frame, flange -> torch
/psvs/seam         foxglove.SceneUpdate       the taught seam (path model) and the torch path, base_link
/psvs/log          foxglove.Log               status and log messages
/psvs/<name>       JSON (jsonschema)          psvs's own records in psvs's units (mm, px, s), exact floats
=================  =========================  ==============================================================

Lengths in Foxglove's messages are metres (ROS REP 103, what Foxglove's 3-D panel expects); psvs's own JSON
records keep mm. Every message's ``timestamp`` equals its MCAP/WebSocket log time (ns since the Unix
epoch): the run's start on the wall clock plus the frame's time. Image annotations use Foxglove's pixel
convention (origin at the top-left *corner* of the image), i.e. psvs's (u, v) + 0.5.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from psvs.io.jsonsafe import json_safe

#: Frame ids (ROS-Industrial names): the robot's base, its flange, the PSVS frame C (X right, Y down, Z along
#: the optical axis: an optical frame, REP 103), the torch tip.
BASE_FRAME, FLANGE_FRAME, CAMERA_FRAME, TORCH_FRAME = "base_link", "flange", "psvs_optical_frame", "torch"


def parse_endpoint(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``[HOST:]PORT`` -> (host, port); loopback unless a host is given. ValueError names the problem."""
    host, _, port = str(text).rpartition(":")
    host = host.strip("[]") or default_host
    try:
        p = int(port)
    except ValueError:
        raise ValueError(f"an endpoint must be [HOST:]PORT with PORT an integer, got {text!r}") from None
    if not 0 <= p <= 65535:
        raise ValueError(f"an endpoint's port must be in 0..65535, got {p}")
    return host, p


def url_host(host: str) -> str:
    """A host as it goes in a URL (IPv6 addresses in brackets)."""
    return f"[{host}]" if ":" in host else host


def _split_ns(ns: int):
    from foxglove.messages import Timestamp
    return Timestamp(sec=int(ns // 10**9), nsec=int(ns % 10**9))


def _identity_pose():
    from foxglove.messages import Pose, Quaternion, Vector3
    return Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))


def _quat(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(R).as_quat()      # x, y, z, w


class Telemetry:
    """The channels above, sent to a Foxglove WebSocket server at ``serve`` = (host, port) and/or recorded to
    ``mcap_path``, from a start time ``t0_ns`` (default: now). The MCAP file is written beside its place and
    moved there by :meth:`close` (an existing file is replaced only then; on an error it is left alone).

    Raises OSError naming the address when the port cannot be bound (e.g. in use)."""

    def __init__(self, mcap_path=None, serve: tuple[str, int] | None = None, t0_ns: int | None = None,
                 name: str = "psvs"):
        import foxglove
        self._fg = foxglove
        self.ctx = foxglove.Context()
        self.t0_ns = time.time_ns() if t0_ns is None else int(t0_ns)
        self.path = Path(mcap_path) if mcap_path is not None else None
        self._writer = self._server = None
        self._channels: dict[str, object] = {}
        if self.path is not None:
            if not self.path.parent.is_dir():
                raise FileNotFoundError(f"output folder does not exist: {self.path.parent}")
            self._tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
            self._writer = foxglove.open_mcap(self._tmp, allow_overwrite=True, context=self.ctx)
        if serve is not None:
            host, port = serve
            try:
                self._server = foxglove.start_server(name=name, host=host, port=int(port), context=self.ctx)
            except RuntimeError as exc:
                self.close(keep=False)
                raise OSError(f"cannot serve Foxglove on {url_host(host)}:{port}: "
                              f"{str(exc).split(': ', 1)[-1]}") from None

    @property
    def port(self) -> int | None:
        """The WebSocket server's port (the one bound when 0 was asked), None without a server."""
        return None if self._server is None else self._server.port

    def ns(self, t_s: float) -> int:
        """Log time (ns since the epoch) of a time ``t_s`` (s) since the start."""
        return self.t0_ns + int(round(float(t_s) * 1e9))

    def _channel(self, topic: str, kind: str):
        ch = self._channels.get(topic)
        if ch is None:
            if kind == "json":
                schema = self._fg.Schema(name=f"psvs.{topic.rsplit('/', 1)[-1]}", encoding="jsonschema",
                                         data=b'{"type": "object"}')
                ch = self._fg.Channel(topic, message_encoding="json", schema=schema, context=self.ctx)
            else:
                ch = getattr(self._fg.channels, f"{kind}Channel")(topic, context=self.ctx)
            self._channels[topic] = ch
        return ch

    def record(self, name: str, t_s: float, data: dict) -> None:
        """psvs's own record on ``/psvs/<name>`` (JSON; floats written exactly: ``repr`` round-trips; NaN and
        infinities, which JSON has not, as null)."""
        self._channel(f"/psvs/{name}", "json").log(json.dumps(json_safe(data), allow_nan=False).encode(),
                                                   log_time=self.ns(t_s))

    def image(self, t_s: float, image: np.ndarray, frame_id: str = CAMERA_FRAME) -> None:
        """The (H, W) uint8 image on /psvs/image."""
        from foxglove.messages import RawImage
        img = np.ascontiguousarray(image, np.uint8)
        h, w = img.shape
        ns = self.ns(t_s)
        self._channel("/psvs/image", "RawImage").log(
            RawImage(timestamp=_split_ns(ns), frame_id=frame_id, width=w, height=h, encoding="mono8", step=w,
                     data=img.tobytes()), log_time=ns)

    def edges(self, t_s: float, left_px: np.ndarray, right_px: np.ndarray) -> None:
        """Matched edge pixels (N, 2) (u, v) of each view on /psvs/edges (drawn over /psvs/image)."""
        from foxglove.messages import Color, ImageAnnotations, Point2, PointsAnnotation, PointsAnnotationType
        ns = self.ns(t_s)
        anns = []
        for uv, rgb in ((left_px, (0.1, 0.9, 0.2)), (right_px, (0.9, 0.2, 0.9))):
            uv = np.asarray(uv, float).reshape(-1, 2)
            uv = uv[np.all(np.isfinite(uv), axis=1)] + 0.5
            anns.append(PointsAnnotation(timestamp=_split_ns(ns), type=PointsAnnotationType.Points,
                                         points=[Point2(x=float(u), y=float(v)) for u, v in uv],
                                         outline_color=Color(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0), thickness=3.0))
        self._channel("/psvs/edges", "ImageAnnotations").log(ImageAnnotations(points=anns), log_time=ns)

    def depth_image(self, t_s: float, depth_mm: np.ndarray, topic: str, frame_id: str = CAMERA_FRAME) -> None:
        """A depth map (H, W) mm on ``topic`` as a RawImage of encoding 32FC1 in metres (ROS's convention
        for depth images), NaN where there is no depth."""
        from foxglove.messages import RawImage
        z = np.ascontiguousarray(np.asarray(depth_mm, float) * 1e-3, "<f4")
        h, w = z.shape
        ns = self.ns(t_s)
        self._channel(topic, "RawImage").log(
            RawImage(timestamp=_split_ns(ns), frame_id=frame_id, width=w, height=h, encoding="32FC1", step=4 * w,
                     data=z.tobytes()), log_time=ns)

    def points(self, t_s: float, points_mm: np.ndarray, frame_id: str = CAMERA_FRAME,
               topic: str = "/psvs/points") -> None:
        """Points (N, 3) mm in ``frame_id`` on ``topic`` (float64 x, y, z in metres; NaN rows dropped)."""
        from foxglove.messages import PackedElementField, PackedElementFieldNumericType, PointCloud
        p = np.asarray(points_mm, float).reshape(-1, 3)
        p = np.ascontiguousarray(p[np.all(np.isfinite(p), axis=1)] * 1e-3)
        fields = [PackedElementField(name=n, offset=8 * i, type=PackedElementFieldNumericType.Float64)
                  for i, n in enumerate("xyz")]
        ns = self.ns(t_s)
        self._channel(topic, "PointCloud").log(
            PointCloud(timestamp=_split_ns(ns), frame_id=frame_id, pose=_identity_pose(), point_stride=24,
                       fields=fields, data=p.tobytes()), log_time=ns)

    def transforms(self, t_s: float, parent_child_T: list[tuple[str, str, np.ndarray]]) -> None:
        """Frames on /tf: (parent, child, child2parent (4, 4) mm) each."""
        from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Vector3
        ns = self.ns(t_s)
        tfs = []
        for parent, child, T in parent_child_T:
            q = _quat(T[:3, :3])
            tfs.append(FrameTransform(timestamp=_split_ns(ns), parent_frame_id=parent, child_frame_id=child,
                                      translation=Vector3(**dict(zip("xyz", map(float, T[:3, 3] * 1e-3), strict=True))),
                                      rotation=Quaternion(**dict(zip("xyzw", map(float, q), strict=True)))))
        self._channel("/tf", "FrameTransforms").log(FrameTransforms(transforms=tfs), log_time=ns)

    def lines(self, t_s: float, lines: dict[str, np.ndarray], frame_id: str = BASE_FRAME) -> None:
        """Polylines {id: (N, 3) mm} on /psvs/seam (one scene entity each, replacing the last of that id)."""
        from foxglove.messages import Color, LinePrimitive, LinePrimitiveLineType, Point3, SceneEntity, SceneUpdate
        ns = self.ns(t_s)
        colours = {0: (1.0, 0.6, 0.1), 1: (0.2, 0.6, 1.0), 2: (0.9, 0.9, 0.9)}
        ents = []
        for k, (eid, pts) in enumerate(lines.items()):
            p = np.asarray(pts, float).reshape(-1, 3)
            p = p[np.all(np.isfinite(p), axis=1)] * 1e-3
            r, g, b = colours[k % 3]
            line = LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=_identity_pose(), thickness=2.0,
                                 scale_invariant=True, points=[Point3(x=float(x), y=float(y), z=float(z))
                                                               for x, y, z in p],
                                 color=Color(r=r, g=g, b=b, a=1.0))
            ents.append(SceneEntity(timestamp=_split_ns(ns), frame_id=frame_id, id=eid, lines=[line]))
        self._channel("/psvs/seam", "SceneUpdate").log(SceneUpdate(entities=ents), log_time=ns)

    def log(self, t_s: float, message: str, level: str = "info") -> None:
        """A status or log message on /psvs/log (level: debug, info, warning, error)."""
        from foxglove.messages import Log, LogLevel
        ns = self.ns(t_s)
        lvl = {"debug": LogLevel.Debug, "info": LogLevel.Info, "warning": LogLevel.Warning,
               "error": LogLevel.Error}[level]
        self._channel("/psvs/log", "Log").log(Log(timestamp=_split_ns(ns), level=lvl, message=str(message),
                                                  name="psvs"), log_time=ns)

    def close(self, keep: bool = True) -> None:
        """Stop the server; finish the MCAP file and move it into place (``keep=False``: discard it). The
        server stops and no temporary file stays behind even when finishing the file fails."""
        try:
            if self._writer is not None:
                writer, self._writer = self._writer, None
                writer.close()
                if keep:
                    os.replace(self._tmp, self.path)
        finally:
            if self.path is not None:
                self._tmp.unlink(missing_ok=True)
            if self._server is not None:
                self._server.stop()
                self._server = None
            for ch in self._channels.values():
                ch.close()
            self._channels = {}

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        self.close(keep=exc_type is None or exc_type is KeyboardInterrupt)
