"""The camera source interface every frame source of psvs implements (OpenCV cameras, video files, image
sequences, Basler pylon cameras), the frame it delivers, the acquisition settings it takes, and the
``--camera`` spec that picks one.

A source is opened, configured, grabbed from and closed::

    source = open_camera("basler:0")          # psvs.live.source; or "0" (an OpenCV index), or VideoSource(...)
    with source:                              # open() ... close()
        source.configure(Acquisition(exposure_us=2000, pixel_format="Mono12"))
        while (frame := source.grab()) is not None:
            frame.image, frame.counter, frame.timestamp_s, frame.dropped

Another vendor's SDK (Allied Vision's ``vmbpy``, IDS's ``ids-peak``) is one more module with a class that
has these methods, named in :data:`VENDORS`; the callers (``psvs live``, ``capture``, ``serve``) do not change.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field, fields
from typing import Protocol, runtime_checkable

import numpy as np

#: The clocks a frame's timestamp can be on: the camera's own (its timestamp counter, in seconds), the host's
#: monotonic clock when the frame arrived (a camera that gives no timestamp), or a file's nominal frame rate.
CLOCKS = ("camera", "host", "file")

#: Triggers a camera may be run with (None: free run at its frame rate).
TRIGGERS = ("software", "line1")


@dataclass(frozen=True, eq=False)
class Frame:
    """One grabbed frame.

    image : (H, W) uint8 grey (a 10- or 12-bit camera's frames scaled by its bit depth, as 16-bit files are:
        :func:`psvs.io.images.grey8_from_bits`).
    index : frames delivered by this source so far, from 0.
    counter : the camera's own frame counter (a GigE block ID, a USB3 frame ID); ``index`` for a source that
        has none.
    timestamp_s : the frame's time, s, on ``clock`` (one of :data:`CLOCKS`).
    dropped : frames the camera took between the previous delivered frame and this one that never arrived
        (a gap in ``counter``): counted, never silently skipped.
    """

    image: np.ndarray
    index: int
    counter: int
    timestamp_s: float
    clock: str
    dropped: int = 0


class CameraLost(OSError):
    """The camera stopped delivering in mid-run (unplugged, powered off, closed): the run stops cleanly,
    keeping what it has; ``last`` is the last frame delivered (None when there was none)."""

    def __init__(self, message: str, last: Frame | None = None):
        super().__init__(message)
        self.last = last


@dataclass(frozen=True)
class Acquisition:
    """How frames are taken; None leaves the camera's own value.

    exposure_us : exposure time, microseconds.   gain_db : analogue gain, dB.
    frame_rate_hz : acquisition frame rate (free run), Hz.
    pixel_format : e.g. Mono8, Mono10, Mono12, Mono10p, Mono12p, Mono12Packed (what the camera has).
    trigger : None (free run), "software" (one frame per :meth:`FrameSource.grab`) or "line1" (hardware).
    auto_exposure, auto_gain : off unless asked: a measurement needs a fixed response.
    settings_file : a feature file (.pfs, as pylon Viewer saves it) loaded before everything else.
    features : (name, value) pairs set in order after everything else (``--camera-set NAME=VALUE``).
    """

    exposure_us: float | None = None
    gain_db: float | None = None
    frame_rate_hz: float | None = None
    pixel_format: str | None = None
    trigger: str | None = None
    auto_exposure: bool = False
    auto_gain: bool = False
    settings_file: str | None = None
    features: tuple[tuple[str, str], ...] = field(default=())

    def __post_init__(self):
        for name in ("exposure_us", "gain_db", "frame_rate_hz"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v)):
                raise ValueError(f"{name} must be a number, got {v!r}")
        for name in ("exposure_us", "frame_rate_hz"):
            v = getattr(self, name)
            if v is not None and v <= 0:
                raise ValueError(f"{name} must be > 0, got {v!r}")
        if self.trigger is not None and self.trigger not in TRIGGERS:
            raise ValueError(f"trigger must be one of {', '.join(TRIGGERS)}, got {self.trigger!r}")

    def asks_anything(self) -> bool:
        """Whether any setting is asked for (a source that takes none refuses then)."""
        return any(getattr(self, f.name) not in (None, False, ()) for f in fields(self))

    def merged(self, over: Acquisition) -> Acquisition:
        """These settings with every value ``over`` gives replacing this one's (features appended)."""
        kw = {f.name: getattr(over, f.name) if getattr(over, f.name) not in (None, False) else getattr(self, f.name)
              for f in fields(self) if f.name != "features"}
        return Acquisition(**kw, features=self.features + over.features)


