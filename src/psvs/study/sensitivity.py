"""Which tolerance explains a score: the root-sum-square (RSS) model of optical tolerancing, fitted to a study.

A first-order tolerance analysis (``psvs design --tolerance``) adds the effects of the errors in quadrature: a
score s of a build with deviations x is about ``sqrt(s0^2 + (a . x)^2)`` where ``a_i`` is what a unit of
parameter i moves the score's underlying quantity (signed: two tilts may cancel) and ``s0`` what the build
has at nominal (e.g. the calibration's noise floor). Fitted to the samples of a study with the deviations
standardised (z_i = x_i / std x_i), ``|a_i|`` is the score (its unit) that one standard deviation of
parameter i adds in quadrature: the tolerance to tighten is the one with the largest.

Why not only a rank correlation of |x_i| with s: when several errors of comparable effect add with their
signs (the four mirrors' tilts out of vertical all move the twins' rows), each one's magnitude correlates
only weakly with the total (rho about 0.17 for each of those four on the default rig, as many samples as
you like), and chance correlations of errors that do nothing reach 2/sqrt(N): at 50 builds the rank
correlation cannot find them, while the RSS fit, which sees the signs, does (docs/tolerancing.md).

The fit: :func:`scipy.optimize.least_squares` on the residuals ``sqrt(c + (z a)^2) - s``, from
:data:`STARTS` seeded random starts (the sign of ``a`` is arbitrary), the best kept. It needs at least
:data:`MIN_SAMPLES_PER_PARAMETER` samples per varied parameter; ``r2`` says how much of the score's variance
the model explains (a score the model does not describe -- one calibration absorbs -- has a low ``r2``, and
its ranking means little).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

#: Random starts of the fit (seeded: the same rows give the same answer).
STARTS = 8
#: Samples needed per varied parameter (and the floor) for the fit to be made.
MIN_SAMPLES_PER_PARAMETER = 2


def fit_rss(x: np.ndarray, score: np.ndarray) -> dict | None:
    """Fit ``score ~ sqrt(s0^2 + (z a)^2)`` with ``z`` the standardised columns of ``x``.

    Parameters
    ----------
    x : ndarray, shape (N, P)
        The deviations of the N builds (every column varies).
    score : ndarray, shape (N,)
        Their score (finite).

    Returns
    -------
    dict or None
        ``per_sigma`` (P,): |a_i|, the score one standard deviation of parameter i adds in quadrature (the
        score's unit); ``floor``: s0; ``residual_rms``; ``r2`` (1 - residual variance / score variance).
        None when N < :data:`MIN_SAMPLES_PER_PARAMETER` x (P + 1).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> x = rng.uniform(-1, 1, (80, 3))
    >>> s = np.sqrt(0.5 ** 2 + (2.0 * x[:, 0] / x[:, 0].std() - 1.0 * x[:, 2] / x[:, 2].std()) ** 2)
    >>> np.round(fit_rss(x, s)["per_sigma"], 3).tolist()
    [2.0, 0.0, 1.0]
    """
    n, p = x.shape
    if n < MIN_SAMPLES_PER_PARAMETER * (p + 1):
        return None
    z = (x - x.mean(axis=0)) / x.std(axis=0)
    rng = np.random.default_rng(0)

    def residual(a):
        return np.sqrt(a[-1] ** 2 + (z @ a[:-1]) ** 2) - score

    best = None
    for _ in range(STARTS):
        a0 = np.append(rng.normal(0.0, score.std() / np.sqrt(p) + 1e-12, p), score.min())
        sol = least_squares(residual, a0, x_scale="jac")
        if best is None or sol.cost < best.cost:
            best = sol
    res = residual(best.x)
    var = score.var()
    return {"per_sigma": np.abs(best.x[:-1]), "floor": float(abs(best.x[-1])),
            "residual_rms": float(np.sqrt(np.mean(res ** 2))),
            "r2": float(1.0 - np.mean(res ** 2) / var) if var > 0 else float("nan")}


def rss_ranking(devs: dict, score: np.ndarray) -> dict | None:
    """:func:`fit_rss` on the deviations ``devs`` (parameter -> (N,) values; those that do not vary are left
    out) as scores.json holds it: ``ranking`` (``parameter``, ``per_sigma``, largest first), ``floor``,
    ``residual_rms``, ``r2``, ``n``; None when too few samples or nothing varies."""
    names = [k for k, v in devs.items() if np.ptp(v) > 0]
    if not names:
        return None
    fit = fit_rss(np.column_stack([devs[k] for k in names]), score)
    if fit is None:
        return None
    order = np.argsort(-fit["per_sigma"], kind="stable")
    return {"ranking": [{"parameter": names[j], "per_sigma": float(fit["per_sigma"][j])} for j in order],
            "floor": fit["floor"], "residual_rms": fit["residual_rms"], "r2": fit["r2"], "n": int(len(score))}
