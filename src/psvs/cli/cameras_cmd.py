"""``psvs cameras``: the cameras psvs can open: machine-vision cameras (vendor, model, serial, interface) and
the OpenCV indices that open."""
from __future__ import annotations

from psvs.live.discover import OPENCV_INDICES, opencv_cameras, vendor_cameras


def add_parser(sub) -> None:
    p = sub.add_parser("cameras", help="list the cameras psvs can open (--camera)",
                       description="Lists the Basler cameras pylon finds (vendor, model, serial, interface: "
                                   "--camera basler:SERIAL) and the OpenCV camera indices 0-9 that open "
                                   "(--camera N). Without psvs[basler] it says how to install it and still lists "
                                   "the OpenCV cameras.")
    p.add_argument("--no-opencv", action="store_true", help="do not probe OpenCV indices (opening each takes a "
                                                            "moment)")
    p.set_defaults(run=run)


def _vendor_lines() -> list[str]:
    found, missing = vendor_cameras()
    lines = [f"Basler (pylon): {line.partition(': ')[2]}" for line in missing]
    if not found and not missing:
        lines.append("Basler (pylon): no camera found")
    if found:
        lines.append(f"Basler (pylon): {len(found)} camera{'s' * (len(found) > 1)}")
        lines += [f"  --camera {c.spec}  ({c.alias})  {c.label}" for c in found]
    return lines


def _opencv_lines() -> list[str]:
    opened = [f"  --camera {c.spec}  {c.label}" for c in opencv_cameras()]
    head = f"OpenCV: {len(opened)} of indices 0-{OPENCV_INDICES - 1} open" if opened else \
        f"OpenCV: none of indices 0-{OPENCV_INDICES - 1} opens"
    return [head, *opened]


def run(args) -> int:
    for line in _vendor_lines():
        print(line)
    if not args.no_opencv:
        for line in _opencv_lines():
            print(line)
    return 0
