"""A run as a ROS 2 bag (rosbags, CDR; MCAP storage, rosbag2's default since Iron, or sqlite3): replay it
with ``ros2 bag play`` and RViz.

Topics (one message per control cycle, stamped with the simulated time; lengths in metres, as ROS
wants, REP 103):
  /psvs/image        sensor_msgs/msg/Image        the sensor window of the complex image, mono8
  /psvs/seam_points  sensor_msgs/msg/PointCloud2  the groove-edge points seen, base frame, float32 x y z
  /psvs/seam_path    nav_msgs/msg/Path            the path model from the torch to the last seam point
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from psvs.robot.loop import TrackRun

TOPICS = {"/psvs/image": "sensor_msgs/msg/Image", "/psvs/seam_points": "sensor_msgs/msg/PointCloud2",
          "/psvs/seam_path": "nav_msgs/msg/Path"}
FRAME = "base_link"
STORAGES = ("mcap", "sqlite3")


def _typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_HUMBLE)


def _messages(run: TrackRun, ts, t0_ns: int):
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    PointField, Pose, PoseStamped = T["sensor_msgs/msg/PointField"], T["geometry_msgs/msg/Pose"], \
        T["geometry_msgs/msg/PoseStamped"]
    Point, Quat = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, n in enumerate("xyz")]
    for k, c in enumerate(run.cycles):
        ns = t0_ns + int(round(c.t_s * 1e9))
        hdr = Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=FRAME)
        h, w = c.image.shape
        img = T["sensor_msgs/msg/Image"](header=Header(stamp=hdr.stamp, frame_id="psvs_camera"), height=h, width=w,
                                         encoding="mono8", is_bigendian=0, step=w,
                                         data=np.ascontiguousarray(c.image).ravel())
        pts = (np.asarray(c.points_mm, np.float64) * 1e-3).astype(np.float32)
        cloud = T["sensor_msgs/msg/PointCloud2"](header=hdr, height=1, width=len(pts), fields=fields,
                                                 is_bigendian=False, point_step=12, row_step=12 * len(pts),
                                                 data=pts.reshape(-1).view(np.uint8), is_dense=True)
        poses = [PoseStamped(header=hdr, pose=Pose(position=Point(x=float(p[0]) * 1e-3, y=float(p[1]) * 1e-3,
                                                                  z=float(p[2]) * 1e-3),
                                                   orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0)))
                 for p in c.path_mm]
        path = T["nav_msgs/msg/Path"](header=hdr, poses=poses)
        yield ns, {"/psvs/image": img, "/psvs/seam_points": cloud, "/psvs/seam_path": path}


def write_bag(run: TrackRun, path, storage: str = "mcap", t0_ns: int = 0) -> None:
    """Write the run as a ROS 2 bag folder at ``path`` in ``storage`` ('mcap': ``bag.mcap``, or 'sqlite3':
    ``bag.db3``, with ``metadata.yaml``), stamped ``t0_ns`` (ns since the epoch; ``psvs track``: the run's
    start, as its MCAP recording) plus the simulated time: built in a temporary folder beside it and moved
    into place at the end (an existing bag there is replaced only then)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    if storage not in STORAGES:
        raise ValueError(f"bag storage must be one of {', '.join(STORAGES)}, got {storage!r}")
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    path = Path(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {path.parent}")
    ts = _typestore()
    tmp_root = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}."))
    tmp = tmp_root / "bag"
    try:
        with Writer(tmp, version=8, storage_plugin=plugin) as writer:
            conns = {t: writer.add_connection(t, m, typestore=ts) for t, m in TOPICS.items()}
            for ns, msgs in _messages(run, ts, int(t0_ns)):
                for topic, msg in msgs.items():
                    writer.write(conns[topic], ns, ts.serialize_cdr(msg, TOPICS[topic]))
        if path.exists():
            old = tmp_root / "old"
            os.replace(path, old)
        os.replace(tmp, path)
    finally:
        shutil.rmtree(tmp_root, ignore_errors=True)


def read_bag(path) -> dict[str, list]:
    """Messages per topic, deserialised (for checks and tools): {topic: [(timestamp_ns, msg), ...]}."""
    from rosbags.rosbag2 import Reader
    ts = _typestore()
    out: dict[str, list] = {}
    with Reader(path) as reader:
        for conn, stamp, raw in reader.messages():
            out.setdefault(conn.topic, []).append((stamp, ts.deserialize_cdr(raw, conn.msgtype)))
    return out
