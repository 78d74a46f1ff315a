"""Dense disparity and view separation from a single complex image (docs/dense.md)."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "build": ["RigDense", "dense_on_rig", "rectified_images", "rig_cloud", "rig_depth", "rig_trust"],
        "cloud": ["Cloud", "disparity_cloud", "write_cloud_ply"],
        "compiled": ["announce_dense"],
        "disparity": ["DenseResult", "check_dense_memory", "check_range", "constant_refusal", "dense_disparity"],
        "echo_test": ["BLOCK_CELLS", "CELL_PX", "MIN_LAGS"],
        "evaluate": ["check_truth_fits", "evaluate_pair", "motorcycle", "truth_fit"],
        "params": ["DEFAULT", "DenseParams", "FAST", "searched_lags"],
        "report": ["scores_markdown", "write_report"],
        "rig_cache": ["filled_maps", "rectification"],
        "separate": ["SeparationParams", "psnr_db", "rig_views", "separate_views"],
        "refusal": ["elsewhere_words", "mirror_words", "nothing_answered", "nothing_trusted", "periodic_words",
                    "repeat_words", "strongest_echo"],
        "trust": ["ALPHA", "TOL_PX", "EchoTrust", "trusted_maps", "within_disparities"],
        "workspace": ["Workspace"],
    },
)
