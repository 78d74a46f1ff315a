"""From matched pixels to millimetres: the paper's equations (9)-(17) and exact triangulation."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=["triangulate"],
    submod_attrs={
        "model_check": ["MODEL_ERROR_NOTE", "check_closed_form", "closed_form_depth_error", "closed_form_excess",
                        "designed", "model_error_note"],
        "refraction_fit": ["fit_refraction"],
        "tolerance": ["Sensitivity", "field_points", "tolerance_analysis"],
        "triangulate": ["EPIPOLAR_TOL_PX", "MATCH_SIGMA_PX", "MODELS", "Triangulation", "default_model",
                        "depth_sigma_mm", "epipolar_gap_px", "fit_refraction_terms", "twin_rows"],
    },
)
