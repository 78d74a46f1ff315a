"""Whether the automatic matcher's twins stand above chance (:func:`psvs.match.auto.match_auto`).

A candidate twin is a left edge, a right edge and a disparity on whose rows the two edges agree within
+-1 px (the paper's shape match); its evidence is how many rows agree. Edges agree on some rows by chance:
on a noisy image thousands of small edges make candidates of up to a hundred rows, on stripes or a
checkerboard every edge agrees with every other at each multiple of the period. Chance is read on the
image itself, at disparities the working range cannot produce: the same votes and candidates (same rows,
same polarity rule) over *null bands* of lags as wide as the searched range, beyond its far end (a point
nearer than the near limit; where none fit in the image, before its near end). A twin cannot be there,
chance and repetition are there as much as in the range.

**The level.** The null candidates' agreeing rows, read by peaks over threshold as the dense engine's echo
test reads its correlations (psvs.dense.echo_test): u the (k + 1)-th largest (k = 50, or all of them;
then u = the fewest rows a candidate can have, less one), beta the mean excess of the k largest over u,
raised by one standard error, beta (1 + 1/sqrt(k)); under an exponential tail
P(rows > u + x) = (k / n) e^(-x / beta), so the level that the real search's m candidates exceed with
probability alpha in all is **t = u + beta ln(m k / (n alpha))** (alpha = 1 %), and never less than the
strongest null candidate (a structured image's tail is heavier than the fit's). A clean scene makes few null
candidates (a few object outlines that half agree at some lag), too few to read a tail from: under
:data:`MIN_TAIL` of them the level is twice the strongest one's excess over the floor (a candidate must agree
on twice the rows beyond the fewest that chance's best did). An image is *answered* when
some candidate exceeds t, and then paired by the matcher's own rules (rows, shares of an edge, support by
its neighbours, the grey image's steps); without one nothing is paired. The paper's seeded algorithm asks
the same before it takes an edge (:func:`psvs.match.auto.image_chance`).

**Each pair.** A twin standing alone (no accepted pair of its object backs it) must also exceed
:func:`pair_level`: each candidate's chance p from the same tail, Benjamini and Hochberg's step-up over all
the range's candidates at a :data:`FDR` false-discovery rate, never below the strongest null candidate (the
strongest of them when there is no tail to read). A twin an accepted pair backs must stand where chance makes
no candidate as strong near it at one disparity (:meth:`Chance.backed_beyond_chance`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Lags (px) between the searched range and a null band.
GAP_PX = 3.0
#: The chance, aimed at, that an image without twins is answered (the level's false-alarm rate over the image;
#: met on unstructured images, not on structured ones: measured in docs/matching.md).
ALPHA = 0.01
#: The expected share of chance pairs among the twins accepted standing alone (:func:`pair_level`).
FDR = 0.05
#: The null candidates the tail is read from (the k largest).
TAIL = 50
#: Fewer null candidates than this: no tail is read (module docstring).
MIN_TAIL = 20
#: The narrowest null band worth searching, px of lag.
MIN_BAND_PX = 8.0


#: The share of a candidate's votes whose pixels must twin as strongly or more below the range to set it aside.
ELSEWHERE_SHARE = 0.5
#: A twin below the range this strong, relative to the candidate's agreeing rows, or stronger, contradicts it:
#: a pixel that twins about as well below the range as in it is no evidence for the twin in it (an adversarial
#: trial: Fig. 5b at 1300 mm, just past the far limit of 1200, paired one ashtray's view with the other's,
#: 165 px, 643 mm, on 67 rows while its pixels twinned with their own views at 82 px on about as many or
#: more, the strongest on 91).
AS_STRONG = 0.9

#: The lags a backing pair's disparity window spans (+-2 px: psvs.match.auto's support).
BACKED_LAGS = 5


@dataclass(frozen=True, eq=False)
class NullCandidates:
    """The candidates chance made at the null bands' lags: their agreeing rows (n,), boxes (n, 4) px
    (u0, v0, u1, v1) of their left pixels, the ``bands`` ((lo, hi) px, ...) they were read over and their
    ``lags`` (n,) px (None: not kept)."""

    rows: np.ndarray
    boxes: np.ndarray
    bands: tuple[tuple[float, float], ...]
    lags: np.ndarray | None = None

    def expected_near(self, rows: float, box, reach: float) -> float:
        """How many candidates of at least ``rows`` rows chance makes, in expectation, within ``reach`` px of
        ``box`` (u0, v0, u1, v1) and within one backing window of lags (:data:`BACKED_LAGS`): those the null
        bands hold there, per lag of them, times the window."""
        lags = sum(b - a + 1 for a, b in self.bands)
        if lags <= 0:
            return math.inf
        b, x = self.boxes, box
        near = ((self.rows >= rows) & (b[:, 0] <= x[2] + reach) & (b[:, 2] >= x[0] - reach)
                & (b[:, 1] <= x[3] + reach) & (b[:, 3] >= x[1] - reach))
        return float(near.sum()) * BACKED_LAGS / lags


@dataclass(frozen=True, eq=False)
class Elsewhere:
    """The twins the edges find at lags *below* the searched range (a scene beyond the far limit, or a search
    narrowed past it): per edge pixel (N,), the most agreeing rows of a candidate in whose votes it is the
    left pixel (``left_rows``) or the right pixel (``right_rows``) at one of those lags, and that candidate's
    lag (``left_lag``, ``right_lag``, px; 0 where none); ``band`` the lags (lo, hi) px searched; ``left_keys``
    and ``right_keys`` (N,) each pixel's place in the left and the right view (:func:`_pixel_keys` of its
    integer (u, v)), to find a seeded pair's pixels (:meth:`beats_pixels`). A candidate in the range most of
    whose pixels twin as strongly there (:data:`AS_STRONG`) or more, beyond chance, is the view of something the
    range does not hold: pairing it in the range would pair it with the wrong edge (an adversarial trial:
    Fig. 5b at 1100 mm searched at 400-700 mm paired each ashtray's view with the other's, at 541-609 mm,
    exit 0). Read per pixel, not per edge component: a component merged of a clutter's many outlines twins
    somewhere with each of them."""

    left_rows: np.ndarray
    right_rows: np.ndarray
    left_lag: np.ndarray
    right_lag: np.ndarray
    band: tuple[float, float]
    left_keys: np.ndarray | None = None
    right_keys: np.ndarray | None = None

    def strongest(self) -> tuple[float, float]:
        """(agreeing rows, lag px) of the strongest candidate at these lags, through either of its pixels
        ((0, 0) when none)."""
        if not len(self.left_rows):
            return 0.0, 0.0
        rows, lags = np.concatenate([self.left_rows, self.right_rows]), np.concatenate([self.left_lag, self.right_lag])
        k = int(np.argmax(rows))
        return float(rows[k]), float(lags[k])

    def beats_pixels(self, left_px, right_px, rows: float, level: float) -> float:
        """:meth:`beats` for a pair of integer pixels (left (K, 2) and right (K, 2) (u, v), each in its own
        view's coordinates, as :class:`~psvs.match.pairs.EdgePair` holds them); pixels that are no edge pixel
        are left out."""
        found = []
        for keys, px in ((self.left_keys, left_px), (self.right_keys, right_px)):
            order = np.argsort(keys, kind="stable")
            want = _pixel_keys(px)
            at = np.minimum(np.searchsorted(keys[order], want), len(keys) - 1) if len(keys) else want[:0]
            found.append(order[at][keys[order][at] == want] if len(keys) else at)
        return self.beats(found[0], found[1], rows, level)

    def beats(self, left: np.ndarray, right: np.ndarray, rows: float, level: float) -> float:
        """The lag (px) of the candidates outside the range that are as strong as a candidate (its votes' left
        pixels ``left`` and right pixels ``right``, indices (K,), ``rows`` agreeing rows; :data:`AS_STRONG` of its
        rows) or stronger and beyond chance's ``level``, on at least :data:`ELSEWHERE_SHARE` of its votes through
        either side; 0.0 when none are."""
        for mine, lags in ((self.left_rows[left], self.left_lag[left]),
                           (self.right_rows[right], self.right_lag[right])):
            stronger = (mine >= AS_STRONG * rows) & (mine > level)
            if len(mine) and stronger.mean() >= ELSEWHERE_SHARE:
                return float(np.median(lags[stronger]))
        return 0.0


@dataclass(frozen=True, eq=False)
class Chance:
    """How the automatic matcher's candidates stand against chance on one image.

    ``strongest_rows``: the most agreeing rows of a candidate in the working range (0: no candidate);
    ``level_rows``: t, the level a candidate must exceed for the image to be answered; ``null_max_rows``:
    the strongest null candidate (0: none); ``null_candidates`` and
    ``tests``: how many candidates the null bands and the working range made; ``bands``: the null bands'
    lags (px) ((lo, hi), ...); ``pair_level_rows``: the rows a twin standing alone (no accepted pair of its
    object backs it) must exceed to be paired (:func:`pair_level`; infinite: none may); ``null``: the null
    candidates themselves, which a backed twin is weighed against (:meth:`backed_beyond_chance`; None: no
    null was read, and no twin is backed beyond chance); ``elsewhere``: the edges' twins at lags below the
    range (:class:`Elsewhere`; None: none fit), which a candidate must not be weaker than
    (:meth:`twin_elsewhere`)."""

    strongest_rows: float
    level_rows: float
    null_max_rows: float
    null_candidates: int
    tests: int
    bands: tuple[tuple[float, float], ...]
    pair_level_rows: float = math.inf
    null: NullCandidates | None = None
    elsewhere: Elsewhere | None = None

    def twin_elsewhere(self, left: np.ndarray, right: np.ndarray, rows: float) -> float:
        """The lag (px) outside the range at which most of a candidate's votes (their left and right pixels'
        indices, (K,) each; ``rows`` agreeing rows) twin as strongly (:data:`AS_STRONG`) or more, beyond chance
        (:class:`Elsewhere`); 0.0 when they do not (or it was not read)."""
        return 0.0 if self.elsewhere is None else self.elsewhere.beats(left, right, rows, self.level_rows)

    def backed_beyond_chance(self, rows: float, box, reach: float) -> bool:
        """Whether a twin of ``rows`` agreeing rows that an accepted pair of its object backs (within
        ``reach`` px of its ``box``, at its disparity) stands beyond chance there: chance makes fewer than
        :data:`FDR` candidates as strong near it in one backing window of lags, in expectation
        (:meth:`NullCandidates.expected_near`). A small edge beside a textured card is no evidence of its
        own: chance makes such candidates near it at every lag."""
        return self.null is not None and self.null.expected_near(rows, box, reach) < FDR

    @property
    def answered(self) -> bool:
        """Whether some candidate stands beyond chance's level (the image holds twins)."""
        return self.strongest_rows > self.level_rows

    def describe(self) -> str:
        """One line: the strongest twin against chance's level, and where chance was read."""
        bands = ", ".join(f"{a:.0f}..{b:.0f}" for a, b in self.bands)
        if not self.bands:
            return ("the working range's disparities fill the image's rows: no lag is left to read chance at, "
                    "so no twin can be told from chance")
        head = ("no edge agrees with another on enough rows at the working range's disparities" if self.tests == 0
                else f"the strongest twin agrees on {self.strongest_rows:.0f} rows, chance on this image up to "
                     f"{self.level_rows:.0f}")
        where = f"at disparities {bands} px, which the working range cannot produce"
        alone = (f"; a twin no other pair backs needs more than {self.pair_level_rows:.0f} rows"
                 if self.answered and math.isfinite(self.pair_level_rows) else "") + self._elsewhere_words()
        alone += self._nearer_words()
        if self.null_candidates >= MIN_TAIL:
            return (f"{head} (the {ALPHA:.0%} false-alarm level read from {self.null_candidates} candidates "
                    f"{where}; their strongest {self.null_max_rows:.0f} rows){alone}")
        return (f"{head} (twice the excess of chance's strongest of {self.null_candidates} candidates "
                f"{where}, {self.null_max_rows:.0f} rows){alone}")

    def _nearer_words(self) -> str:
        """A hint when chance's strongest candidate outnumbers every twin in the range: the twins of a scene
        nearer than the near limit lie at the null bands' lags, and the image is refused as chance."""
        if self.answered or self.null_max_rows <= self.strongest_rows or self.null is None or self.null.lags is None:
            return ""
        lag = float(self.null.lags[int(np.argmax(self.null.rows))])
        return (f"; the strongest agreement of all, {self.null_max_rows:.0f} rows, lies at {lag:.0f} px, beyond the "
                "range: if the scene stands nearer than the near limit, widen the range (--near-mm) to measure it")

    @property
    def twins_below(self) -> bool:
        """Whether some candidate below the range (:class:`Elsewhere`) stands beyond chance's level."""
        return self.elsewhere is not None and self.elsewhere.strongest()[0] > self.level_rows

    def _elsewhere_words(self) -> str:
        """Where the edges twin below the range, when some candidate there stands beyond chance's level."""
        if not self.twins_below:
            return ""
        rows, lag = self.elsewhere.strongest()
        return (f"; edges twin beyond chance below the range too, the strongest on {rows:.0f} rows at {lag:.0f} px "
                "(a scene beyond the far limit: those edges are not paired in the range, widen it to measure them; or "
                "an edge map of speckle, which twins at any lag: an object whose grey is at the pipeline's threshold)")


