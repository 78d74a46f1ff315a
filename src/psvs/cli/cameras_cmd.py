"""``psvs cameras``: the cameras psvs can open: machine-vision cameras (vendor, model, serial, interface) and
the OpenCV indices that open."""
from __future__ import annotations

#: OpenCV indices tried (V4L2 numbers its devices from 0; a gap is possible).
OPENCV_INDICES = 10


def add_parser(sub) -> None:
    p = sub.add_parser("cameras", help="list the cameras psvs can open (--camera)",
                       description="Lists the Basler cameras pylon finds (vendor, model, serial, interface: "
                                   "--camera basler:SERIAL) and the OpenCV camera indices 0-9 that open "
                                   "(--camera N). Without psvs[basler] it says how to install it and still lists "
                                   "the OpenCV cameras.")
    p.add_argument("--no-opencv", action="store_true", help="do not probe OpenCV indices (opening each takes a "
                                                            "moment)")
    p.set_defaults(run=run)


def _basler_lines() -> list[str]:
    from psvs.live.camera import vendor_module
    try:
        pylon = vendor_module("basler")
    except ValueError as exc:
        return [f"Basler (pylon): not available: {exc}"]
    found = [pylon.describe(info) for info in pylon.devices()]
    if not found:
        return ["Basler (pylon): no camera found"]
    lines = [f"Basler (pylon): {len(found)} camera{'s' * (len(found) > 1)}"]
    for k, d in enumerate(found):
        lines.append(f"  --camera basler:{d['serial']}  (basler:{k})  {d['vendor']} {d['model']}, serial "
                     f"{d['serial']}, {d['interface']}")
    return lines


def _opencv_lines() -> list[str]:
    import cv2

    from psvs._quiet import c_stderr_captured
    opened = []
    for k in range(OPENCV_INDICES):
        with c_stderr_captured():              # each backend's complaint about an index that is not there
            cap = cv2.VideoCapture(k)
            ok = cap.isOpened()
            if ok:
                w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
                opened.append(f"  --camera {k}  {w}x{h} px ({cap.getBackendName()})")
            cap.release()
    head = f"OpenCV: {len(opened)} of indices 0-{OPENCV_INDICES - 1} open" if opened else \
        f"OpenCV: none of indices 0-{OPENCV_INDICES - 1} opens"
    return [head, *opened]


def run(args) -> int:
    for line in _basler_lines():
        print(line)
    if not args.no_opencv:
        for line in _opencv_lines():
            print(line)
    return 0
