"""The image's self-check for the page's answers on a still (psvs.health.check.refuse_if_drifted), as ``psvs
match`` and ``psvs disparity`` ask it: the matching the whole check always; the dense run a quick look, and
the whole check when the look cannot judge and the answer is weak or the look reads the field beyond the
tolerance (psvs.health.check.whole_check_due)."""
from __future__ import annotations

import threading

from psvs.errors import MeasurementError
from psvs.health.check import HealthCheck, refuse_if_drifted
from psvs.optics.rig import Rig

#: The self-check's answers on the images asked last ((the image, the rig, the range, quick) -> (the refusal's
#: words or "", the check)), so that matching edge after edge of one image checks it once.
_CHECKED: dict = {}
_LOCK = threading.Lock()       # requests run on the server's threads


def drift_refusal(still, rig: Rig, near_mm: float, far_mm: float,
                  quick: bool = False) -> tuple[str, HealthCheck | None]:
    """(why the image's own twins say ``rig`` does not fit it, :func:`psvs.health.check.refuse_if_drifted`'s
    "the rig does not fit this image: ..." or "", the check when it did not refuse, else None); ``quick``: its
    quick look (a ``drifted`` confirmed by the whole check). Asked once per image, rig, range and kind."""
    key = (id(still.grey), id(rig), float(near_mm), float(far_mm), bool(quick))
    with _LOCK:
        if key in _CHECKED:
            return _CHECKED[key][2]
    try:
        said = ("", refuse_if_drifted(still.grey, rig, near_mm, far_mm, quick=quick))
    except MeasurementError as exc:
        said = (str(exc), None)
    with _LOCK:
        if len(_CHECKED) >= 4:                              # the last image's verdicts, not every image's
            _CHECKED.clear()
        _CHECKED[key] = (still.grey, rig, said)              # both held, so their ids are not reused
    return said
