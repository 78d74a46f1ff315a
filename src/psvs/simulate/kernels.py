"""The renderer's per-ray glue as Numba kernels (compiled once per machine, kept in ``__pycache__``): what
:meth:`psvs.simulate.geometry.SceneGeometry.intersect` makes of Embree's answer (the hit face's normal, the
distance, the object, the point, the normal turned to face the ray), what :func:`psvs.simulate.radiance.shade`
computes of the lamp (distance, cosine, the shadow rays, the irradiance), and the two textures read per hit
(a photograph's bilinear read, value noise). Each is one pass over the rays in
place of NumPy's dozen temporary arrays, with the same formulas in the same order of operations (a dot product
of three terms summed as NumPy's ``einsum`` sums it: the first and third, then the second), so the images are
the same to the last bit (tests/simulate/test_render_kernels.py holds them to the NumPy forms)."""
from __future__ import annotations

import numba as nb
import numpy as np

#: How each kernel is compiled: cached, without the GIL (the renderer's threads run them side by side), and
#: NumPy's error model (x / 0 gives inf or NaN, as the NumPy forms did, where Numba's default raises).
_kernel = nb.njit(cache=True, nogil=True, error_model="numpy")


@_kernel
def face_hits(prim, tfar, face_normals, face_offsets, face_owner, origins, dirs, refine):  # pragma: no cover
    """Embree's hits as distances, objects and face normals: ``prim`` (N,) the hit triangle (< 0 none),
    ``tfar`` (N,) float32 Embree's distance, the faces' unit normals (F, 3), plane offsets (F,) and owners (F,),
    the rays (N, 3) mm. Returns (t (N,) mm, inf on a miss; obj (N,) -1 on a miss; normals (N, 3), the hit face's,
    face 0's on a miss). With ``refine`` t is the float64 ray-plane distance to the hit face, else Embree's."""
    n = prim.shape[0]
    t = np.empty(n)
    obj = np.empty(n, dtype=np.int64)
    nrm = np.empty((n, 3))
    for i in range(n):
        p = prim[i]
        hit = p >= 0
        f = p if hit else 0
        nx, ny, nz = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
        nrm[i, 0], nrm[i, 1], nrm[i, 2] = nx, ny, nz
        if not hit:
            t[i] = np.inf
            obj[i] = -1
            continue
        if refine:
            on = origins[i, 0] * nx + origins[i, 2] * nz
            on += origins[i, 1] * ny
            dn = dirs[i, 0] * nx + dirs[i, 2] * nz
            dn += dirs[i, 1] * ny
            t[i] = (face_offsets[f] - on) / dn
        else:
            t[i] = np.float64(tfar[i])
        obj[i] = face_owner[f]
    return t, obj, nrm


@_kernel
def finish_hits(t, obj, nrm, origins, dirs):  # pragma: no cover - compiled
    """In place: a distance that is not finite and positive becomes a miss (t inf, obj -1), the normals
    (N, 3) turn to face their ray; returns the hit points (N, 3) mm (the ray's origin on a miss)."""
    n = t.shape[0]
    points = np.empty((n, 3))
    for i in range(n):
        ti = t[i]
        if not np.isfinite(ti) or ti <= 0:
            t[i] = np.inf
            obj[i] = -1
            ti = 0.0
        for j in range(3):
            points[i, j] = origins[i, j] + ti * dirs[i, j]
        dn = nrm[i, 0] * dirs[i, 0] + nrm[i, 2] * dirs[i, 2]
        dn += nrm[i, 1] * dirs[i, 1]
        if dn > 0:
            for j in range(3):
                nrm[i, j] *= -1
    return points


