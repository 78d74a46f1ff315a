"""Images as the page receives them: PNG bytes, PNG data URLs, and disparity maps as colour pictures."""
from __future__ import annotations

import base64

import cv2
import numpy as np
from fastapi.responses import Response


def png(img: np.ndarray) -> bytes:
    """``img`` (grey, BGR or boolean; True as 255) encoded as PNG."""
    ok, buf = cv2.imencode(".png", img.view(np.uint8) * 255 if img.dtype == bool else img)
    if not ok:
        raise ValueError("could not encode the image as PNG")
    return buf.tobytes()


def data_url(img: np.ndarray) -> str:
    """``img`` as a ``data:image/png;base64,...`` URL, for an ``<img>`` or a canvas in a JSON answer."""
    return "data:image/png;base64," + base64.b64encode(png(img)).decode()


def png_response(img: np.ndarray) -> Response:
    """``img`` as an ``image/png`` answer the browser does not cache (the image changes under the same URL)."""
    return Response(png(img), media_type="image/png", headers={"Cache-Control": "no-store"})


def colour_disparity(d: np.ndarray, lo: float, hi: float, trusted: np.ndarray | bool = True) -> np.ndarray:
    """A disparity map (H, W) as a BGR colour image: near (large d) bright, no answer black, and the pixels
    not ``trusted`` (bool, or (H, W) bool: the echo does not support them beyond chance) in grey, not colour.

    Parameters
    ----------
    d : ndarray
        Disparities (px), NaN where there is no answer.
    lo, hi : float
        The searched disparity range (px), mapped to the ends of the colour map.
    trusted : bool or ndarray
        Which answers stand (default all); the others are drawn as grey levels.
    """
    t = np.clip((np.nan_to_num(d, nan=lo) - lo) / max(hi - lo, 1e-9), 0, 1)
    level = np.rint(255 * t).astype(np.uint8)
    out = cv2.applyColorMap(level, cv2.COLORMAP_INFERNO)
    untrusted = ~np.broadcast_to(np.asarray(trusted, dtype=bool), d.shape)
    out[untrusted] = level[untrusted][:, None]
    out[~np.isfinite(d)] = 0
    return out