@runtime_checkable
class FrameSource(Protocol):
    """What ``psvs live``, ``capture`` and ``serve`` read frames from.

    ``name`` is shown to the user; ``fps`` is the nominal rate (0 when unknown); ``frame_count`` a file's
    frame count (0 for a camera)."""

    name: str
    fps: float
    frame_count: int

    def open(self) -> None:
        """Connect (idempotent); ValueError/OSError naming what is missing."""

    def configure(self, acquisition: Acquisition) -> None:
        """Apply the settings before the first grab; ValueError naming a setting the source lacks."""

    def grab(self) -> Frame | None:
        """The next frame, None at the end of a file; :class:`CameraLost` when a camera stops delivering."""

    def close(self) -> None:
        """Stop and disconnect (idempotent)."""

    def settings(self) -> dict:
        """The acquisition in effect, for a recording's ``[camera.acquisition]`` table (TOML values)."""

    def feature_file(self) -> str | None:
        """The camera's full feature file (pylon's .pfs text), None for a source that has none."""


#: Camera kinds by their --camera prefix: module and class (imported only when asked for), and the extra
#: that installs the vendor's SDK.
VENDORS = {"basler": ("psvs.live.pylon", "PylonSource", "basler", "pypylon")}


@dataclass(frozen=True)
class CameraSpec:
    """A parsed ``--camera``: kind "opencv" with an index, or a vendor kind with a serial ("0": the first)."""

    kind: str
    device: str

    def __str__(self) -> str:
        return self.device if self.kind == "opencv" else f"{self.kind}:{self.device}"


#: The largest camera index OpenCV's VideoCapture takes (a C int).
MAX_OPENCV_INDEX = 2**31 - 1


def parse_camera(text) -> CameraSpec:
    """``N`` (an OpenCV index >= 0), ``basler:SERIAL`` or ``basler:N`` (the N-th found), ``basler`` (the first)."""
    text = str(text).strip()
    if text.isascii() and text.isdigit():
        if int(text) > MAX_OPENCV_INDEX:      # OpenCV takes a C int: a larger one was its "Bad argument"
            raise ValueError(f"--camera {text}: an OpenCV index is at most {MAX_OPENCV_INDEX} (psvs cameras lists "
                             "them)")
        return CameraSpec("opencv", str(int(text)))
    kind, _, device = text.partition(":")
    if kind.lower() not in VENDORS:
        raise ValueError(f"--camera must be an OpenCV index (0, 1, ...) or {', '.join(k + ':SERIAL' for k in VENDORS)}"
                         f", got {text!r}")
    device = device.strip() or "0"
    return CameraSpec(kind.lower(), device)


def parse_features(items, what: str = "--camera-set") -> tuple[tuple[str, str], ...]:
    """``NAME=VALUE`` strings as (name, value) pairs (both stripped), in order; ValueError naming ``what`` for
    one without a name or an ``=``."""
    out = []
    for item in items:
        name, eq, value = str(item).partition("=")
        if not eq or not name.strip():
            raise ValueError(f"{what} must be NAME=VALUE, got {item!r}")
        out.append((name.strip(), value.strip()))
    return tuple(out)


def vendor_module(kind: str):
    """The module of a vendor kind, imported; ValueError naming the extra to install when its SDK is missing."""
    module, _, extra, sdk = VENDORS[kind]
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if sdk not in str(exc) and getattr(exc, "name", None) != sdk:
            raise
        raise ValueError(f"--camera {kind}:... needs the {sdk} package: pip install 'psvs[{extra}]'") from None