def null_bands(d_min: float, d_max: float, width_px: int) -> list[tuple[float, float]]:
    """The null bands of lags (px) for a search over ``d_min..d_max`` on rows ``width_px`` wide: bands as
    wide as the range, from :data:`GAP_PX` beyond ``d_max`` while they fit in the row; where none does,
    one before ``d_min``. Bands narrower than :data:`MIN_BAND_PX` are left out ([] when none fits)."""
    span, out = d_max - d_min, []
    a = d_max + GAP_PX
    while width_px - 1 - a >= MIN_BAND_PX:
        b = min(a + span, width_px - 1.0)
        out.append((a, b))
        a = b + GAP_PX
    if not out and d_min - 2 * GAP_PX >= MIN_BAND_PX:
        out.append((max(GAP_PX, d_min - GAP_PX - span), d_min - GAP_PX))
    return out


def _tail(null_rows: np.ndarray, floor: float, tail: int) -> tuple[np.ndarray, float, float, int]:
    """The null candidates' rows sorted from the largest, and the peaks-over-threshold fit of their tail
    (module docstring): (rows, u, beta, k)."""
    r = np.sort(np.asarray(null_rows, dtype=float))[::-1]
    k = min(tail, len(r))
    u = float(r[k]) if k < len(r) else floor - 1.0
    beta = max(float(np.mean(r[:k] - u)), 1.0) * (1.0 + 1.0 / math.sqrt(k))
    return r, u, beta, k


