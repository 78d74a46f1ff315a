import numpy as np
import pytest

from psvs.dense.cost import NO_TWIN
from psvs.dense.guided import guided_filter_volume, n_levels


def _reflect(i, n):
    return -i - 1 if i < 0 else 2 * n - i - 1 if i >= n else i


def _row_sums(rows, r):
    """The kernel's row sums of ``rows`` (..., W), float32 additions in its order: the row extended by
    reflection, levels of 2^b sums by doubling, the window's levels added from the widest down."""
    w = rows.shape[-1]
    idx = [min(r - 1 - i, w - 1) for i in range(r)] + list(range(w)) + [max(w - 1 - j, 0) for j in range(r)]
    levels = [rows[..., idx]]
    n = w + 2 * r
    for b in range(1, n_levels(r)):
        half, m = 1 << (b - 1), n - (1 << b) + 1
        levels.append(levels[b - 1][..., :m] + levels[b - 1][..., half:half + m])
    out, off = None, 0
    for b in range(len(levels) - 1, -1, -1):
        if (2 * r + 1) & (1 << b):
            part = levels[b][..., off:off + w]
            out = part if out is None else out + part
            off += 1 << b
    return out


def _column_sums(sums, r):
    """The kernel's running sums down the columns of ``sums`` (H, W): the first window's rows added one by
    one, then per row the entering row minus the leaving one added."""
    h = sums.shape[0]
    col = np.zeros(sums.shape[1], np.float32)
    for j in range(-r, r + 1):
        col = col + sums[_reflect(j, h)]
    out = [col]
    for y in range(1, h):
        col = col + (sums[_reflect(y + r, h)] - sums[_reflect(y - r - 1, h)])
        out.append(col)
    return np.array(out)


def _replay(volume, guide, weight, r, eps, missing):
    """The guided filter as the kernel computes it, one float32 operation at a time in NumPy (IEEE)."""
    scale = np.float32(1.0 / ((2 * r + 1) * (2 * r + 1)))
    box = lambda a: _column_sums(_row_sums(a, r), r)  # noqa: E731 - window sums
    mean_g = box(guide) * scale
    inv_var = np.float32(1.0) / (box(guide * guide) * scale - mean_g * mean_g + eps)
    out = np.empty_like(volume)
    for k, v in enumerate(volume):
        p = np.where(v == missing, np.float32(0.0), v)
        mp = box(p) * scale
        a = (box(guide * p) * scale - mean_g * mp) * inv_var
        b = mp - a * mean_g
        q = (box(a) * guide + box(b)) * scale * weight
        out[k] = np.where(v == missing, missing, q)
    return out


@pytest.mark.parametrize("radius, shape", [(4, (48, 64)), (3, (37, 71)), (2, (17, 23)), (7, (8, 12)), (5, (30, 6))])
def test_guided_filter_is_exactly_its_float32_operations(radius, shape):
    """The kernel's result is bit for bit a NumPy replay of its float32 operations, in and out of place:
    it is compiled without fastmath, so every copy of a loop that LLVM may run (the vector body, its
    remainder, the scalar copy taken when a run-time overlap check on the arrays' addresses fails) rounds
    alike. With fastmath the vector copy divided by an approximate reciprocal and the scalar copy exactly,
    and where the heap put the work spaces decided which one ran."""
    rng = np.random.default_rng(radius)
    vol = rng.uniform(-1, 1, (5, *shape)).astype(np.float32)
    vol[2, :, :5] = NO_TWIN
    vol[4, 3:, 1] = NO_TWIN
    guide = rng.random(shape).astype(np.float32)
    weight = rng.random(shape).astype(np.float32)
    eps, missing = np.float32(0.01), np.float32(NO_TWIN)
    want = _replay(vol, guide, weight, radius, eps, missing)
    np.testing.assert_array_equal(guided_filter_volume(vol, guide, radius, eps, missing, weight=weight), want)
    inp = vol.copy()
    np.testing.assert_array_equal(guided_filter_volume(inp, guide, radius, eps, missing, True, weight), want)
