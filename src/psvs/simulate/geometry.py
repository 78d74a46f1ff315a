"""Ray-scene intersection: Embree finds the candidate surface, float64 geometry gives the exact hit.

Embree (through embreex) runs in float32 on tessellated meshes. Curved objects are tessellated so that
the mesh *circumscribes* the true surface; each candidate hit is then recomputed exactly in float64
(ray-plane for flat faces, ray-disc, ray-sphere, ray-cylinder), and a ray that misses the true surface
(it passed between the mesh and the surface) continues from there. Positions are exact to ~1e-9 mm.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np
import trimesh
from embreex import mesh_construction, rtcore_scene

from psvs._threads import pool_size
from psvs.simulate.kernels import face_hits, finish_hits, rigid_rows
from psvs.simulate.scene import Pose, Scene, SceneObject

SECTIONS = 128                 # polygon sides for discs and cylinders
SPHERE_SUBDIVISIONS = 4        # icosphere level (5120 faces)
BACKDROP_HALF_MM = 1.0e5
_ZERO = np.zeros(3)


class Hits(NamedTuple):
    """t_mm (N,) distance along the ray (inf on a miss), obj (N,) object index (-1 on a miss; the backdrop
    is ``len(scene.objects)``), points_mm (N, 3), normals (N, 3) unit, facing the incoming ray."""

    t_mm: np.ndarray
    obj: np.ndarray
    points_mm: np.ndarray
    normals: np.ndarray


def _local_mesh(o: SceneObject) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) mm, faces (F, 3)) in the object's local frame, circumscribing curved surfaces."""
    if o.kind == "rectangle":
        w, h = o.size_mm
        v = np.array([[-w / 2, -h / 2, 0], [w / 2, -h / 2, 0], [w / 2, h / 2, 0], [-w / 2, h / 2, 0]], float)
        return v, np.array([[0, 1, 2], [0, 2, 3]])
    if o.kind == "disc":
        r = o.radius_mm / np.cos(np.pi / SECTIONS)
        a = 2 * np.pi * np.arange(SECTIONS) / SECTIONS
        v = np.vstack([[0, 0, 0], np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros(SECTIONS)])])
        k = np.arange(SECTIONS)   # the centre vertex 0, then rim vertices 1..SECTIONS: one fan triangle each
        f = np.column_stack([np.zeros(SECTIONS, int), 1 + k, 1 + (k + 1) % SECTIONS])
        return v, f
    if o.kind == "box":
        m = trimesh.creation.box(extents=o.size_mm)
        return np.asarray(m.vertices, float), np.asarray(m.faces)
    if o.kind == "cylinder":
        m = trimesh.creation.cylinder(radius=o.radius_mm / np.cos(np.pi / SECTIONS), height=o.height_mm,
                                      sections=SECTIONS)
        return np.asarray(m.vertices, float), np.asarray(m.faces)
    if o.kind == "sphere":
        m = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=1.0)
        tri = m.triangles
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        inradius = np.min(np.abs(np.einsum("ij,ij->i", n / np.linalg.norm(n, axis=1, keepdims=True), tri[:, 0])))
        return np.asarray(m.vertices, float) * (o.radius_mm / inradius), np.asarray(m.faces)
    return np.asarray(o.vertices_mm, float), np.asarray(o.faces)


def backdrop_object(scene: Scene) -> SceneObject:
    """The backdrop as a large rectangle facing the camera (an ordinary object)."""
    pose = Pose(np.eye(3), np.array([0.0, 0.0, scene.backdrop_z_mm]))
    return SceneObject("rectangle", pose, scene.backdrop_texture, size_mm=(2 * BACKDROP_HALF_MM,) * 2,
                       name="backdrop")


def group_by(labels: np.ndarray):
    """Yield (label, indices) for each distinct integer label, indices sorted (one argsort, no masks)."""
    order = np.argsort(labels, kind="stable")
    sorted_labels = labels[order]
    cuts = np.flatnonzero(np.diff(sorted_labels)) + 1
    for chunk in np.split(order, cuts):
        if len(chunk):
            yield int(labels[chunk[0]]), chunk


