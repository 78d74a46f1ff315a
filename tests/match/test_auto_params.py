"""AutoParams and MatchParams: the matching tuning, checked when built; match_auto uses its params."""
import numpy as np
import pytest

from psvs.match.auto import AutoParams, match_auto
from psvs.match.correspondence import MatchParams
from tests.support.scenes import POLY, paper_edges


@pytest.mark.parametrize("field, value, message", [
    ("min_rows", 0, r"min_rows must be an integer >= 1, got 0"),
    ("min_rows", 10.5, r"min_rows must be an integer >= 1, got 10.5"),
    ("long_run_rows", True, r"long_run_rows must be an integer >= 1, got True"),
    ("min_run", -1, r"min_run must be an integer >= 1"),
    ("standalone_rows", 0, r"standalone_rows must be an integer >= 1"),
    ("support_px", -1, r"support_px must be an integer >= 0"),
    ("min_fraction", 1.5, r"min_fraction must be in \[0, 1\], got 1.5"),
    ("seen_fraction", -0.1, r"seen_fraction must be in \[0, 1\]"),
    ("seen_fraction", float("nan"), r"seen_fraction must be finite"),
    ("tol_px", -1.0, r"tol_px must be >= 0 px"),
    ("polarity_level", -2.0, r"polarity_level must be >= 0 grey levels"),
])
def test_bad_tuning_is_refused_naming_the_field(field, value, message):
    with pytest.raises(ValueError, match=message):
        AutoParams(**{field: value})


def test_defaults_and_integers_of_numpy():
    p = AutoParams(min_rows=np.int64(12))
    assert p.min_rows == 12 and p.standalone_rows == 30 and p.seen_fraction == 0.8


def test_match_auto_uses_its_params():
    """The twin agrees on ~230 rows: found by default, not when 300 rows are asked for."""
    edges = paper_edges([POLY, POLY - [130, 0]])
    assert len(match_auto(edges, (80, 250)).pairs) == 1
    m = match_auto(edges, (80, 250), params=AutoParams(min_rows=300, standalone_rows=300))
    assert not m.pairs and len(m.unmatched) == 2
    with pytest.raises(TypeError, match="params must be an AutoParams, got dict"):
        match_auto(edges, (80, 250), params={"min_rows": 300})


@pytest.mark.parametrize("kwargs, message", [
    ({"subpixel": 1}, r"subpixel must be True or False, got 1"),
    ({"model": "pinhole"}, r"model must be one of paper, refraction, exact or None, got 'pinhole'"),
    ({"n_seeds": 1}, r"n_seeds must be an integer in 2..100 \(the paper's range\), got 1"),
    ({"auto": {"min_rows": 5}}, r"auto must be an AutoParams, got dict"),
])
def test_bad_match_params_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        MatchParams(**kwargs)
