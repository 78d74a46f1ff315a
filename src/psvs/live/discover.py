"""The cameras psvs can open: what ``psvs cameras`` lists and the page's camera choice offers.

Machine-vision cameras are found by their vendor's SDK (:data:`psvs.live.camera.VENDORS`: Basler's pylon,
with ``psvs[basler]``), each by serial number; a vendor whose SDK is not installed is named with the extra
that installs it. OpenCV cameras have no list to ask: indices 0 .. ``indices`` - 1 are opened one by one
(each takes a moment; a gap is possible, V4L2 numbers from 0).
"""
from __future__ import annotations

from dataclasses import dataclass

from psvs._quiet import c_stderr_captured
from psvs.live.camera import VENDORS, vendor_module

#: OpenCV indices tried.
OPENCV_INDICES = 10


@dataclass(frozen=True)
class FoundCamera:
    """One camera found: ``spec`` what ``--camera`` (and the page) takes, ``alias`` another spec naming the same
    camera by its place among those found ('' when none), ``label`` what it is (vendor, model, serial, interface;
    or an OpenCV index's frame size and backend)."""

    spec: str
    alias: str
    label: str


def vendor_cameras() -> tuple[list[FoundCamera], list[str]]:
    """The cameras each installed vendor SDK finds, in its order, and one line per vendor whose SDK is not
    installed (what to install)."""
    found, missing = [], []
    for kind in VENDORS:
        try:
            module = vendor_module(kind)
        except ValueError as exc:
            missing.append(f"{kind}: not available: {exc}")
            continue
        for k, info in enumerate(module.devices()):
            d = module.describe(info)
            found.append(FoundCamera(f"{kind}:{d['serial']}", f"{kind}:{k}",
                                     f"{d['vendor']} {d['model']}, serial {d['serial']}, {d['interface']}"))
    return found, missing


def opencv_cameras(indices: int = OPENCV_INDICES) -> list[FoundCamera]:
    """The OpenCV indices below ``indices`` that open, with their frame size and backend."""
    import cv2
    opened = []
    for k in range(indices):
        with c_stderr_captured():              # each backend's complaint about an index that is not there
            cap = cv2.VideoCapture(k)
            try:
                if cap.isOpened():
                    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
                    opened.append(FoundCamera(str(k), "", f"{w}x{h} px ({cap.getBackendName()})"))
            finally:
                cap.release()
    return opened
