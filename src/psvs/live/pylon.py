"""Basler machine-vision cameras (GigE Vision, USB3 Vision) through Basler's pylon SDK (``pypylon``, the
optional extra ``psvs[basler]``): a :class:`psvs.live.camera.FrameSource`.

The camera is opened by serial number (``basler:SERIAL``) or by its place among those found (``basler:0``),
configured (a feature file, exposure, gain, frame rate, pixel format, trigger, then ``--camera-set``
features in order; auto-exposure and auto-gain off unless asked) and grabbed one frame at a time, every
frame in order (``GrabStrategy_OneByOne``): a frame the camera took but that never arrived shows as a gap in
its frame counter (the block ID) and is counted in :attr:`Frame.dropped`. Mono10/Mono12 frames (and their
packed variants, unpacked by pylon) are scaled to 8 bits by the sensor's bit depth
(:func:`psvs.io.images.grey8_from_bits`). Timestamps are the camera's (its tick counter, converted to s);
a camera that gives none (pylon's emulator gives 0) falls back to the host's monotonic clock, and each
frame says which (:attr:`Frame.clock`). pylon's emulator (environment ``PYLON_CAMEMU=N``) is such a camera.
"""
from __future__ import annotations

import os
import tempfile
import time

from pypylon import genicam, pylon

from psvs.io.images import grey8_from_bits
from psvs.live.camera import Acquisition, CameraLost, Frame

#: Grey pixel formats psvs takes and their significant bits (packed ones are unpacked by pylon: a grab
#: result's Array is uint16, LSB-aligned, for Mono10p/Mono12p too, basler/pypylon#668).
MONO_BITS = {"Mono8": 8, "Mono10": 10, "Mono10p": 10, "Mono10Packed": 10, "Mono12": 12, "Mono12p": 12,
             "Mono12Packed": 12}

#: How long a grab waits for a frame before it counts the camera as gone, s (a hardware trigger may wait
#: longer: ``line1`` waits until Ctrl-C, checking that the camera is still there every this often).
GRAB_TIMEOUT_S = 5.0

#: Block IDs are 64-bit on GigE Vision 2 and USB3 Vision; all ones means the camera has none.
NO_BLOCK_ID = 0xFFFFFFFFFFFFFFFF


def devices() -> list:
    """The pylon devices connected (pylon's DeviceInfo objects), in pylon's order."""
    return list(pylon.TlFactory.GetInstance().EnumerateDevices())


def describe(info) -> dict:
    """A device's vendor, model, serial and interface (GigE, USB, Emulation, ...)."""
    return {"vendor": info.GetVendorName(), "model": info.GetModelName(), "serial": info.GetSerialNumber(),
            "interface": info.GetDeviceClass().removeprefix("Basler")}


