"""Rig geometry and exact optics: mirrors, plate refraction, tracing, projection, mirror design, the rig's
3-D layout."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=["pinhole_views", "rectify"],
    submod_attrs={
        "bounds": ["check_rig_bounds"],
        "design": ["MAX_BLOCKED_SHARE", "MirrorDesign", "design_mirrors", "share_words"],
        "field": ["field_pixels"],
        "illumination": ["flat_field", "illumination_map"],
        "layout3d": ["rig_layout"],
        "layout_check": ["check_clear"],
        "mirrors": ["VIEWS", "check_in_front", "direction_map", "front_z_mm", "mirror_planes", "virtual_baseline_mm",
                    "virtual_centre"],
        "obstruction": ["blocked_shares", "find_obstructions", "plate_edges", "sized_shares"],
        "pinhole_views": ["PinholeView"],
        "plate": ["FILE_MARGIN_MM", "PLAUSIBLE_PLATE", "derived_refraction_terms", "file_refraction_terms",
                  "plausible_refraction_terms", "refraction_terms"],
        "project": ["epipolar_curve_px", "epipolar_curves_px", "in_image", "project_from", "project_points"],
        "rectify": ["Rectification", "forget", "needs_rectification", "remember", "remembered"],
        "rig": ["Calibration", "Camera", "MIRROR_NAMES", "MirrorError", "MirrorExtent", "Mirrors", "Rig",
                "default_rig"],
        "scale": ["PAPER_FOCAL_PX", "pixel_scale"],
        "search_range": ["disparity_range", "rectification_for", "working_disparities"],
        "solids": ["finite_solids", "segments_hit"],
        "trace": ["Rays", "camera_dirs", "distort", "ideal_sensor_from_pixels", "lit_pairs", "pixels_from_camera_dirs",
                  "trace_camera_rays", "trace_pixels", "undistort"],
        "window": ["roi_rig"],
    },
)
