"""The image's self-check for the page's answers on a still (psvs.health.check.refuse_if_drifted): the
matching always, the dense run when its answer is weak (psvs.dense.trust.WEAK_SHARE), as ``psvs match`` and
``psvs disparity`` ask it; once per image, rig and range."""
from __future__ import annotations

import threading

from psvs.errors import MeasurementError
from psvs.health.check import refuse_if_drifted
from psvs.optics.rig import Rig

#: The self-check's verdict on the image asked last (the image, the rig, the range -> the refusal's words or
#: ""), so that matching edge after edge of one image checks it once.
_CHECKED: dict = {}
_LOCK = threading.Lock()       # requests run on the server's threads


def drift_refusal(still, rig: Rig, near_mm: float, far_mm: float) -> str:
    """Why the image's own twins say ``rig`` does not fit it (:func:`psvs.health.check.refuse_if_drifted`:
    "the rig does not fit this image: ..."), or "" when they do or cannot tell; asked once per image, rig
    and range."""
    key = (id(still.grey), id(rig), float(near_mm), float(far_mm))
    with _LOCK:
        if key in _CHECKED:
            return _CHECKED[key][2]
    try:
        refuse_if_drifted(still.grey, rig, near_mm, far_mm)
        said = ""
    except MeasurementError as exc:
        said = str(exc)
    with _LOCK:
        _CHECKED.clear()                                     # one image at a time: the last one's verdict
        _CHECKED[key] = (still.grey, rig, said)              # both held, so their ids are not reused
    return said
