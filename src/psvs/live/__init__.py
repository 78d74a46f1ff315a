"""Live sensing: frame sources (video, camera, simulated sequences) and a frame-to-frame edge tracker."""
