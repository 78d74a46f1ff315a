"""An ordered, configurable image pipeline; the paper's own (median 3x3, threshold 92, Roberts) is the default.

Pipelines are read from TOML files by :func:`psvs.io.pipeline_file.load_pipeline`.
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

from psvs._validate import check_grey
from psvs.imaging.steps import STEPS, check_param


@dataclass(frozen=True)
class Step:
    """One step of a pipeline: ``op``, the name of an operation of :data:`STEPS`, and its parameters as
    (name, value) pairs; an unknown operation is refused when the step is made."""

    op: str
    params: tuple[tuple[str, object], ...] = ()

    def __post_init__(self):
        if self.op not in STEPS:
            raise ValueError(f"unknown pipeline step {self.op!r} (known: {', '.join(STEPS)})")
        allowed = list(inspect.signature(STEPS[self.op]).parameters)[1:]
        for k, v in self.params:
            if k not in allowed:
                raise ValueError(f"step {self.op!r}: unknown parameter {k!r} (allowed: {', '.join(allowed) or 'none'})")
            check_param(self.op, k, v)

    def __call__(self, img):
        return STEPS[self.op](img, **dict(self.params))


@dataclass(frozen=True)
class Pipeline:
    """Steps applied in order to a grey (H, W) uint8 image; the last must give a bool edge map."""

    steps: tuple[Step, ...]

    def __post_init__(self):
        if not self.steps:
            raise ValueError("a pipeline needs at least one step")

    def run(self, grey: np.ndarray, keep: bool = False):
        """Edge map (H, W) bool; with ``keep``, also a list of (op, image) after every step."""
        grey = check_grey(grey)
        stages = []
        img = grey
        for step in self.steps:
            img = step(img)
            if keep:
                stages.append((step.op, img))
        if img.dtype != bool:
            raise ValueError(f"the pipeline must end with an edge detector or threshold, got {self.steps[-1].op!r}")
        return (img, stages) if keep else img

    def to_dict(self) -> dict:
        """The pipeline as ``{"steps": [{"op": name, param: value, ...}, ...]}`` (:func:`make_pipeline` reads it)."""
        return {"steps": [{"op": s.op, **dict(s.params)} for s in self.steps]}


def make_pipeline(steps: list[dict]) -> Pipeline:
    """A pipeline from a list of {"op": name, param: value, ...}."""
    out = []
    for i, spec in enumerate(steps):
        if not isinstance(spec, dict) or "op" not in spec:
            raise ValueError(f"steps[{i}] must be a table with 'op', got {spec!r}")
        out.append(Step(spec["op"], tuple((k, v) for k, v in spec.items() if k != "op")))
    return Pipeline(tuple(out))


#: The paper's pipeline (section IV.2): median filter, binary conversion at 92, Roberts edges.
PAPER = make_pipeline([{"op": "median", "ksize": 3}, {"op": "threshold", "level": 92}, {"op": "roberts"}])