def pair_level(null_rows: np.ndarray, rows: np.ndarray, floor: float, fdr: float = FDR, tail: int = TAIL) -> float:
    """The agreeing rows a twin standing alone must exceed (:attr:`Chance.pair_level_rows`): each candidate's
    chance p = P(a null candidate agrees on more rows), the tail's exponential beyond u and the null's own
    share below it, then Benjamini and Hochberg's step-up over the ``rows`` (m,) of all the range's
    candidates at false-discovery rate ``fdr``; never below the strongest null candidate. With fewer than
    :data:`MIN_TAIL` null candidates, the strongest of them (``floor`` - 1 with none)."""
    null = np.asarray(null_rows, dtype=float)
    if len(null) < MIN_TAIL:
        return float(null.max()) if len(null) else floor - 1.0
    r, u, beta, k = _tail(null, floor, tail)
    rows = np.asarray(rows, dtype=float)
    n = len(r)
    above = (k / n) * np.exp(-(rows - u) / beta)
    below = (n - np.searchsorted(r[::-1], rows, side="right")) / n          # share of null rows > rows
    p = np.where(rows > u, above, np.maximum(below, k / n))
    order = np.argsort(p, kind="stable")
    passed = np.flatnonzero(p[order] <= fdr * np.arange(1, len(p) + 1) / max(len(p), 1))
    if not len(passed):
        return float(max(rows.max(initial=0.0), r[0]))
    found = rows[order[:passed[-1] + 1]]
    return max(float(found.min()) - 1.0, float(r[0]))


