import numpy as np
import pytest

from psvs.dense import dense_disparity, psnr_db, separate_views
from psvs.dense.evaluate import superimpose
from tests.dense.planted import layered_pair


@pytest.fixture(scope="module")
def pair():
    return layered_pair()


@pytest.mark.parametrize("split", [0.5, 0.3])
def test_views_come_back_with_the_true_disparity(pair, split):
    left, right, tl, tr = pair
    c = superimpose(left, right, split)
    lv, rv = separate_views(c, tl, split, tr)
    assert psnr_db(lv, left) > 29.0 and psnr_db(rv, right) > 29.0
    assert psnr_db(lv, left) > psnr_db(c, left) + 4.0 and psnr_db(rv, right) > psnr_db(c, right) + 4.0
    # and the separated views still add up to the complex image (least squares: within a few grey levels)
    assert np.sqrt(np.mean(((1 - split) * lv + split * rv - c) ** 2)) < 3.0


def test_views_come_back_with_the_estimated_disparity(pair):
    left, right, _, _ = pair
    c = superimpose(left, right)
    res = dense_disparity(c, 0, 40)
    lv, rv = separate_views(c, res.disparity_left, 0.5, res.disparity_right)
    assert psnr_db(lv, left) > 27.5 and psnr_db(rv, right) > 27.5
    assert psnr_db(lv, left) > psnr_db(c, left) + 3.0   # better than calling the mixture a view


def test_psnr_of_known_errors():
    a = np.zeros((10, 10))
    assert psnr_db(a, a) == float("inf")
    assert psnr_db(a + 2.55, a) == pytest.approx(40.0)


@pytest.mark.parametrize("kwargs, message", [
    ({"disparity_left": np.zeros((5, 5))}, "does not match"),
    ({"split": 1.0}, "split"),
])
def test_bad_input_is_named(pair, kwargs, message):
    left, right, tl, _ = pair
    args = {"image": superimpose(left, right), "disparity_left": tl, **kwargs}
    with pytest.raises(ValueError, match=message):
        separate_views(**args)


def _differences(h: int, w: int, offset: int, n_unknowns: int):
    """G: the 4-neighbour differences of one view (h, w) at ``offset`` among ``n_unknowns``, as scipy
    builds it (the reference the matrix-free operators are checked against)."""
    import scipy.sparse as sp
    idx = np.arange(h * w).reshape(h, w)
    blocks = []
    for a, b in ((idx[:, 1:], idx[:, :-1]), (idx[1:, :], idx[:-1, :])):
        a, b = a.ravel() + offset, b.ravel() + offset
        r = np.arange(a.size)
        blocks.append(sp.csr_matrix((np.r_[np.ones(a.size), -np.ones(a.size)], (np.r_[r, r], np.r_[a, b])),
                                    shape=(a.size, n_unknowns)))
    return sp.vstack(blocks).tocsr()


def test_rectified_normal_equations_match_scipy_sparse():
    """The rectified path's operator (any sampling D, e.g. a build's bilinear one) is DᵀD + c·TᵀT + λ·GᵀG as
    scipy builds it explicitly."""
    import scipy.sparse as sp

    from psvs.dense.separate import coupling_ties, rect_apply, sampling_matrix
    rng = np.random.default_rng(5)
    h, w, s, coupling, lam = 8, 11, 0.45, 0.9, 0.2
    n = h * w
    uv = np.column_stack([rng.uniform(-1, w, 70), rng.uniform(-1, h, 70)])    # some off the grid
    uv[3] = np.nan
    data = sp.hstack([(1 - s) * sampling_matrix(uv, h, w), s * sampling_matrix(uv + [2.3, 0.4], h, w)]).tocsr()
    dl = rng.uniform(0, 5, (h, w))
    dl[1, 2] = np.nan
    yy, xx, x0, f = coupling_ties(dl, None, w)
    m, r = yy.size, np.arange(yy.size)
    ties = sp.csr_matrix((np.r_[-np.ones(m), 1 - f, f], (np.r_[r, r, r], np.r_[
        yy * w + xx, n + yy * w + x0, n + yy * w + np.minimum(x0 + 1, w - 1)])), shape=(m, 2 * n))
    grad = sp.vstack([_differences(h, w, 0, 2 * n), _differences(h, w, n, 2 * n)]).tocsr()
    normal = data.T @ data + coupling * (ties.T @ ties) + lam * (grad.T @ grad)
    apply = rect_apply(data, data.T.tocsr(), (yy, xx, x0, f), (h, w), coupling, lam)
    out = np.empty(2 * n)
    for _ in range(3):
        v = rng.normal(0, 1, 2 * n)
        apply(v, out)
        np.testing.assert_allclose(out, normal @ v, atol=1e-12)


def test_matrix_free_normal_equations_match_scipy_sparse():
    """The Numba operator is DᵀD + c·TᵀT + λ·GᵀG as scipy builds it, and the solve follows scipy's cg."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spl

    from psvs.dense.separate import cg_matrix_free, coupling_ties, normal_apply
    rng = np.random.default_rng(3)
    h, w, s, coupling, lam = 9, 13, 0.4, 0.7, 0.05
    n = h * w
    dl = rng.uniform(0, 6, (h, w))
    dl[2, 3] = np.nan
    dl[:, -1] = 12.99                 # twins at the grid's left end and beyond it
    dr = rng.uniform(0, 6, (h, w))
    yy, xx, x0, f = coupling_ties(dl, dr, w)
    m = yy.size
    r = np.arange(m)
    x1 = np.minimum(x0 + 1, w - 1)
    ties = sp.csr_matrix((np.r_[-np.ones(m), 1 - f, f], (np.r_[r, r, r], np.r_[yy * w + xx, n + yy * w + x0,
                                                                              n + yy * w + x1])), shape=(m, 2 * n))
    k = np.arange(n)
    data = sp.csr_matrix((np.r_[np.full(n, 1 - s), np.full(n, s)], (np.r_[k, k], np.r_[k, k + n])), shape=(n, 2 * n))
    grad = sp.vstack([_differences(h, w, 0, 2 * n), _differences(h, w, n, 2 * n)]).tocsr()
    normal = (data.T @ data + coupling * (ties.T @ ties) + lam * (grad.T @ grad)).tocsr()
    ptr = np.searchsorted(yy, np.arange(h + 1)).astype(np.int64)
    apply = lambda v, out: normal_apply(v, out, h, w, s, coupling, lam, ptr, xx.astype(np.int64),  # noqa: E731
                                         x0.astype(np.int64), f)
    v = rng.normal(0, 1, 2 * n)
    out = np.empty(2 * n)
    apply(v, out)
    np.testing.assert_allclose(out, normal @ v, atol=1e-12)
    b, start = rng.normal(0, 1, 2 * n), rng.normal(0, 1, 2 * n)
    for it in (5, 40):
        want, _ = spl.cg(normal, b, x0=start, maxiter=it, rtol=1e-7)
        np.testing.assert_allclose(cg_matrix_free(b, start, it, 1e-7, apply), want, atol=1e-8)
