"""The corpus's bad rig files (given to any command) and the cases of the commands that run work at scale:
psvs batch, mount and montecarlo (tests/corpus/cases.py gathers them with the rest)."""
from __future__ import annotations

import numpy as np

from tests.corpus.files import DEFAULT_RIG, nested, rig_text, texture_png
from tests.corpus.runner import Case

R = ("--rig", "rig.toml")


def rig_cases(command: tuple[str, ...], stem: str) -> list[Case]:
    """Bad rig files given to ``command`` (its --rig is rig.toml)."""
    bad = {
        "missing": (None, "not found"),
        "malformed": ("[camera\nfocal_length_mm = 11.3\n", "malformed"),
        "nested-deep": (nested(), ""),
        "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(40), ""),
        "unknown-key": (rig_text(extra="\n[camera2]\nx = 1\n"), "unknown"),
        "missing-key": (rig_text("focal_length_mm = 11.3\n", ""), "focal_length_mm"),
        "negative-focal": (rig_text("focal_length_mm = 11.3", "focal_length_mm = -11.3"), "focal_length_mm"),
        "huge-focal": (rig_text("focal_length_mm = 11.3", "focal_length_mm = 1e308"), "focal_length_mm"),
        "nan-focal": (rig_text("focal_length_mm = 11.3", "focal_length_mm = nan"), "focal_length_mm"),
        "string-focal": (rig_text("focal_length_mm = 11.3", 'focal_length_mm = "long"'), "focal_length_mm"),
        "principal-point-far": (rig_text("principal_point_px = [319.5, 239.5]",
                                         "principal_point_px = [1e12, 239.5]"), "principal_point"),
        "distortion-huge": (rig_text(extra="", base=DEFAULT_RIG.replace(
            "principal_point_px = [319.5, 239.5]",
            "principal_point_px = [319.5, 239.5]\ndistortion = [1e6, 0, 0, 0, 0]")), "distortion"),
        "refraction-huge": (rig_text("split_ratio = 0.5", "split_ratio = 0.5\nrefraction_l_mm = 1e300\n"
                                                          "refraction_m_mm = -1e300"), "refraction"),
        "sensor-huge": (rig_text("image_size_px = [640, 480]", "image_size_px = [200000, 200000]"), "image_size"),
        "tilt-89": (rig_text(extra="\n[mirrors.m2]\ntilt_deg = [89.0, 0.0]\n"), "tilt"),
        "box-turned": (rig_text("split_ratio = 0.5", "split_ratio = 0.5\nbox_rotation_deg = [1e9, 0, 0]"), "box"),
        "split-one": (rig_text("split_ratio = 0.5", "split_ratio = 1.0"), "split_ratio"),
        "index-below-one": (rig_text("refractive_index = 1.52", "refractive_index = 0.5"), "refractive_index"),
        "m2-before-m1": (rig_text("m2_axis_distance_mm = 44.0", "m2_axis_distance_mm = 10.0"), "m2_axis"),
        "pitch-zero": (rig_text("pixel_pitch_mm = [0.01, 0.01]", "pixel_pitch_mm = [0.0, 0.01]"), "pixel_pitch"),
    }
    cases = []
    for name, (content, says) in bad.items():
        files = {} if content is None else {"rig.toml": content}
        cases.append(Case(f"{stem}-rig-{name}", command, 2, says, files))
    return cases


def video_bytes(w: int = 640, h: int = 480, frames: int = 2) -> bytes:
    """A lossless FFV1 video of textured frames."""
    import tempfile
    from pathlib import Path

    from psvs.io.video import write_video
    rng = np.random.default_rng(2)
    with tempfile.TemporaryDirectory() as tmp:
        write_video(Path(tmp) / "v.avi", [rng.integers(0, 256, (h, w), dtype=np.uint8) for _ in range(frames)])
        return (Path(tmp) / "v.avi").read_bytes()


