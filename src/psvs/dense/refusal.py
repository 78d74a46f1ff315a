"""Why a dense map gives no depth, in words a user can check on the image: ``psvs disparity`` refuses in them
(exit 1) and the page's dense run says them (``refused``), so both say the same."""
from __future__ import annotations

import math

import numpy as np

from psvs.dense.build import RigDense
from psvs.dense.echo_test import BLOCK_CELLS, CELL_PX, MIN_LAGS
from psvs.dense.trust import ALPHA, TOL_PX, EchoTrust


def _asked(dense: RigDense) -> str:
    """The disparities asked for, in words (the search also reads a lag beyond each end,
    psvs.dense.params.searched_lags)."""
    lo, hi = dense.asked_px or dense.result.searched_px
    return f"{lo:.0f}..{hi:.0f} px"


def nothing_answered(dense: RigDense) -> str:
    """Why ``dense``'s left map answers no pixel at all, naming the disparities asked for; "" when it answers
    some (to be asked before its trust is tested: :func:`nothing_trusted`)."""
    if np.isfinite(dense.result.disparity_left).any():
        return ""
    return f"no pixel found a disparity in {_asked(dense)}: the image holds no texture the search can match"


def _periodic_refusal(trust: EchoTrust, asked: str) -> str:
    """The refusal of a frame whose texture repeats with a period the elsewhere test names."""
    return f"the image's texture repeats along its rows: {periodic_words(trust)}: nothing in {asked} is trusted"


def nothing_trusted(dense: RigDense, trust: EchoTrust) -> str:
    """Why ``dense`` answers nothing (:func:`nothing_answered`), or nothing of it is trusted (``trust``,
    :func:`psvs.dense.build.rig_trust` of it), naming the disparities asked for; "" when some answer is
    trusted."""
    why = nothing_answered(dense)
    if why or trust.count > 0:
        return why
    asked = _asked(dense)
    t, e, k = trust.test, trust.elsewhere, 2 ** trust.level
    copied = t.copied if t.copied is not None else np.zeros_like(t.ambiguous)
    rivals = t.ambiguous & ~copied
    periodic = e is not None and e.periodic_any
    if rivals.any() and not t.echoes:
        return (f"the image's texture repeats along its rows: {int(rivals.sum())} cells of "
                f"{k * t.cell_px}x{k * t.cell_px} px echo beyond chance at two or more separate disparities alike "
                f"(stripes, bricks, a row of identical windows), and nothing else echoes: which of them is the twin "
                f"cannot be told in {asked}")
    if copied.any() and not t.echoes:
        if periodic:                   # a periodic wall's own words name its period
            return _periodic_refusal(trust, asked)
        return (f"the image's texture repeats along its rows: in {int(copied.sum())} cells of {k * t.cell_px}x"
                f"{k * t.cell_px} px a patch matches one beside it more closely than any twin can (stripes, a "
                f"grating): every multiple of its period is as good an answer, and nothing else is trusted in "
                f"{asked}")
    if t.tests == 0:
        h, w = dense.left_image.shape
        return (f"the echo test has no patch to judge on {w // k}x{h // k} px (the image at the level it is "
                f"tested): its patches are {min(BLOCK_CELLS) * CELL_PX} px and more a side, each needing its twin "
                f"inside the image at {MIN_LAGS} lags or more")
    if e is not None and e.any:
        return f"the image echoes beyond chance only outside the searched disparities {asked}: {elsewhere_words(trust)}"
    if e is not None and e.repeats:
        return (f"the image echoes beyond chance only as a short repeat along its rows, not in the searched "
                f"disparities {asked}: {repeat_words(trust)}")
    if periodic:
        return _periodic_refusal(trust, asked)
    if e is not None and e.mirrored_any:
        return (f"the image's texture repeats along its rows at or beyond the end of the searched disparities {asked}: "
                f"{mirror_words(trust)}")
    if e is not None and math.isfinite(e.edge_lag_px):
        return (f"the image echoes beyond chance only at the edge of the searched disparities {asked}, where the "
                f"search cannot pin it: the strongest, {e.edge_z:.1f} spreads where chance reaches "
                f"{e.edge_threshold:.1f}, repeats {e.edge_lag_px * k:.0f} px to its left: widen the range searched "
                "(--near-mm/--far-mm, or --min-disparity/--max-disparity) to measure it")
    if t.echoes or t.strongest > 1.0:       # an echo stands, but no answer of the maps stands on it
        return (f"no answer of the maps stands on the image's echo: {strongest_echo(trust)}, but no answer within "
                f"{TOL_PX:g} px of an echoing lag carries its own echo and texture (the search answered those "
                f"pixels elsewhere: a texture that repeats, or one surface's echo over another's): nothing in "
                f"{asked} is trusted")
    return (f"no part of the image echoes beyond chance: {strongest_echo(trust)}: the image shows no echo of the "
            f"disparities {asked}")


