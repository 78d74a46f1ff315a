"""The study's report by value: planted rows whose scores are known functions of the deviations; scores.json read
back against numpy and scipy computed here; the figures are PNGs; all files or none."""
import json
import math

import numpy as np
import pyarrow as pa
import pytest
from scipy.stats import spearmanr

from psvs.study.report import summarise, write_report
from psvs.study.sample import COLUMNS


def planted_rows(n=60, seed=0):
    """Rows: rms_3d_mm = 0.1 + |dev m2 tilt b|^2 exactly (monotone in its magnitude), row_offset_px driven by
    |m1 tilt a| plus a little of |m3 shift|, a noise deviation (k1) unrelated to both; every 10th build failed."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        row = {c: math.nan for c in COLUMNS}
        row.update({c: 0.0 for c in COLUMNS if c.startswith("dev_")})
        a, b, s, k1 = rng.uniform(-0.2, 0.2, 3).tolist() + [float(rng.normal(0, 0.05))]
        row.update(index=i, seed=seed, views_seed=i, ok=i % 10 != 9, reason="" if i % 10 != 9 else
                   f"calibration needs at least 3 usable images, got {i % 3} (skipped ...)",
                   dev_m2_tilt_b_deg=b, dev_m1_tilt_a_deg=a, dev_m3_shift_mm=s, dev_k1=k1,
                   rms_3d_mm=0.1 + b * b, max_3d_mm=0.3 + 2 * b * b, reproj_rms_px=0.02 + 0.001 * i,
                   row_offset_px=30 * abs(a) + 2 * abs(s), images_used=16, images_skipped=0, test_points=300,
                   table1_note="", cpu_s=20.0, wall_s=14.0)
        rows.append(row)
    return rows


def test_scores_json_by_value(tmp_path):
    rows = planted_rows()
    targets = {"rms_3d_mm": 0.12, "row_offset_px": 3.0}
    paths = write_report(rows, tmp_path, targets)
    assert {p.name for p in paths} == {"scores.json", "report.md", "histograms.png", "yield.png", "sensitivity.png",
                                       "sensitivity_rss.png"}
    got = json.loads((tmp_path / "scores.json").read_text())
    ok = np.array([r["ok"] for r in rows])
    rms = np.array([r["rms_3d_mm"] for r in rows])
    assert got["samples"] == 60 and got["ok"] == 54 and got["failed_fraction"] == pytest.approx(0.1)
    assert got["failure_reasons"] == {"calibration needs at least 3 usable images, got 0": 2,
                                      "calibration needs at least 3 usable images, got 1": 2,
                                      "calibration needs at least 3 usable images, got 2": 2}
    # the fraction of ALL builds meeting the target: a failed build never meets it
    assert got["targets"]["rms_3d_mm"]["fraction"] == pytest.approx(np.sum(ok & (rms <= 0.12)) / 60, abs=1e-12)
    st = got["scores"]["rms_3d_mm"]
    assert st["n"] == 54 and st["mean"] == pytest.approx(rms[ok].mean()) and st["max"] == pytest.approx(rms[ok].max())
    assert st["p90"] == pytest.approx(np.percentile(rms[ok], 90))
    # the score is exactly a monotone function of |m2 tilt b|: ranked first with rho 1
    first = got["sensitivity"]["rms_3d_mm"][0]
    assert first["parameter"] == "m2_tilt_b_deg" and first["rho"] == pytest.approx(1.0, abs=1e-12)
    ranking = {r["parameter"]: r["rho"] for r in got["sensitivity"]["row_offset_px"]}
    assert max(ranking, key=lambda k: abs(ranking[k])) == "m1_tilt_a_deg"
    m3 = np.abs([r["dev_m3_shift_mm"] for r in rows])[ok]
    off = np.array([r["row_offset_px"] for r in rows])[ok]
    assert ranking["m3_shift_mm"] == pytest.approx(spearmanr(m3, off)[0], abs=1e-12)
    assert "dev_k2" not in ranking and "k2" not in ranking           # never varied: not ranked
    md = (tmp_path / "report.md").read_text()
    assert "54 calibrated (10.0 % failed)" in md and "m2_tilt_b_deg +1.00" in md
    for name in ("histograms.png", "yield.png", "sensitivity.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_pyarrow_table_reports_the_same(tmp_path):
    """The rows as read back from the study's Parquet file (a pyarrow Table) give the same scores.json."""
    rows = planted_rows(30, seed=3)
    table = pa.Table.from_pylist(rows)
    assert summarise(table, {"max_3d_mm": 0.32}) == summarise(rows, {"max_3d_mm": 0.32})


def test_nothing_is_written_when_the_report_cannot_be(tmp_path):
    """An unknown target or a missing folder: an error, and no file of the report lands."""
    (tmp_path / "scores.json").write_text("earlier")
    with pytest.raises(ValueError, match="target 'rms_mm' is no score"):
        write_report(planted_rows(12), tmp_path, {"rms_mm": 1.0})
    with pytest.raises(FileNotFoundError, match="output folder does not exist"):
        write_report(planted_rows(12), tmp_path / "missing", {})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scores.json"]
    assert (tmp_path / "scores.json").read_text() == "earlier"
    with pytest.raises(ValueError, match="no samples to report on"):
        write_report([], tmp_path)


