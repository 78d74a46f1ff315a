"""The report of a Monte-Carlo study (docs/tolerancing.md): ``scores.json``, ``report.md`` and figures from the
samples' rows (:func:`psvs.study.sample.run_sample`; a list of dicts, or a ``pyarrow.Table`` read back
from the study's Parquet file).

- **Statistics** of each score over the builds whose calibration succeeded: count, mean, median, 90th and
  95th percentile, max.
- **Yield**: the fraction of *all* builds meeting each target of ``[targets]`` (a build whose calibration
  failed, or whose score is NaN, does not meet it), and the fraction whose calibration failed, with the
  reasons counted.
- **RSS sensitivity** (:mod:`psvs.study.sensitivity`): for each score, the root-sum-square model of
  optical tolerancing fitted to the builds: the score one standard deviation of each tolerance adds in
  quadrature, ranked; it sees the deviations' signs, so it finds errors that add or cancel with others.
- **Sensitivity ranking**: for each score, Spearman's rank correlation (:func:`scipy.stats.spearmanr`) of
  each drawn deviation's *magnitude* |dev| with the score, over the successful builds, ranked by
  |rho|. The magnitude: a tilt either way worsens a build alike, so the signed deviation would hide it.
  Deviations that do not vary (not toleranced) are left out.

Figures (matplotlib, Agg): ``histograms.png`` (one panel per score, its target marked with the fraction
meeting it), ``yield.png`` (the fraction of builds at or below each value of each score: read any target
off it), ``sensitivity.png`` (the rank correlations' top deviations per score) and ``sensitivity_rss.png``
(the RSS fit's). Every file is written
atomically, all together (:func:`psvs.io.atomic.output_batch`).
"""
from __future__ import annotations

import io
import json
import math
from collections import Counter
from pathlib import Path

import numpy as np

from psvs.io.atomic import output_batch, write_atomic
from psvs.io.jsonsafe import json_safe
from psvs.study.sample import SCORES

#: Deviations shown per score in sensitivity.png and report.md.
TOP = 8


def _columns(rows) -> dict:
    """Column name -> list of values, from a list of row dicts or anything with ``to_pydict`` (pyarrow)."""
    if isinstance(rows, dict):
        return rows
    if hasattr(rows, "to_pydict"):
        return rows.to_pydict()
    rows = list(rows)
    if not rows:
        raise ValueError("no samples to report on")
    return {k: [r.get(k) for r in rows] for k in rows[0]}


def _floats(values) -> np.ndarray:
    return np.array([math.nan if v is None else float(v) for v in values], dtype=float)


#: The fewest builds a percentile is read from: with fewer, the q-th percentile lies beyond every build but
#: the largest and is an interpolation, no estimate (an adversarial trial: p90 and p95 of 2 builds).
MIN_BUILDS = {"p90": 10, "p95": 20}


def _stats(x: np.ndarray) -> dict:
    """A score's statistics over the builds that gave it: n, mean, median, p90, p95 (NaN with fewer than
    :data:`MIN_BUILDS` builds), max."""
    x = x[np.isfinite(x)]
    if not len(x):
        return {"n": 0}
    q = np.percentile(x, [50, 90, 95])
    out = {"n": int(len(x)), "mean": float(x.mean()), "median": float(q[0]), "p90": float(q[1]),
           "p95": float(q[2]), "max": float(x.max())}
    out.update({k: math.nan for k, m in MIN_BUILDS.items() if len(x) < m})
    return out


def yield_interval(met: int, n: int) -> tuple[float, float]:
    """The 95 % Clopper-Pearson interval of a yield of ``met`` builds of ``n`` (fractions 0-1): 2 of 2 builds
    meeting a target is a yield of 16-100 %, not 100 %."""
    from scipy.stats import binomtest
    ci = binomtest(int(met), int(n)).proportion_ci(0.95, method="exact")
    return float(ci.low), float(ci.high)