def strongest_echo(trust: EchoTrust) -> str:
    """The echo test's strongest patch in words a user can check on the image (px of the maps' grid)."""
    t = trust.test
    k = 2 ** trust.level
    u, v, side, lag = t.strongest_at
    return (f"its strongest echo, a {side * k}x{side * k} px patch centred at ({(u + 0.5) * k - 0.5:.0f}, "
            f"{(v + 0.5) * k - 0.5:.0f}) that repeats {lag * k} px to its left, stands {t.strongest_z:.1f} spreads "
            f"above the patch's correlation at other lags, where chance on this image reaches "
            f"{t.strongest_threshold:.1f} (the {ALPHA:.0%} false-alarm level read from the correlations' negative "
            "side, which no echo reaches)")


def elsewhere_words(trust: EchoTrust) -> str:
    """What the image shows outside the searched range, in words a user can act on."""
    e = trust.elsewhere
    k = 2 ** trust.level
    return (f"the strongest, {e.strongest_z:.1f} spreads where chance reaches {e.threshold:.1f}, repeats "
            f"{e.strongest_lag_px * k:.0f} px to its left; nothing in {_cells_words(trust, e.cells)} showing it "
            "is trusted: widen the range searched "
            "(--near-mm/--far-mm, or --min-disparity/--max-disparity) to measure it")


def _cells_words(trust: EchoTrust, cells: np.ndarray) -> str:
    """"N cells of S px a side": how many of the elsewhere test's ``cells`` (ny, nx bool) are flagged, and their
    side in px of the image the maps were made of."""
    e = trust.elsewhere
    return f"{int(cells.sum())} cells of {e.cell_px * e.scale * 2 ** trust.level:.0f} px a side"


def repeat_words(trust: EchoTrust) -> str:
    """Where the image's texture repeats along its rows (psvs.dense.elsewhere), in words a user can check."""
    e = trust.elsewhere
    k = 2 ** trust.level
    return (f"{_cells_words(trust, e.repeating)} correlate with themselves "
            f"{e.period_px * k:.0f} px to their left ({e.period_z:.1f} spreads where chance reaches "
            f"{e.period_threshold:.1f}): a texture that repeats along the rows (bricks, stripes), or a surface far "
            "beyond the range; there only a surface whose own echo supports its answer is trusted")


def periodic_words(trust: EchoTrust) -> str:
    """Where the image's echo in the range is a multiple of a shorter repeat
    (:func:`psvs.dense.elsewhere.periodic_patches`), in words a user can check."""
    e = trust.elsewhere
    k = 2 ** trust.level
    return (f"{_cells_words(trust, e.periodic)} correlate with themselves "
            f"{e.periodic_px * k:.0f} px to their left and at a multiple of that ({e.periodic_z:.1f} spreads where "
            f"chance reaches {e.periodic_threshold:.1f}): a texture that repeats along the rows (a fence, blinds, "
            "tiles) echoes at every multiple of its period, and which one is the twin cannot be told; nothing on "
            "that surface is trusted")


def mirror_words(trust: EchoTrust) -> str:
    """Where the image's echoes in the range mirror a repeat at its top or beyond it
    (:func:`psvs.dense.elsewhere.mirrored_patches`), in words a user can check."""
    return (f"{_cells_words(trust, trust.elsewhere.mirrored)} correlate with themselves "
            f"most strongly at one repeat (at the range's top or beyond it), and echo in the range at two other "
            "disparities that add up to that repeat: the twin's and its mirror's, which cannot be told apart "
            "(wallpaper, tiles); nothing on that surface is trusted")
