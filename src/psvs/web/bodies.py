"""The JSON bodies the page posts, as pydantic models that refuse what they can judge alone.

Types, bounds and unknown keys are checked field by field (a malformed body: 422). Rules between fields or
against the library's names are checked here once, in validators that raise :class:`ValueError`: the app
answers those with 400 and the validator's one-line message, like any other bad value (``psvs.web.app``).
What needs the current image or the rig (a seed on the image, a pipeline the library can build) is checked
by the routes.
"""
from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from psvs.imaging.pipeline import PAPER, Pipeline, make_pipeline
from psvs.match.correspondence import MatchParams
from psvs.measure.triangulate import MODELS
from psvs.mount.seats import DEFAULT_PITCH_MM, PITCH_RANGE_MM
from psvs.web.limits import check_steps

#: Largest near or far distance (mm) a body may ask for.
MAX_RANGE_MM = 100000
#: Longest rig file or mount.toml text a body may carry (characters; psvs writes a few kB).
MAX_FILE_CHARS = 1_000_000


class Body(BaseModel):
    """A request body: unknown keys are refused (a misspelt key is an error, not a silent default)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)     # NaN: "a finite number", not a bound


class RangeBody(Body):
    """A body with a working range: the depths (mm) whose disparities are searched, near < far."""

    near_mm: float = Field(400.0, gt=0, le=MAX_RANGE_MM)
    far_mm: float = Field(1200.0, gt=0, le=MAX_RANGE_MM)

    @model_validator(mode="after")
    def _near_before_far(self):
        if not self.near_mm < self.far_mm:
            raise ValueError(f"near_mm must be < far_mm, got {self.near_mm:g} and {self.far_mm:g}")
        return self


class PipelineBody(Body):
    """A body with an image pipeline: JSON steps as in pipeline files, or None for the paper's."""

    steps: list[dict] | None = Field(default=None, description="pipeline steps; default: the paper's")

    def pipeline(self) -> Pipeline:
        """The pipeline of ``steps`` (bounded by :func:`psvs.web.limits.check_steps`, then built by the library,
        which raises ValueError on an unknown step or a bad parameter)."""
        return PAPER if self.steps is None else make_pipeline(check_steps(self.steps))


class MatchBody(PipelineBody, RangeBody):
    """``POST /api/match``: a double-clicked seed or automatic pairing, the pipeline, range and model."""

    seed: tuple[float, float] | None = Field(default=None, description="double-clicked (u, v) px; None: automatic")
    model: str | None = Field(default=None, description="triangulation model; default: refraction on the "
                                                        "paper's geometry, exact on a build")

    @field_validator("seed", mode="before")
    @classmethod
    def _seed_of_numbers(cls, seed):
        if isinstance(seed, (list, tuple)) and any(isinstance(c, bool) for c in seed):   # pydantic takes true as 1
            raise ValueError(f"seed must be two numbers (u, v) in px, got {list(seed)!r}")
        return seed

    @field_validator("model")
    @classmethod
    def _known_model(cls, model: str | None) -> str | None:
        if model is not None and model not in MODELS:
            raise ValueError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
        return model

    def params(self) -> MatchParams:
        """The matcher's parameters this body sets (the model; the rest are the library's defaults)."""
        return MatchParams(model=self.model)


class LiveBody(MatchBody):
    """``POST /api/live/start``: as a match (the seed is the edge to track), optionally with dense depth."""

    dense: bool = Field(False, description="also a dense depth map of every frame (the fast mode)")
    check: bool = Field(True, description="the rolling self-check of the twins' rows (psvs.health.rolling)")
    tolerance_px: float = Field(0.5, gt=0, le=100, description="the self-check's tolerance, px RMS")


class RigChoiceBody(Body):
    """``POST /api/rig``: a shipped rig's ``name``, or a rig file's ``text`` (with the ``file_name`` the page
    shows); exactly one of the two."""

    name: str | None = Field(default=None, max_length=100)
    text: str | None = Field(default=None, max_length=MAX_FILE_CHARS)
    file_name: str | None = Field(default=None, max_length=255)

    @model_validator(mode="after")
    def _one_of(self):
        if (self.name is None) == (self.text is None):
            raise ValueError("give a shipped rig's name or a rig file's text, not both or neither")
        return self


class MountMeshBody(Body):
    """``POST /api/mount/mesh``: a mount's STL file (``psvs mount``'s mount.stl), base64, and its name."""

    stl: str = Field(min_length=1, max_length=8_000_000)
    name: str = Field("mount.stl", min_length=1, max_length=255)