@_kernel
def lamp_rays(points, normals, hit, lamp, offset):  # pragma: no cover - compiled
    """The lamp as each hit sees it: ``points``, ``normals`` (N, 3) mm, ``hit`` (N,) bool, ``lamp`` (3,) its
    position mm, ``offset`` mm how far off its surface a shadow ray starts. Returns (r2 (N,) squared distance
    mm², cos (N,) the cosine between the normal and the lamp (0 on a miss), the indices (M,) of the hits the
    lamp lights (cos > 0), their shadow rays' starts (M, 3) mm, unit directions (M, 3) and lengths (M,) mm,
    ``offset`` short of the lamp at both ends)."""
    n = points.shape[0]
    r2 = np.zeros(n)
    cos = np.zeros(n)
    lit = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if not hit[i]:
            continue
        tx = lamp[0] - points[i, 0]
        ty = lamp[1] - points[i, 1]
        tz = lamp[2] - points[i, 2]
        s = tx * tx + tz * tz
        s += ty * ty
        r2[i] = s
        c = normals[i, 0] * tx + normals[i, 2] * tz
        c += normals[i, 1] * ty
        c /= np.sqrt(s)
        cos[i] = c
        if c > 0:
            lit[m] = i
            m += 1
    lit = lit[:m]
    start = np.empty((m, 3))
    ldir = np.empty((m, 3))
    length = np.empty(m)
    for k in range(m):
        i = lit[k]
        r = np.sqrt(r2[i])
        for j in range(3):
            ldir[k, j] = (lamp[j] - points[i, j]) / r
            start[k, j] = points[i, j] + offset * normals[i, j]
        length[k] = r - 2 * offset
    return r2, cos, lit, start, ldir, length


@_kernel
def lit_radiance(albedo, hit, r2, cos, lit, shadowed, ambient, lamp_gain):  # pragma: no cover - compiled
    """In place: ``albedo`` (N,) times the irradiance, ambient + ``lamp_gain`` cos / r2 where the lamp lights
    the hit (``lit`` its indices, ``shadowed`` (M,) whether a solid blocks it), 0 on a miss."""
    lamp = np.zeros(albedo.shape[0], dtype=np.bool_)
    for k in range(lit.shape[0]):
        if not shadowed[k]:
            lamp[lit[k]] = True
    for i in range(albedo.shape[0]):
        if not hit[i]:
            albedo[i] = 0.0
        elif lamp[i]:
            c = cos[i] * lamp_gain
            c /= r2[i]
            albedo[i] *= ambient + c
        else:
            albedo[i] *= ambient + 0.0


@_kernel
def bilinear_texture(image, xy, width_mm, height_mm):  # pragma: no cover - compiled
    """``image`` (H, W) stretched over width x height mm centred on the origin, read bilinearly at the local
    points ``xy`` (N, 2) mm (clamped to its edge pixels): (N,) values, NaN at a point that is not finite
    (:class:`psvs.simulate.textures.ImageTexture`)."""
    h, w = image.shape
    out = np.empty(xy.shape[0])
    for i in range(xy.shape[0]):
        u = (xy[i, 0] / width_mm + 0.5) * w - 0.5
        v = (xy[i, 1] / height_mm + 0.5) * h - 0.5
        if not (np.isfinite(u) and np.isfinite(v)):      # no pixel to read
            out[i] = np.nan
            continue
        u = min(max(u, 0.0), w - 1.0)
        v = min(max(v, 0.0), h - 1.0)
        u0 = min(int(np.floor(u)), w - 2) if w > 1 else 0
        v0 = min(int(np.floor(v)), h - 2) if h > 1 else 0
        fu, fv = u - u0, v - v0
        u1, v1 = min(u0 + 1, w - 1), min(v0 + 1, h - 1)
        top = image[v0, u0] * (1 - fu) + image[v0, u1] * fu
        bot = image[v1, u0] * (1 - fu) + image[v1, u1] * fu
        out[i] = top * (1 - fv) + bot * fv
    return out


