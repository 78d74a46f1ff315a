"""Correspondence on the complex image: the paper's seeded edge algorithm (III.3), automatic pairing of
every edge with its twin, sub-pixel refinement, and 3-D output."""
