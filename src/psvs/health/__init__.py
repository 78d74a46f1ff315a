"""A sensor that knows when it has been knocked: the twins' rows checked on ordinary frames (docs/health.md).

``rows`` reads each tile's twin row offset off one frame through a calibration, tested against chance; ``field``
is the smooth field a moved mirror makes and its robust fit; ``check`` judges it (``psvs check``); ``explain``
says which mirrors' tilts best explain it; ``figure`` draws the field; ``rolling`` keeps the check going on a
running sensor's frames at a small share of its time (``psvs live``); ``unseen`` puts a figure on what the rows
cannot show (a mirror turned about the vertical).
"""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "check": ["HealthCheck", "OVERLAP", "QUICK_TILES", "SPARE_TILES", "TOLERANCE_PX", "WEAK_SHARE", "check_frames",
                  "frame_checker",
                  "checked_tolerance", "covered_regions", "evidence_factors", "independent_tiles", "judge",
                  "judged_pairs_px", "refuse_if_drifted", "whole_check_due"],
        "explain": ["Explanation", "explain_drift", "explain_offsets", "explanation_line", "tilted"],
        "field": ["MAX_TURN_DEG", "curvature_bound_px", "field_basis", "robust_fit"],
        "figure": ["offset_figure"],
        "rolling": ["FIRST_COST_S", "HealthEvent", "RollingCheck", "SHARE", "health_record"],
        "rows": ["FrameTiles", "frame_tiles", "spread_tiles"],
        "unseen": ["QUOTED_TURN_RAD", "depth_share_of_turn", "not_checked_line"],
    },
)