def chance_level(null_rows: np.ndarray, tests: int, floor: float, alpha: float = ALPHA,
                 tail: int = TAIL) -> float:
    """t (rows) that chance's largest of ``tests`` candidates exceeds with probability ``alpha``, from the
    null candidates' agreeing rows ``null_rows`` (n,) (module docstring), and at least their largest;
    ``floor`` is the fewest rows a candidate can have. Without null candidates, ``floor`` - 1: chance made
    none; with fewer than :data:`MIN_TAIL`, twice the strongest one's excess over ``floor`` - 1."""
    n = len(null_rows)
    if n < MIN_TAIL:
        top = float(np.max(null_rows)) if n else 0.0
        return floor - 1.0 + 2.0 * (top - (floor - 1.0)) if n else floor - 1.0
    r, u, beta, k = _tail(null_rows, floor, tail)
    rate = max(tests, 1) * k / n          # how many of the real candidates chance takes beyond u
    t = u + beta * math.log(rate / alpha) if rate > alpha else u
    return max(t, float(r[0]))            # never below what chance made (a tail heavier than the fit's)


#: The share of a seeded pair's pixels an automatic pair must hold, at its disparity, to back it.
BACKED_SHARE = 0.5


def agreeing_rows(pair, tol_px: float) -> int:
    """The rows on which a seeded pair (an :class:`~psvs.match.pairs.EdgePair` of integer pixels) agrees with
    its shape disparity within ``tol_px``: the statistic a candidate of the automatic matcher is weighed by."""
    if not len(pair):
        return 0
    on = np.abs(np.asarray(pair.disparity_px, dtype=float) - pair.shape_disparity_px) <= tol_px
    return int(len(np.unique(np.rint(np.asarray(pair.left_px)[on, 1]))))