class SceneGeometry:
    """Embree scene for a :class:`Scene` plus the exact surfaces for refinement."""

    def __init__(self, scene: Scene):
        self.objects = list(scene.objects) + ([backdrop_object(scene)] if scene.backdrop_z_mm is not None else [])
        tris, owner, self.world_triangles = [], [], []
        for k, o in enumerate(self.objects):
            v, f = _local_mesh(o)
            w = o.pose.to_world(v)[f]             # (F, 3, 3) world triangles, float64
            tris.append(w)
            owner.append(np.full(len(f), k))
        self.triangles = np.concatenate(tris)
        self.face_owner = np.concatenate(owner)
        nrm = np.cross(self.triangles[:, 1] - self.triangles[:, 0], self.triangles[:, 2] - self.triangles[:, 0])
        self.face_normals = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
        self.face_offsets = np.einsum("ij,ij->i", self.face_normals, self.triangles[:, 0])
        self._embree = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self._embree, self.triangles.astype(np.float32))
        self._threads = pool_size(8)
        # per object index (plus one slot for "no object"): does it need exact curved refinement?
        self._curved = np.array([o.kind in ("disc", "sphere", "cylinder") for o in self.objects] + [False])

    def _run(self, origins, dirs, **kwargs):
        """Embree query in float32, split over threads (embreex releases the GIL)."""
        o, d = origins.astype(np.float32, copy=False), dirs.astype(np.float32, copy=False)
        n = len(o)
        if self._threads == 1 or n < 100_000:
            return self._embree.run(o, d, **kwargs)
        cuts = np.linspace(0, n, self._threads + 1).astype(int)
        parts = [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]

        def one(sl):
            kw = dict(kwargs)
            if kw.get("dists") is not None:
                kw["dists"] = kw["dists"][sl]
            return self._embree.run(o[sl], d[sl], **kw)

        with ThreadPoolExecutor(self._threads) as ex:
            out = list(ex.map(one, parts))
        if isinstance(out[0], dict):
            return {key: np.concatenate([np.asarray(r[key]) for r in out]) for key in out[0]}
        return np.concatenate([np.asarray(r) for r in out])

    def min_z_mm(self, k: int) -> float:
        """Smallest z (frame C) of object k's mesh, mm."""
        return float(self.triangles[self.face_owner == k][..., 2].min())

    def occluded(self, origins_mm: np.ndarray, dirs: np.ndarray, dist_mm: np.ndarray) -> np.ndarray:
        """Mask (N,) of rays blocked before ``dist_mm`` (shadow rays)."""
        if len(origins_mm) == 0:
            return np.zeros(0, dtype=bool)
        res = self._run(origins_mm, dirs, dists=dist_mm.astype(np.float32), query="OCCLUDED")
        return np.asarray(res) >= 0

    def intersect(self, origins_mm: np.ndarray, dirs: np.ndarray, max_passes: int = 4, refine: bool = True) -> Hits:
        """First hit of every ray (origins (N, 3) mm, unit dirs (N, 3)).

        Curved objects (discs, spheres, cylinders) are always intersected exactly in float64, per
        object, and rays that miss a curved object's true surface continue past it (up to
        ``max_passes`` times). Flat faces (rectangles, boxes, meshes, the backdrop) are refined all at
        once by a float64 ray-plane intersection with the hit face when ``refine`` (ground truth);
        without it they keep Embree's float32 distance (~1e-4 mm at 1 m: enough for shading).
        """
        res = self._run(origins_mm, dirs, output=1)
        prim = np.asarray(res["primID"])
        tfar = np.asarray(res["tfar"])
        o, d = (np.ascontiguousarray(a, dtype=np.float64) for a in (origins_mm, dirs))
        t, obj, nrm = face_hits(prim, tfar, self.face_normals, self.face_offsets, self.face_owner, o, d, refine)
        curved = self._curved[np.where(obj >= 0, obj, len(self.objects))]
        if curved.any():
            idx = np.flatnonzero(curved)
            t_c, obj_c, nrm_c = self._intersect_curved(origins_mm[idx], dirs[idx], obj[idx], prim[idx],
                                                       tfar[idx], max_passes)
            t[idx], obj[idx], nrm[idx] = t_c, obj_c, nrm_c
        points = finish_hits(t, obj, nrm, o, d)
        return Hits(t, obj, points, nrm)

    def _intersect_curved(self, o, d, obj, prim, t_embree, max_passes):
        """Exact hits for rays whose Embree candidate is on a curved object; misses continue past it."""
        n = len(o)
        t_out, obj_out, nrm_out = np.full(n, np.inf), np.full(n, -1), np.zeros((n, 3))
        start = np.zeros(n)
        active = np.arange(n)
        for p in range(max_passes):
            if p > 0:  # continue the rays that slipped between a tessellation and its true surface
                oo = o[active] + start[active, None] * d[active]
                res = self._run(oo, d[active], output=1)
                prim_a = np.asarray(res["primID"])
                t_embree_a = np.asarray(res["tfar"])
                obj_a = np.where(prim_a >= 0, self.face_owner[np.maximum(prim_a, 0)], -1)
            else:
                oo, prim_a, t_embree_a, obj_a = o, prim, t_embree, obj
            retry = []
            for k, sel in group_by(obj_a):
                if k < 0:
                    continue
                t, ok, nrm = self._exact(k, oo[sel], d[active[sel]], prim_a[sel])
                idx = active[sel]
                t_out[idx[ok]] = start[idx[ok]] + t[ok]
                obj_out[idx[ok]] = k
                nrm_out[idx[ok]] = nrm[ok]
                start[idx[~ok]] += np.maximum(t_embree_a[sel[~ok]], 0) + 1e-3
                retry.append(idx[~ok])
            active = np.concatenate(retry) if retry else np.zeros(0, int)
            if len(active) == 0:
                break
        return t_out, obj_out, nrm_out

    def _exact(self, k: int, o: np.ndarray, d: np.ndarray, prim: np.ndarray):
        """Exact float64 hit of rays (o, d) with object k, given Embree's candidate triangles."""
        obj = self.objects[k]
        R, p0 = obj.pose.rotation, obj.pose.position_mm
        ol, dl = (o - p0) @ R, d @ R       # local frame
        if obj.kind in ("rectangle", "box", "mesh"):
            nrm = self.face_normals[prim]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (self.face_offsets[prim] - np.einsum("ij,ij->i", o, nrm)) / np.einsum("ij,ij->i", d, nrm)
            return t, np.isfinite(t) & (t > 0), nrm
        if obj.kind == "disc":
            with np.errstate(divide="ignore", invalid="ignore"):
                t = -ol[:, 2] / dl[:, 2]
            p = ol + t[:, None] * dl
            ok = np.isfinite(t) & (t > 0) & (p[:, 0] ** 2 + p[:, 1] ** 2 <= obj.radius_mm ** 2)
            return t, ok, np.tile(R[:, 2], (len(t), 1))
        if obj.kind == "sphere":
            b = np.einsum("ij,ij->i", ol, dl)
            c = np.einsum("ij,ij->i", ol, ol) - obj.radius_mm ** 2
            disc = b * b - c
            ok = disc >= 0
            t = -b - np.sqrt(np.where(ok, disc, 0))
            ok &= t > 0
            p = ol + t[:, None] * dl
            return t, ok, (p / obj.radius_mm) @ R.T
        return self._exact_cylinder(obj, ol, dl, R)

    @staticmethod
    def _exact_cylinder(obj: SceneObject, ol, dl, R):
        """Finite cylinder about local z, |z| <= h/2, with flat caps."""
        r, h2 = obj.radius_mm, obj.height_mm / 2
        a = dl[:, 0] ** 2 + dl[:, 1] ** 2
        b = ol[:, 0] * dl[:, 0] + ol[:, 1] * dl[:, 1]
        c = ol[:, 0] ** 2 + ol[:, 1] ** 2 - r * r
        disc = b * b - a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            t_side = (-b - np.sqrt(np.where(disc >= 0, disc, 0))) / a
            z_side = ol[:, 2] + t_side * dl[:, 2]
            side_ok = (disc >= 0) & (a > 0) & (t_side > 0) & (np.abs(z_side) <= h2)
            t_caps = []
            for zc in (-h2, h2):
                tc = (zc - ol[:, 2]) / dl[:, 2]
                pc = ol + tc[:, None] * dl
                t_caps.append(np.where((tc > 0) & (pc[:, 0] ** 2 + pc[:, 1] ** 2 <= r * r), tc, np.inf))
        t = np.minimum(np.where(side_ok, t_side, np.inf), np.minimum(*t_caps))
        ok = np.isfinite(t)
        p = ol + np.where(ok, t, 0)[:, None] * dl
        on_cap = np.abs(np.abs(p[:, 2]) - h2) < 1e-9 * max(1.0, h2)
        nl = np.where(on_cap[:, None], np.column_stack([np.zeros_like(t), np.zeros_like(t), np.sign(p[:, 2])]),
                      np.column_stack([p[:, 0], p[:, 1], np.zeros_like(t)]) / r)
        return t, ok, nl @ R.T

    def local_xy(self, k: int, points_mm: np.ndarray) -> np.ndarray:
        """Texture coordinates: local (x, y) of points on object k, (N, 2) mm."""
        return self.objects[k].pose.to_local(points_mm)[:, :2]

    def moved(self, world2rig: np.ndarray, objects) -> MovedGeometry:
        """This geometry seen from a frame at ``world2rig`` (4x4: this scene's points -> that frame), whose
        ``objects`` are this geometry's objects moved there (:func:`psvs.simulate.sequence.scene_in_rig_frame`,
        same order): see :class:`MovedGeometry`."""
        return MovedGeometry(self, world2rig, objects)