def sensitivity(cols: dict, ok: np.ndarray) -> dict:
    """score -> list of {"parameter", "rho", "p"} (Spearman of |deviation| with the score over the
    successful builds), ranked by |rho|; parameters without variation are left out."""
    from scipy.stats import spearmanr
    devs = [k for k in cols if k.startswith("dev_")]
    out = {}
    for score in SCORES:
        if score not in cols:
            continue
        y = _floats(cols[score])
        ranking = []
        for d in devs:
            x = np.abs(_floats(cols[d]))
            use = ok & np.isfinite(x) & np.isfinite(y)
            if use.sum() < 3 or np.ptp(x[use]) == 0 or np.ptp(y[use]) == 0:
                continue
            rho, p = spearmanr(x[use], y[use])
            ranking.append({"parameter": d[4:], "rho": float(rho), "p": float(p)})
        if ranking:
            out[score] = sorted(ranking, key=lambda r: -abs(r["rho"]))
    return out


def rss(cols: dict, ok: np.ndarray) -> dict:
    """score -> :func:`psvs.study.sensitivity.rss_ranking` over the successful builds with a finite score
    (scores it cannot be fitted to are left out)."""
    from psvs.study.sensitivity import rss_ranking
    devs = [k for k in cols if k.startswith("dev_")]
    out = {}
    for score in SCORES:
        if score not in cols:
            continue
        y = _floats(cols[score])
        use = ok & np.isfinite(y)
        if use.sum() == 0 or np.ptp(y[use]) == 0:
            continue
        fit = rss_ranking({d[4:]: _floats(cols[d])[use] for d in devs}, y[use])
        if fit is not None:
            out[score] = fit
    return out


def summarise(rows, targets: dict | None = None) -> dict:
    """What ``scores.json`` holds: samples, failures (fraction and reasons), each score's statistics, each
    target's yield and the sensitivity ranking."""
    cols = _columns(rows)
    n = len(cols["ok"])
    ok = np.array([bool(v) for v in cols["ok"]])
    reasons = Counter(_reason_kind(str(r)) for r, good in zip(cols.get("reason", [""] * n), ok, strict=True)
                      if not good)
    scores = {s: _stats(_floats(cols[s])[ok]) for s in SCORES if s in cols}
    yields = {}
    for name, limit in (targets or {}).items():
        if name not in cols:
            raise ValueError(f"target {name!r} is no score of the samples (scores: {', '.join(SCORES)})")
        y = _floats(cols[name])
        met = ok & np.isfinite(y) & (y <= limit)
        yields[name] = {"target": float(limit), "fraction": float(met.sum() / n), "met": int(met.sum()),
                        "interval_95": yield_interval(int(met.sum()), n)}
    return {"samples": n, "ok": int(ok.sum()), "failed_fraction": float(1 - ok.sum() / n),
            "failure_reasons": dict(reasons.most_common()), "scores": scores, "targets": yields,
            "sensitivity": sensitivity(cols, ok), "rss_sensitivity": rss(cols, ok)}


def _png(fig) -> bytes:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


