"""Rig geometry and exact optics: mirrors, plate refraction, tracing, projection, mirror design."""