def test_all_failed_still_reports(tmp_path):
    """Every build failed: fractions 0, no statistics, no ranking, and valid JSON (no NaN)."""
    rows = planted_rows(6)
    for r in rows:
        r.update(ok=False, reason="the drawn build is no rig: plate_thickness_mm must be >= 0 mm, got -1")
    write_report(rows, tmp_path, {"rms_3d_mm": 1.0})
    got = json.loads((tmp_path / "scores.json").read_text())
    assert got["ok"] == 0 and got["targets"]["rms_3d_mm"]["fraction"] == 0.0
    assert got["failure_reasons"] == {"the drawn build is no rig": 6} and got["sensitivity"] == {}
    assert got["scores"]["rms_3d_mm"] == {"n": 0}


def test_rss_sensitivity_recovers_planted_effects(tmp_path):
    """A score built as the RSS model says, sqrt(0.1^2 + (3 z_a - 2 z_b)^2) with z the standardised
    deviations of m1 tilt a and m2 tilt b (signed: they partly cancel), two other deviations doing nothing: the fit
    gives 3 and 2 per sigma (within 1 %), the floor 0.1, the rest under 0.05; the rank correlation of |dev|
    at the same 60 builds is far weaker (below 0.7 for both)."""
    rows = planted_rows(60, seed=5)
    a = np.array([r["dev_m1_tilt_a_deg"] for r in rows])
    b = np.array([r["dev_m2_tilt_b_deg"] for r in rows])
    score = np.sqrt(0.1 ** 2 + (3 * (a - a.mean()) / a.std() - 2 * (b - b.mean()) / b.std()) ** 2)
    for r, v in zip(rows, score, strict=True):
        r.update(ok=True, reason="", row_offset_px=float(v))
    write_report(rows, tmp_path, {})
    got = json.loads((tmp_path / "scores.json").read_text())["rss_sensitivity"]["row_offset_px"]
    per = {r["parameter"]: r["per_sigma"] for r in got["ranking"]}
    assert [r["parameter"] for r in got["ranking"][:2]] == ["m1_tilt_a_deg", "m2_tilt_b_deg"]
    assert per["m1_tilt_a_deg"] == pytest.approx(3.0, rel=0.01) and per["m2_tilt_b_deg"] == pytest.approx(2.0, rel=0.01)
    assert per["m3_shift_mm"] < 0.05 and per["k1"] < 0.05
    assert got["floor"] == pytest.approx(0.1, abs=0.01) and got["r2"] > 0.999 and got["n"] == 60
    rho = {r["parameter"]: r["rho"] for r in json.loads((tmp_path / "scores.json").read_text())["sensitivity"]
           ["row_offset_px"]}
    assert rho["m1_tilt_a_deg"] < 0.7 and rho["m2_tilt_b_deg"] < 0.7
    assert (tmp_path / "sensitivity_rss.png").read_bytes()[:4] == b"\x89PNG"


def test_rss_is_not_fitted_on_too_few_builds():
    """4 varied deviations need 10 builds: at 8 the RSS ranking is left out, the rank correlation is not."""
    got = summarise(planted_rows(9, seed=2))     # one of the 9 failed: 8 calibrated builds
    assert "rms_3d_mm" not in got["rss_sensitivity"] and "rms_3d_mm" in got["sensitivity"]


def test_a_yield_has_its_interval_and_few_builds_no_percentiles(tmp_path):
    """An adversarial trial (2026-12-06): `montecarlo -n 2` reported p90 and p95 interpolated between two builds
    and a yield of "100.0 %". The yield now carries its 95 % Clopper-Pearson interval (checked against the beta
    distribution's quantiles), and p90/p95 need 10 and 20 builds (NaN, None in scores.json, said in report.md)."""
    from scipy.stats import beta
    rows = planted_rows()[:2]
    for r in rows:
        r.update(ok=True, reason="", rms_3d_mm=0.1)
    write_report(rows, tmp_path, {"rms_3d_mm": 0.12})
    got = json.loads((tmp_path / "scores.json").read_text())
    lo, hi = got["targets"]["rms_3d_mm"]["interval_95"]
    assert got["targets"]["rms_3d_mm"]["fraction"] == 1.0 and hi == 1.0
    assert lo == pytest.approx(beta.ppf(0.025, 2, 1), abs=1e-9)           # x = n: the lower bound alone
    st = got["scores"]["rms_3d_mm"]
    assert st["n"] == 2 and st["p90"] is None and st["p95"] is None and st["median"] == pytest.approx(0.1)
    md = (tmp_path / "report.md").read_text()
    assert "| needs 10 builds | needs 20 builds |" in md and "100.0 % (95 %: 16-100 %)" in md
    # 27 of 54: the interval of a middle yield, both ends by the beta distribution
    from psvs.study.report import yield_interval
    lo, hi = yield_interval(27, 54)
    assert lo == pytest.approx(beta.ppf(0.025, 27, 28), abs=1e-9) and hi == pytest.approx(beta.ppf(0.975, 28, 27),
                                                                                         abs=1e-9)