class MovedGeometry:
    """A :class:`SceneGeometry` seen from another frame (a camera moving through a rigid scene, frame after
    frame): rays are taken into the scene's frame and hits brought back, instead of building Embree's scene
    again for every pose (20 ms for the weld seam's 21 thousand triangles: a quarter of the time of a sensor
    window's render in the simulated cell). The same interface as SceneGeometry: ``objects`` (the moved
    objects, for shading and texture coordinates), :meth:`intersect`, :meth:`occluded`, :meth:`min_z_mm`,
    :meth:`local_xy`; the hits are those of the moved scene to float64's rounding (Embree's float32 candidate
    faces are searched in the scene's own frame)."""

    def __init__(self, base: SceneGeometry, world2rig: np.ndarray, objects):
        objects = list(objects)
        if len(objects) != len(base.objects):
            raise ValueError(f"the moved scene has {len(objects)} objects, its geometry {len(base.objects)}")
        self.base, self.objects = base, objects
        m = np.asarray(world2rig, dtype=np.float64)
        self._R, self._t = np.ascontiguousarray(m[:3, :3]), np.ascontiguousarray(m[:3, 3])
        self._Rt, self._back = np.ascontiguousarray(self._R.T), -(self._R.T @ self._t)   # this frame -> the scene's

    def _in_base(self, origins_mm: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rays (N, 3) of this frame in the scene's own frame."""
        rows = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
        return rigid_rows(rows(origins_mm), self._Rt, self._back), rigid_rows(rows(dirs), self._Rt, _ZERO)

    def intersect(self, origins_mm: np.ndarray, dirs: np.ndarray, max_passes: int = 4, refine: bool = True) -> Hits:
        """:meth:`SceneGeometry.intersect` of rays in this frame, the hits in this frame."""
        hits = self.base.intersect(*self._in_base(origins_mm, dirs), max_passes, refine)
        return Hits(hits.t_mm, hits.obj, rigid_rows(hits.points_mm, self._R, self._t),
                    rigid_rows(hits.normals, self._R, _ZERO))

    def occluded(self, origins_mm: np.ndarray, dirs: np.ndarray, dist_mm: np.ndarray) -> np.ndarray:
        """:meth:`SceneGeometry.occluded` of rays in this frame."""
        if len(origins_mm) == 0:
            return np.zeros(0, dtype=bool)
        return self.base.occluded(*self._in_base(origins_mm, dirs), dist_mm)

    def min_z_mm(self, k: int) -> float:
        """Smallest z (this frame) of object k's mesh, mm."""
        tri = self.base.triangles[self.base.face_owner == k]
        return float((tri @ self._R[2] + self._t[2]).min())

    def local_xy(self, k: int, points_mm: np.ndarray) -> np.ndarray:
        """Texture coordinates: local (x, y) of points (this frame) on object k, (N, 2) mm."""
        return self.objects[k].pose.to_local(points_mm)[:, :2]
