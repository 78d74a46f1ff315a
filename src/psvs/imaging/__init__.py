"""Image processing for the correspondence algorithm: filters, binarisation, edges, pipelines.
Knows nothing about rigs."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "block_grid": ["BLOCK_GRID_LIMIT", "block_grid_refusal", "block_grid_strength", "check_block_grid"],
        "edge_noise": ["MIN_STABLE_SHARE", "EdgeStability", "edge_stability"],
        "grey": ["to_grey8"],
        "noise": ["NoiseLevel", "noise_level"],
        "pipeline": ["PAPER", "Pipeline", "make_pipeline"],
        "steps": ["STEPS"],
    },
)
