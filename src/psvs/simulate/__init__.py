"""Render PSVS complex images of 3-D scenes through the exact optics, with a realistic sensor."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=["render", "textures"],
    submod_attrs={
        "builtin": ["BUILTINS", "builtin_scene", "describe", "parse_spec", "regulated_light", "seam_centre_line",
                    "weld_seam"],
        "geometry": ["MovedGeometry", "SceneGeometry"],
        "render": ["SAMPLE_SECONDS", "check_render_work", "check_supersample", "render_seconds", "render_views"],
        "scene": ["KINDS", "MAX_OBJECTS", "Lighting", "Pose", "Scene", "SceneObject", "check_object_count"],
        "sensor": ["MAX_BLUR_PX", "Sensor", "expose"],
        "sequence": ["render_from", "render_sequence", "scene_in_rig_frame", "straight_path"],
        "textures": ["AsymmetricCircleGrid", "CharucoBoard", "CircleGrid", "Circles", "Uniform"],
    },
)
