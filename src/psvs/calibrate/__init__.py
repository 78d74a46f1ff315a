"""Targets in complex images and measurement of the paper's accuracy pattern (Table I)."""