def batch_cases() -> list[Case]:
    """psvs batch: refused before any cluster starts or any file is written (the scheduler: before a file)."""
    base = ("batch", "disparity", "v.avi", "--rig", "default", "-o", "out")
    video = {"v.avi": lambda f: video_bytes()}
    return [
        Case("batch-scheduler-unreachable", (*base, "--scheduler", "tcp://127.0.0.1:9"), 2, "cannot reach", video),
        Case("batch-scheduler-not-an-address", (*base, "--scheduler", "http://x"), 2, "tcp://HOST:PORT", video),
        Case("batch-workers-zero", (*base, "--workers", "0"), 2, "--workers", video),
        Case("batch-sequence-pattern-huge", ("batch", "disparity", "seq_%999999999d.png", "--rig", "default", "-o",
                                              "out"), 2, "at most 12"),
        Case("batch-workers-and-scheduler", (*base, "--workers", "2", "--scheduler", "tcp://127.0.0.1:9"), 2,
             "--workers", video),
        Case("batch-missing-input", base, 2, "not found"),
        Case("batch-one-image", ("batch", "match", "a.png", "--rig", "default", "-o", "out", "--auto"), 2,
             "one image", {"a.png": texture_png()}),
        Case("batch-output-is-the-input-folder", ("batch", "match", "in", "--rig", "default", "-o", "in", "--auto"),
             2, "folder of the images", {"in/a.png": texture_png()}),
        Case("batch-empty-folder", ("batch", "match", "in", "--rig", "default", "-o", "out", "--auto"), 2,
             "no image", {"in/notes.txt": "no images here"}),
        Case("batch-not-a-video", base, 2, "v.avi", {"v.avi": b"RIFF" + bytes(100)}),
        Case("batch-video-wrong-size", base, 2, "640x480", {"v.avi": lambda f: video_bytes(320, 240)}),
        Case("batch-bad-option", (*base, "--split", "1.5"), 2, "split", video),
        Case("batch-figures-per-frame", ("batch", "match", "v.avi", "--rig", "default", "-o", "out", "--auto",
                                         "--figures", "."), 2, "--figures", video),
        Case("batch-output-is-a-file", base, 2, "out", video, ("out",)),
        Case("batch-other-parameters", base, 2, "parameter file", video, ("out/study.json",)),
        Case("batch-rig-missing", ("batch", "disparity", "v.avi", "--rig", "none.toml", "-o", "out"), 2,
             "not found", video),
        Case("batch-no-rig", ("batch", "disparity", "v.avi", "-o", "out", "--min-disparity", "5",
                              "--max-disparity", "50"), 2, "--rig", video),
    ]


def mount_cases() -> list[Case]:
    """psvs mount: the design (--rig), the output folder and the builder's choices."""
    base = ("mount", *R, "-o", "m")
    good = {"rig.toml": DEFAULT_RIG}
    return rig_cases(base, "mount") + [
        Case("mount-output-is-a-file", ("mount", *R, "-o", "afile"), 2, "afile", good, ("afile",)),
        Case("mount-wall-negative", (*base, "--wall-mm", "-2"), 2, "wall_mm", good),
        Case("mount-wall-nan", (*base, "--wall-mm", "nan"), 2, "wall_mm", good),
        Case("mount-wall-thinner-than-a-nozzle", (*base, "--wall-mm", "0.01"), 2, "thinnest wall the printer makes: "
             "at least 0.4 mm", good),
        Case("mount-clearance-huge", (*base, "--clearance-mm", "9"), 2, "clearance_mm", good),
        Case("mount-lens-zero", (*base, "--lens-diameter-mm", "0"), 2, "lens_diameter_mm", good),
        Case("mount-lens-front-inf", (*base, "--lens-front-mm", "inf"), 2, "lens_front_mm", good),
        Case("mount-interface-unknown", (*base, "--interface", "m42"), 2, "invalid choice", good),
        Case("mount-pitch-text", (*base, "--pitch-mm", "fine"), 2, "pitch", good),
        Case("mount-near-beyond-far", (*base, "--near-mm", "900", "--far-mm", "500"), 2, "near", good),
    ]


def montecarlo_cases() -> list[Case]:
    """psvs montecarlo: the nominal rig, the tolerance file, the counts, the folder and the cluster."""
    base = ("montecarlo", *R, "--tolerances", "tol.toml", "-n", "2", "-o", "s")
    good = {"rig.toml": DEFAULT_RIG, "tol.toml": "[calibration]\nviews = 4\n"}
    return rig_cases(base, "montecarlo") + [
        Case("montecarlo-tol-missing", (*base[:3], "--tolerances", "none.toml", *base[5:]), 2, "not found",
             {"rig.toml": DEFAULT_RIG}),
        Case("montecarlo-tol-malformed", base, 2, "malformed", {**good, "tol.toml": "[calibration\n"}),
        Case("montecarlo-tol-unknown-key", base, 2, "lens_tilt", {**good, "tol.toml": "[tolerances]\nlens_tilt = 1\n"}),
        Case("montecarlo-tol-negative-width", base, 2, "uniform", {**good, "tol.toml":
             "[tolerances]\nm1_shift_mm = { uniform = -0.5 }\n"}),
        Case("montecarlo-n-zero", (*base[:5], "-n", "0", "-o", "s"), 2, "-n", good),
        Case("montecarlo-n-text", (*base[:5], "-n", "many", "-o", "s"), 2, "-n", good),
        Case("montecarlo-seed-negative", (*base, "--seed", "-3"), 2, "--seed", good),
        Case("montecarlo-output-is-a-file", (*base[:7], "-o", "afile"), 2, "afile", good, ("afile",)),
        Case("montecarlo-scheduler-not-an-address", (*base, "--scheduler", "nowhere"), 2, "--scheduler", good),
        Case("montecarlo-workers-zero", (*base, "--workers", "0"), 2, "--workers", good),
        Case("montecarlo-a-million-samples", (*base[:5], "-n", "1000000", "-o", "s", "--workers", "2"), 2,
             "more than the 1 day limit", good),
        Case("montecarlo-card-too-wide", base, 2, "calibration.card", {**good, "tol.toml":
             "[calibration]\ncard = { rows = 9, cols = 15, spacing_mm = 30.0, diameter_mm = 12.0 }\n"}),
    ]