@_kernel
def value_noise(lattice, xy, scale_mm, low, high):  # pragma: no cover - compiled
    """Smooth value noise at the local points ``xy`` (N, 2) mm: the smoothstep-bilinear interpolation of
    ``lattice`` (1024, 1024) at pitch ``scale_mm``, between ``low`` and ``high``; NaN at a point that is not
    finite (:class:`psvs.simulate.textures.Noise`)."""
    out = np.empty(xy.shape[0])
    for i in range(xy.shape[0]):
        gx, gy = xy[i, 0] / scale_mm, xy[i, 1] / scale_mm
        if not (np.isfinite(gx) and np.isfinite(gy)):    # no lattice cell to read
            out[i] = np.nan
            continue
        ix_f, iy_f = np.floor(gx), np.floor(gy)
        fx, fy = gx - ix_f, gy - iy_f
        fx = fx * fx * (3 - 2 * fx)
        fy = fy * fy * (3 - 2 * fy)
        ix, iy = np.int64(ix_f) & 1023, np.int64(iy_f) & 1023
        ix1, iy1 = (ix + 1) & 1023, (iy + 1) & 1023
        top = lattice[iy, ix] * (1 - fx) + lattice[iy, ix1] * fx
        bot = lattice[iy1, ix] * (1 - fx) + lattice[iy1, ix1] * fx
        out[i] = low + (high - low) * (top * (1 - fy) + bot * fy)
    return out


@_kernel
def not_smooth(img, tol, out):  # pragma: no cover - compiled
    """In place: ``out`` (H, W) uint8 is 1 where the float64 image ``img`` (H, W) is not smooth: the largest of
    its second differences along the row, the column and both diagonals (``|a + b - 2 c|``, the frame's edge
    pixels repeated beyond it) exceeds ``tol``; 0 elsewhere, and where any of the four is NaN (NumPy's
    maximum carries a NaN through: :func:`psvs.simulate.adaptive.rough_pixels`' form)."""
    h, w = img.shape
    for y in range(h):
        ym, yp = max(y - 1, 0), min(y + 1, h - 1)
        for x in range(w):
            xm, xp = max(x - 1, 0), min(x + 1, w - 1)
            c = img[y, x]
            c2 = c + c                          # 2 c, exactly
            e1 = abs(img[y, xm] + img[y, xp] - c2)
            e2 = abs(img[ym, x] + img[yp, x] - c2)
            e3 = abs(img[ym, xm] + img[yp, xp] - c2)
            e4 = abs(img[ym, xp] + img[yp, xm] - c2)
            if np.isnan(e1) or np.isnan(e2) or np.isnan(e3) or np.isnan(e4):
                out[y, x] = 0
            else:
                out[y, x] = 1 if max(max(e1, e2), max(e3, e4)) > tol else 0


@_kernel
def bilinear_fill(coarse, iy, ix, fy, fx, rough_cell, out, traced):  # pragma: no cover - compiled
    """In place: ``out`` (H, W) interpolated bilinearly from the coarse grid's values ``coarse`` (h, w), each
    pixel from the grid cell (``iy`` (H,), ``ix`` (W,)) it lies in at the fractions ``fy`` (H,), ``fx`` (W,),
    along the rows first and then across them (:func:`psvs.simulate.adaptive.one_sample`'s NumPy form, the
    same operations in the same order); ``traced`` (H, W) whether that cell is ``rough_cell`` (h - 1, w - 1)."""
    h, w = out.shape
    for y in range(h):
        r = iy[y]
        gy = fy[y]
        for x in range(w):
            c = ix[x]
            gx = fx[x]
            top = coarse[r, c] * (1 - gx) + coarse[r, c + 1] * gx
            bottom = coarse[r + 1, c] * (1 - gx) + coarse[r + 1, c + 1] * gx
            out[y, x] = top * (1 - gy) + bottom * gy
            traced[y, x] = rough_cell[r, c]


@_kernel
def rigid_rows(v, R, t):  # pragma: no cover - compiled
    """R v + t of each row of ``v`` (N, 3) float64 (``t`` (3,); zeros for a direction), in one pass (NumPy's
    matrix product or broadcasts made several passes and temporaries: slower than building Embree's scene)."""
    n = v.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        x, y, z = v[i, 0], v[i, 1], v[i, 2]
        for j in range(3):
            out[i, j] = R[j, 0] * x + R[j, 1] * y + R[j, 2] * z + t[j]
    return out