class PylonSource:
    """A Basler camera. ``device``: a serial number, or a small integer N (the N-th camera found)."""

    fps: float = 0.0
    frame_count: int = 0

    def __init__(self, device: str = "0"):
        self.device = str(device)
        self.name = f"basler:{self.device}"
        self._cam = None
        self._bits = 8
        self._index, self._last_block, self._t0 = 0, None, None
        self._tick_hz = 1e9
        self._trigger = None
        self._settings: dict = {}
        self._pfs: str | None = None
        self._last: Frame | None = None

    # -- open, configure -------------------------------------------------------------------------------
    def open(self) -> None:
        """Connect to the camera the device spec names (ValueError listing the cameras found when none matches);
        opening an open source does nothing."""
        if self._cam is not None:
            return
        found = devices()
        info = _pick(found, self.device)
        try:
            cam = pylon.InstantCamera(pylon.TlFactory.GetInstance().CreateDevice(info))
            cam.Open()
        except genicam.GenericException as exc:
            raise OSError(f"cannot open {self.name}: {_reason(exc)}") from None
        self._cam = cam
        d = describe(info)
        self._serial = d["serial"]
        self.name = f"basler:{d['serial']} ({d['vendor']} {d['model']}, {d['interface']})"
        self._tick_hz = _tick_hz(cam)

    def configure(self, acquisition: Acquisition) -> None:
        """Apply ``acquisition`` in this order: the feature file, auto-exposure/gain (off unless asked),
        pixel format, exposure, gain, frame rate, trigger, then each ``features`` pair; ValueError naming a
        setting the camera lacks or refuses. Starts grabbing."""
        cam = self._require_open()
        a = acquisition
        if a.settings_file is not None:
            try:
                pylon.FeaturePersistence.Load(str(a.settings_file), cam.GetNodeMap(), True)
            except genicam.GenericException as exc:
                raise ValueError(f"--camera-settings {a.settings_file}: {_reason(exc)}") from None
        _set_if(cam, "ExposureAuto", "Continuous" if a.auto_exposure else "Off", required=a.auto_exposure)
        _set_if(cam, "GainAuto", "Continuous" if a.auto_gain else "Off", required=a.auto_gain)
        if a.pixel_format is not None:
            _set_enum(cam, "PixelFormat", a.pixel_format, "--pixel-format")
        if a.exposure_us is not None:
            _set_first(cam, ("ExposureTime", "ExposureTimeAbs"), a.exposure_us, "--exposure-us")
        if a.gain_db is not None:
            _set_first(cam, ("Gain", "GainAbs"), a.gain_db, "--gain-db")
        if a.frame_rate_hz is not None:
            _set_if(cam, "AcquisitionFrameRateEnable", True)
            _set_first(cam, ("AcquisitionFrameRate", "AcquisitionFrameRateAbs"), a.frame_rate_hz, "--frame-rate")
        _set_trigger(cam, a.trigger)
        for name, value in a.features:
            _set_feature(cam, name, value)
        fmt = _get(cam, "PixelFormat")
        if fmt not in MONO_BITS:
            raise ValueError(f"{self.name} delivers {fmt} pixels; psvs takes grey ones: "
                             f"--pixel-format {'|'.join(k for k in MONO_BITS if k in _symbols(cam, 'PixelFormat'))}")
        self._bits, self._trigger = MONO_BITS[fmt], a.trigger
        self.fps = float(_get(cam, "ResultingFrameRate", _get(cam, "AcquisitionFrameRate", 0.0)) or 0.0)
        self._settings = {**_settings(cam, a, fmt), "serial": self._serial}
        self._pfs = _feature_file(cam)
        cam.StartGrabbing(pylon.GrabStrategy_OneByOne)

    def settings(self) -> dict:
        """The camera's acquisition settings as applied (feature name -> value), for the run's record."""
        return dict(self._settings)

    def feature_file(self) -> str | None:
        """The camera's full feature set (pylon's .pfs text) saved when it was configured; None before."""
        return self._pfs

    # -- grab ------------------------------------------------------------------------------------------
    def grab(self) -> Frame | None:
        """The next frame (one per call with ``trigger="software"``); CameraLost when the camera is gone."""
        cam = self._cam
        if cam is None:
            raise ValueError(f"{self.name} is not open")
        if not cam.IsGrabbing():
            if self._last is None and cam.IsOpen():
                raise ValueError(f"{self.name} is not configured (configure() starts grabbing)")
            raise CameraLost(f"{self.name} is no longer grabbing", self._last)
        try:
            if self._trigger == "software":
                cam.WaitForFrameTriggerReady(int(GRAB_TIMEOUT_S * 1000), pylon.TimeoutHandling_ThrowException)
                cam.ExecuteSoftwareTrigger()
            result = self._retrieve(cam)
        except (genicam.GenericException, RuntimeError) as exc:
            raise CameraLost(f"{self.name}: {_reason(exc)}", self._last) from None
        try:
            if not result.GrabSucceeded():
                raise CameraLost(f"{self.name}: grab failed ({result.GetErrorDescription()})", self._last)
            frame = self._frame(result)
        finally:
            result.Release()
        self._last = frame
        return frame

    def _retrieve(self, cam):
        """Wait for the next result (a hardware trigger: as long as it takes, the camera checked meanwhile)."""
        while True:
            result = cam.RetrieveResult(int(GRAB_TIMEOUT_S * 1000), pylon.TimeoutHandling_Return)
            if result is not None and result.IsValid():
                return result
            if self._trigger != "line1" or cam.IsCameraDeviceRemoved() or not cam.IsGrabbing():
                raise CameraLost(f"{self.name}: no frame in {GRAB_TIMEOUT_S:g} s"
                                 + (" (removed)" if cam.IsCameraDeviceRemoved() else ""), self._last)

    def _frame(self, result) -> Frame:
        image = grey8_from_bits(result.Array, self._bits)
        block = result.GetBlockID()
        counter = self._index if block in (None, NO_BLOCK_ID) else int(block)
        dropped = 0
        if self._last_block is not None and counter > self._last_block + 1:
            dropped = counter - self._last_block - 1
        self._last_block = counter
        stamp = int(result.GetTimeStamp())
        now = time.monotonic()
        if self._t0 is None:
            self._t0 = now
        t_s, clock = (stamp / self._tick_hz, "camera") if stamp else (now - self._t0, "host")
        frame = Frame(image, self._index, counter, t_s, clock, dropped)
        self._index += 1
        return frame

    def close(self) -> None:
        """Stop grabbing and release the camera; closing a closed source does nothing."""
        cam, self._cam = self._cam, None
        if cam is None:
            return
        try:
            if cam.IsGrabbing():
                cam.StopGrabbing()
            cam.Close()
        except (genicam.GenericException, RuntimeError):
            pass                        # a camera already gone is closed
        cam.DestroyDevice()

    def _require_open(self):
        if self._cam is None:
            raise ValueError(f"{self.name} is not open")
        return self._cam

    def read(self):
        """The next frame's image (None at the end): the older interface of a frame source."""
        frame = self.grab()
        return None if frame is None else frame.image

    def __iter__(self):
        while True:
            yield self.grab().image

    def __enter__(self):
        self.open()
        return self

    def __exit__(self, *exc):
        self.close()