class MountMakeBody(RangeBody):
    """``POST /api/mount/make``: what ``psvs mount`` asks of the builder (:class:`psvs.mount.layout.MountParams`:
    the camera's interface and the printer's walls and clearance, the seats' screw pitch, mm); the rig is the
    served one."""

    interface: Literal["clamp", "c", "cs"] = "clamp"
    lens_diameter_mm: float = Field(30.0, gt=0, le=500)
    lens_front_mm: float = Field(0.0, ge=-500, le=500)
    flange_mm: float = Field(25.0, gt=0, le=500)
    hole_square_mm: float = Field(36.0, gt=0, le=500)
    wall_mm: float = Field(2.0, gt=0, le=50)
    clearance_mm: float = Field(0.3, ge=0, le=5)
    pitch_mm: float = Field(DEFAULT_PITCH_MM, ge=PITCH_RANGE_MM[0], le=PITCH_RANGE_MM[1])
    margin_mm: float = Field(0.0, ge=0, le=50)


class RobotTrackBody(Body):
    """``POST /api/robot/track``: a simulated seam-tracking run (``psvs track SCENE --speed --length``) through
    the served rig."""

    scene: str = Field("weld_seam", min_length=1, max_length=300)
    speed_mm_s: float = Field(10.0, gt=0, le=200)
    length_mm: float = Field(10.0, gt=0, le=1000)


class RobotRunBody(Body):
    """``POST /api/robot/run``: a track run's log.csv and report.json, as texts (``psvs track -o RUN``)."""

    log: str = Field(min_length=1, max_length=8_000_000)
    report: str = Field(min_length=1, max_length=MAX_FILE_CHARS)


class CheckBody(RangeBody):
    """``POST /api/check``: the self-check of the calibration on the current image, over the working range."""

    tolerance_px: float = Field(0.5, gt=0, le=100, description="healthy within this RMS row offset, px")


class CaptureSetupBody(Body):
    """``POST /api/capture/setup``: the card (its target file's text, as ``psvs target`` writes it) and the folder
    on this machine its views are saved in (new or empty; relative to where psvs serve runs)."""

    target: str = Field(min_length=1, max_length=100_000)
    folder: str = Field(min_length=1, max_length=4096)


class DenseBody(RangeBody):
    """``POST /api/dense``: the dense disparity of the current image."""

    fast: bool = True
    views: bool = Field(False, description="also separate the left and right views (slower)")


class CaptureBody(Body):
    """``POST /api/capture/start``: views to save at least, and the depths (mm) whose thirds are covered."""

    views: int = Field(20, ge=3, le=200)
    near_mm: float = Field(400.0, gt=0, le=MAX_RANGE_MM)
    far_mm: float = Field(900.0, gt=0, le=MAX_RANGE_MM)

    @model_validator(mode="after")
    def _near_before_far(self):
        if not self.near_mm < self.far_mm:
            raise ValueError(f"near_mm must be < far_mm, got {self.near_mm:g} and {self.far_mm:g}")
        return self



class AdjustBody(RangeBody):
    """``POST /api/adjust``: the alignment guide of a calibrated build (docs/mount.md), the working range
    whose field points it weighs, and where the seats come from."""

    calibrated: str = Field(min_length=1, max_length=MAX_FILE_CHARS,
                            description="the calibrated rig file's text (TOML, as psvs calibrate writes it)")
    design: str | None = Field(default=None, min_length=1, max_length=MAX_FILE_CHARS,
                               description="the design: a shipped rig's name or a rig file's text; "
                                           "default: the rig the app serves")
    mount: str | None = Field(default=None, min_length=1, max_length=MAX_FILE_CHARS,
                              description="mount.toml's text (the seats psvs mount wrote); default: the seats "
                                          "on the design's mirrors")
    pitch_mm: float | None = Field(default=None, ge=PITCH_RANGE_MM[0], le=PITCH_RANGE_MM[1],
                                   description="screw pitch, mm per turn, of the default seats (M3 x 0.5)")


class CalibrateBody(Body):
    """``POST /api/calibrate``: the folder of card views (relative to where psvs serve runs; default the
    capture's)."""

    folder: str | None = Field(default=None, max_length=4096)



class CamerasBody(Body):
    """``POST /api/cameras``: also probe OpenCV's indices (each opened for a moment)."""

    opencv: bool = True


class CameraBody(Body):
    """``POST /api/source/camera``: the camera to serve (``camera`` as ``--camera`` takes it: an OpenCV index or
    ``basler:SERIAL``) and, for a machine-vision camera, its acquisition settings (as ``psvs serve``'s options:
    exposure, gain, trigger, ``NAME=VALUE`` features in order)."""

    camera: str = Field(min_length=1, max_length=100)
    exposure_us: float | None = Field(default=None, gt=0, le=1e8)
    gain_db: float | None = Field(default=None, ge=-100, le=100)
    trigger: Literal["software", "line1"] | None = None
    features: list[str] = Field(default_factory=list, max_length=50)

    @field_validator("features")
    @classmethod
    def _short(cls, v: list[str]) -> list[str]:
        if any(len(item) > 500 for item in v):
            raise ValueError("a camera feature NAME=VALUE is at most 500 characters")
        return v
