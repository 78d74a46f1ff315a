"""``psvs mount`` as a library call: design -> layout -> solid -> STEP and STL -> read back and checked ->
drawing, bill of materials and ``mount.toml``, all in memory until every check has passed."""
from __future__ import annotations

import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

from psvs.mount.layout import MountError, MountLayout, MountParams, field_segments, mount_layout
from psvs.optics.design import design_mirrors
from psvs.optics.rig import Rig

#: The STEP's volume read back must match the layout's own sum of parts to this share.
VOLUME_REL_TOL = 1e-4


@dataclass(frozen=True)
class MadeMount:
    """A checked mount: its ``layout``, the ``checks`` (:class:`psvs.mount.check.MountChecks`), the
    STEP's read-back ``step_solids`` and ``step_volume_mm3``, and ``files`` {name: bytes}."""

    layout: MountLayout
    checks: object
    step_solids: int
    step_volume_mm3: float
    files: dict


def make_mount(rig: Rig, params: MountParams = MountParams(), near_mm: float = 400.0,
               far_mm: float = 1200.0) -> MadeMount:
    """Design the rig's mirrors, lay out and build the mount, write and re-read its STEP and STL, and check
    them against the optics. MountError (naming the culprit, nothing made) when the design is blocked,
    the layout cannot be built, or a check fails."""
    from psvs.mount.cad import build_solid, read_step, write_step, write_stl
    from psvs.mount.check import check_mount, printable_mesh
    from psvs.mount.drawing import render_drawing
    from psvs.mount.files import bom_csv, mount_toml
    design = design_mirrors(rig, margin_mm=params.margin_mm, near_mm=near_mm, far_mm=far_mm, search=False)
    if not design.ok:
        raise MountError("the layout is blocked: " + "; ".join(design.problems))
    segments = field_segments(design.rig, far_mm)
    layout = mount_layout(design, params, far_mm, segments)
    solid = build_solid(layout)
    with tempfile.TemporaryDirectory(prefix="psvs-mount-") as tmp:
        step, stl = Path(tmp) / "mount.step", Path(tmp) / "mount.stl"
        write_step(solid, step)
        write_stl(solid, stl)
        n_solids, volume = read_step(step)
        mesh = printable_mesh(stl)
        files = {"mount.step": step.read_bytes(), "mount.stl": stl.read_bytes()}
    problems = []
    if n_solids != 1:
        problems.append(f"the STEP holds {n_solids} solids, not one")
    if abs(volume - layout.volume_mm3) > VOLUME_REL_TOL * layout.volume_mm3:
        problems.append(f"the STEP's volume {volume:.1f} mm^3 is not the parts' {layout.volume_mm3:.1f} mm^3 "
                        "(parts overlap)")
    checks = check_mount(layout, mesh, segments)
    problems += checks.problems(layout)
    if problems:
        raise MountError("; ".join(problems))
    lo, hi = mesh.bounds
    svg, png = render_drawing(layout, segments, tuple(float(v) for v in hi - lo))
    summary = {**{k: v for k, v in asdict(checks).items() if k not in ("blocked_by", "hardware_blocked_by")},
               "step_solids": n_solids, "step_volume_mm3": volume, "far_mm": far_mm}
    files.update({"drawing.svg": svg, "drawing.png": png, "bom.csv": bom_csv(layout).encode(),
                  "mount.toml": mount_toml(layout, summary).encode()})
    return MadeMount(layout, checks, n_solids, volume, files)