def _pick(found: list, device: str):
    """The device a ``basler:`` spec names: a serial number, else a small index into ``found``."""
    if not found:
        raise OSError("no Basler camera found (psvs cameras lists what is connected)")
    for info in found:
        if info.GetSerialNumber() == device:
            return info
    if device.isdigit() and int(device) < len(found) and len(device) <= 3:
        return found[int(device)]
    have = ", ".join(f"{i.GetSerialNumber()} ({i.GetModelName()})" for i in found)
    raise OSError(f"no Basler camera with serial {device} is connected (found: {have})")


def _reason(exc) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text.split(" : ")[0]


def _node(cam, name: str):
    """The camera's feature ``name``, None when it has none (pylon answers a placeholder that is not available)."""
    try:
        node = cam.GetNodeMap().GetNode(name)
        return node if node is not None and genicam.IsAvailable(node) else None
    except genicam.GenericException:
        return None


def _get(cam, name: str, default=None):
    node = _node(cam, name)
    if node is None or not genicam.IsReadable(node):
        return default
    return node.GetValue()


def _symbols(cam, name: str) -> list[str]:
    node = _node(cam, name)
    return list(node.Symbolics) if node is not None and genicam.IsReadable(node) else []


def _set_if(cam, name: str, value, required: bool = False) -> None:
    """Set a feature when the camera has it writable (ValueError when ``required`` and it has not)."""
    node = _node(cam, name)
    if node is None or not genicam.IsWritable(node):
        if required:
            raise ValueError(f"the camera has no writable {name}")
        return
    node.SetValue(value)


def _set_enum(cam, name: str, value: str, option: str) -> None:
    have = _symbols(cam, name)
    if value not in have:
        raise ValueError(f"{option} {value}: the camera has no such {name} (it has: {', '.join(have)})")
    _node(cam, name).SetValue(value)


def _set_first(cam, names: tuple, value: float, option: str) -> None:
    """Set the first of ``names`` the camera has (SFNC names first, then older ace GigE names)."""
    for name in names:
        node = _node(cam, name)
        if node is not None and genicam.IsWritable(node):
            lo, hi = node.GetMin(), node.GetMax()
            if not lo <= value <= hi:
                raise ValueError(f"{option} {value:g} is outside the camera's {name} range {lo:g}-{hi:g}")
            node.SetValue(float(value))
            return
    raise ValueError(f"{option}: the camera has no writable {' or '.join(names)}")


def _set_trigger(cam, trigger: str | None) -> None:
    """Frame-start trigger off (free run), or on from software or input line 1."""
    if "FrameStart" in _symbols(cam, "TriggerSelector"):
        _node(cam, "TriggerSelector").SetValue("FrameStart")
    if trigger is None:
        _set_if(cam, "TriggerMode", "Off")
        return
    source = {"software": "Software", "line1": "Line1"}[trigger]
    _set_enum(cam, "TriggerSource", source, "--trigger")
    _set_enum(cam, "TriggerMode", "On", "--trigger")


def _set_feature(cam, name: str, value: str) -> None:
    """``--camera-set NAME=VALUE``: any feature, from its text (as pylon's feature files write it)."""
    node = _node(cam, name)
    if node is None:
        raise ValueError(f"--camera-set {name}={value}: the camera has no feature {name}")
    if not genicam.IsWritable(node):
        raise ValueError(f"--camera-set {name}={value}: {name} is not writable now")
    try:
        node.FromString(value)
    except genicam.GenericException as exc:
        raise ValueError(f"--camera-set {name}={value}: {_reason(exc)}") from None


def _tick_hz(cam) -> float:
    """The timestamp counter's rate: GigE's GevTimestampTickFrequency, else 1 GHz (ns: USB3 Vision, ace 2)."""
    hz = _get(cam, "GevTimestampTickFrequency")
    return float(hz) if hz else 1e9


def _settings(cam, a: Acquisition, fmt: str) -> dict:
    """The acquisition in effect, read back from the camera (TOML values; None where it has no such feature)."""
    def first(*names):
        return next((float(v) for n in names if (v := _get(cam, n)) is not None), None)
    out = {"camera": f"{_get(cam, 'DeviceVendorName', '')} {_get(cam, 'DeviceModelName', '')}".strip(),
           "pixel_format": fmt, "bits": MONO_BITS[fmt],
           "exposure_us": first("ExposureTime", "ExposureTimeAbs"), "gain_db": first("Gain", "GainAbs"),
           "frame_rate_hz": first("AcquisitionFrameRate", "AcquisitionFrameRateAbs"),
           "auto_exposure": _get(cam, "ExposureAuto", "Off") != "Off",
           "auto_gain": _get(cam, "GainAuto", "Off") != "Off"}
    if a.trigger is not None:
        out["trigger"] = a.trigger
    out["features"] = {n: v for n, v in a.features}
    return {k: v for k, v in out.items() if v is not None}


def _feature_file(cam) -> str | None:
    """The camera's features as a pylon feature file (.pfs) text, None when pylon cannot save them."""
    fd, path = tempfile.mkstemp(suffix=".pfs")
    os.close(fd)
    try:
        pylon.FeaturePersistence.Save(path, cam.GetNodeMap())
        with open(path, encoding="utf-8", errors="replace") as f:
            return f.read()
    except genicam.GenericException:
        return None
    finally:
        os.unlink(path)