def seed_pair_stands(pair, chance: Chance, backing, tol_px: float) -> bool:
    """Whether the twin the paper's algorithm found from a seed stands beyond chance by the automatic
    matcher's own rule: alone, on more agreeing rows (:func:`agreeing_rows`) than
    :attr:`Chance.pair_level_rows`; or backed, the automatic matcher (``backing()``: its accepted pairs, integer
    pixels in the same coordinates, asked only for a pair that does not stand alone) having paired at least
    :data:`BACKED_SHARE` of its pixels at its disparity (within :data:`BACKED_LAGS` // 2 px). The paper's
    algorithm pairs the seed's edge with whatever agrees best, on a photograph's texture as readily as on a
    twin (an adversarial trial: 12 of 22 seeds on the textured scene paired 3-22 rows at a wrong disparity).
    Never when its pixels twin as strongly or more below the range (``chance.elsewhere``, when read with the pixels'
    places: :meth:`Elsewhere.beats_pixels`): Fig. 5b at 1100 mm searched to 700 mm paired 4 of 5 seeds with the
    other ashtray's view at 544-698 mm."""
    if not len(pair) or not chance.answered:
        return False
    rows = agreeing_rows(pair, tol_px)
    e = chance.elsewhere
    if e is not None and e.left_keys is not None and e.beats_pixels(pair.left_px, pair.right_px, rows,
                                                                    chance.level_rows):
        return False                     # its pixels twin as strongly or more below the range
    if rows > chance.pair_level_rows:
        return True
    mine = _pixel_keys(pair.left_px)
    reach = BACKED_LAGS // 2
    held = [_pixel_keys(p.left_px) for p in backing()
            if len(p) and abs(p.shape_disparity_px - pair.shape_disparity_px) <= reach]
    if not held:
        return False
    return float(np.isin(mine, np.concatenate(held)).mean()) >= BACKED_SHARE


def _pixel_keys(px) -> np.ndarray:
    uv = np.rint(np.asarray(px, dtype=float)).astype(np.int64)
    return uv[:, 1] * (1 << 32) + uv[:, 0]
