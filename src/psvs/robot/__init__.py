"""Robot path control with the PSVS on a PUMA-family arm: arm, hand-eye, seam sensor, path model, loop."""
