"""Live sensing: frame sources (video, camera, simulated sequences) and a frame-to-frame edge tracker."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "camera": ["Acquisition", "CameraLost", "CameraSpec", "Frame", "TRIGGERS", "parse_camera", "parse_features",
                   "vendor_module"],
        "drift_gate": ["WITHHELD", "drifted", "withheld"],
        "discover": ["FoundCamera", "OPENCV_INDICES", "opencv_cameras", "vendor_cameras"],
        "dense": ["DenseFrame", "DenseSensor"],
        "log": ["HEALTH_COLUMNS", "health_cells", "write_log"],
        "simulated": ["SimulatedSequence", "ping_pong_positions"],
        "source": ["SEQUENCE_SUFFIXES", "open_camera", "open_video", "sequence_files"],
        "tracker": ["EdgeTracker", "TrackStep", "TrackerParams", "nearest_edge_pixels"],
    },
)