def _grid(n: int):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ncol = min(n, 3)
    nrow = max(1, math.ceil(n / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    return fig, axes.ravel()


def _figures(cols: dict, summary: dict) -> dict:
    """File name -> PNG bytes: histograms, yield curves and the sensitivity ranking."""
    ok = np.array([bool(v) for v in cols["ok"]])
    shown = [s for s in SCORES if s in cols and np.isfinite(_floats(cols[s])[ok]).any()]
    out = {}
    fig, axes = _grid(max(len(shown), 1))
    fig2, axes2 = _grid(max(len(shown), 1))
    for ax, ax2, s in zip(axes, axes2, shown, strict=False):
        x = _floats(cols[s])[ok]
        x = np.sort(x[np.isfinite(x)])
        ax.hist(x, bins=min(30, max(5, len(x) // 3)), color="tab:blue")
        ax2.step(x, np.arange(1, len(x) + 1) / len(ok), where="post")
        ax.set_xlabel(s)
        ax2.set_xlabel(s)
        ax.set_ylabel("builds")
        ax2.set_ylabel("fraction of all builds <= value")
        t = summary["targets"].get(s)
        if t:
            for a in (ax, ax2):
                a.axvline(t["target"], color="tab:red", lw=1)
            ax.set_title(f"{100 * t['fraction']:.0f} % of builds <= {t['target']:g}")
    out["histograms.png"], out["yield.png"] = _png(fig), _png(fig2)
    ranked = [s for s in shown if s in summary["sensitivity"]]
    fig, axes = _grid(max(len(ranked), 1))
    for ax, s in zip(axes, ranked, strict=False):
        top = summary["sensitivity"][s][:TOP][::-1]
        ax.barh([r["parameter"] for r in top], [r["rho"] for r in top], color="tab:green")
        ax.set_xlim(-1, 1)
        ax.set_title(f"{s}: Spearman rho of |deviation|", fontsize=9)
        ax.tick_params(labelsize=7)
    out["sensitivity.png"] = _png(fig)
    fitted = [s for s in shown if s in summary["rss_sensitivity"]]
    fig, axes = _grid(max(len(fitted), 1))
    for ax, s in zip(axes, fitted, strict=False):
        f = summary["rss_sensitivity"][s]
        top = f["ranking"][:TOP][::-1]
        ax.barh([r["parameter"] for r in top], [r["per_sigma"] for r in top], color="tab:orange")
        ax.set_xlabel(f"{s} added in quadrature per 1 sigma")
        ax.set_title(f"{s}: RSS fit, R^2 {f['r2']:.2f}, floor {f['floor']:.3g}", fontsize=9)
        ax.tick_params(labelsize=7)
    out["sensitivity_rss.png"] = _png(fig)
    return out


def report_markdown(summary: dict) -> str:
    """report.md: the failures, each score's statistics and yield, and the top of each ranking."""
    s = summary
    lines = ["# Monte-Carlo tolerancing", "",
             f"{s['samples']} builds, {s['ok']} calibrated ({100 * s['failed_fraction']:.1f} % failed).", ""]
    for reason, count in s["failure_reasons"].items():
        lines.append(f"- {count} x {reason}")
    lines += ["", "| score | n | mean | median | p90 | p95 | max | target | builds meeting it |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, st in s["scores"].items():
        if not st["n"]:
            continue
        t = s["targets"].get(name)
        tt = (f"{t['target']:g} | {100 * t['fraction']:.1f} % (95 %: {100 * t['interval_95'][0]:.0f}-"
              f"{100 * t['interval_95'][1]:.0f} %)") if t else "| "
        pct = " | ".join(f"{st[k]:.4g}" if math.isfinite(st[k]) else f"needs {m} builds" for k, m in MIN_BUILDS.items())
        lines.append(f"| {name} | {st['n']} | {st['mean']:.4g} | {st['median']:.4g} | {pct} | {st['max']:.4g} | {tt} |")
    lines += ["", "## Sensitivity (Spearman rank correlation of |deviation| with the score)", ""]
    for name, ranking in s["sensitivity"].items():
        top = ", ".join(f"{r['parameter']} {r['rho']:+.2f}" for r in ranking[:TOP])
        lines.append(f"- **{name}**: {top}")
    n = max(s["ok"], 1)
    lines.append(f"\n|rho| under 2/sqrt(N) = {2 / math.sqrt(n):.2f} is chance at these {s['ok']} builds.")
    lines += ["", "## Sensitivity (RSS fit: the score one standard deviation of each tolerance adds in quadrature)",
              ""]
    for name, f in s["rss_sensitivity"].items():
        top = ", ".join(f"{r['parameter']} {r['per_sigma']:.3g}" for r in f["ranking"][:TOP])
        lines.append(f"- **{name}** (R^2 {f['r2']:.2f}, floor {f['floor']:.3g}): {top}")
    lines += ["", "![histograms](histograms.png)", "", "![yield](yield.png)", "", "![sensitivity](sensitivity.png)",
              "", "![RSS sensitivity](sensitivity_rss.png)"]
    return "\n".join(lines) + "\n"


def write_report(rows, folder, targets: dict | None = None) -> list[Path]:
    """Write scores.json, report.md, histograms.png, yield.png, sensitivity.png and sensitivity_rss.png into
    ``folder`` (which must exist), all or none; returns their paths."""
    folder = Path(folder)
    cols = _columns(rows)
    summary = summarise(cols, targets)
    files = {"scores.json": json.dumps(json_safe(summary), indent=2, allow_nan=False) + "\n",
             "report.md": report_markdown(summary), **_figures(cols, summary)}
    with output_batch():
        for name, data in files.items():
            write_atomic(folder / name, data)
    return [folder / name for name in files]


def _reason_kind(reason: str) -> str:
    """A failure's kind: its message without the sample's particulars (what follows " (" or ": ", the
    solver's words)."""
    return reason.split(" (")[0].split(": ")[0][:120] or "unknown"
