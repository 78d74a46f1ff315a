"""Mirror mounts: the three-point seat of each mirror (:mod:`psvs.mount.seats`) and the alignment guide
that turns a calibrated build into screw turns (:mod:`psvs.mount.guide`). docs/mount.md."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=["report"],
    submod_attrs={
        "build": ["make_mount"],
        "cad": ["MissingExtra", "require_cad"],
        "files": ["read_mount", "read_mount_text"],
        "guide": ["alignment_guide", "check_aligned", "designed_twin", "row_offsets_px", "working_points"],
        "layout": ["INTERFACES", "MountError", "MountParams"],
        "report": ["check_same_design", "format_guide", "guide_to_dict"],
        "seats": ["DEFAULT_PITCH_MM", "PITCH_RANGE_MM", "Seat", "check_pitch", "seats_for"],
        "stl_view": ["MAX_FACES", "mount_mesh"],
    },
)
