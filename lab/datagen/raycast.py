"""Ray casting against triangle meshes with Mitsuba 3 (no rendering).

``RayScene`` wraps one Mitsuba scene made of triangle meshes and answers two
vectorised questions on numpy arrays:

* ``intersect(o, d, maxt)``: first hit distance ``t`` (inf on a miss), hit point
  and geometric normal — ``scene.ray_intersect``;
* ``occluded(o, d, maxt)``: is anything hit before ``maxt`` — ``scene.ray_test``.

Variant: ``llvm_ad_rgb`` (vectorised, JIT-compiled with LLVM; needs Debian's
``libllvm19`` or another libLLVM that Dr.Jit can find) when it works, else
``scalar_rgb`` with a Python loop over rays (about 10^5 rays/s: fine for the
tests' 64x64 images, far too slow for benchmarks). The choice is made once per
process by ``select_variant()``; ``PIXGRAPH_MITSUBA_VARIANT`` forces one.
"""
from __future__ import annotations

import functools
import os

import numpy as np


@functools.lru_cache(maxsize=1)
def select_variant() -> str:
    """Set and return the Mitsuba variant used for ray casting (see module doc)."""
    import mitsuba as mi
    forced = os.environ.get("PIXGRAPH_MITSUBA_VARIANT")
    candidates = [forced] if forced else ["llvm_ad_rgb", "scalar_rgb"]
    errors = []
    for name in candidates:
        try:
            mi.set_variant(name)
            # Building and intersecting a scene forces Dr.Jit to load LLVM: a
            # missing libLLVM shows up here, not at set_variant time.
            sc = RayScene([(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))])
            t, _, _ = sc.intersect(np.array([[0.2, 0.2, 1.0]]), np.array([[0, 0, -1.0]]))
            if not abs(float(t[0]) - 1.0) < 1e-5:
                raise RuntimeError(f"{name}: test ray gave t={t[0]}")
            return name
        except Exception as e:  # noqa: BLE001 -- report every failed variant together
            errors.append(f"{name}: {e}")
    raise RuntimeError("no usable Mitsuba variant: " + "; ".join(errors))


def _mesh(name: str, V: np.ndarray, F: np.ndarray, bsdf=None):
    """A Mitsuba triangle mesh; ``bsdf`` (a loaded BSDF) only matters for renders."""
    import drjit as dr
    import mitsuba as mi
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf
    m = mi.Mesh(name, vertex_count=len(V), face_count=len(F), has_vertex_normals=False, props=props)
    p = mi.traverse(m)
    p["vertex_positions"] = dr.ravel(mi.TensorXf(np.ascontiguousarray(V, np.float32).ravel()))
    p["faces"] = dr.ravel(mi.TensorXu(np.ascontiguousarray(F, np.uint32).ravel()))
    p.update()
    return m


class RayScene:
    """A Mitsuba scene built from triangle meshes [(V (n,3) float, F (m,3) int), ...]."""

    def __init__(self, meshes):
        import mitsuba as mi
        if mi.variant() is None:
            select_variant()
        d = {"type": "scene"}
        for i, (V, F) in enumerate(meshes):
            if len(F):
                d[f"m{i}"] = _mesh(f"m{i}", V, F)
        self._scene = mi.load_dict(d)
        self._scalar = mi.variant().startswith("scalar")

    def _rays(self, o, d, maxt):
        import mitsuba as mi
        o = np.ascontiguousarray(o, np.float32)
        d = np.ascontiguousarray(d, np.float32)
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
        if maxt is not None:
            ray.maxt = mi.Float(np.ascontiguousarray(np.broadcast_to(maxt, (len(o),)), np.float32))
        return ray

    def intersect(self, o, d, maxt=None):
        """First hits of rays o + t d; d must be unit vectors (t in world units).

        Returns ``(t, p, n)``: t (N,) float64 (inf on a miss), p (N, 3) hit points,
        n (N, 3) unit geometric normals (arbitrary side; NaN on a miss).
        """
        o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
        if self._scalar:
            return self._intersect_scalar(o, d, maxt)
        si = self._scene.ray_intersect(self._rays(o, d, maxt))
        valid = np.array(si.is_valid(), bool)
        t = np.where(valid, np.array(si.t, np.float64), np.inf)
        # o + t d, not si.p: Mitsuba interpolates si.p from barycentrics, which are
        # off by up to ~1 world unit on our 800-unit-long sliver triangles (cove
        # segments, step risers); t comes from the plane equation and is accurate.
        p = o + np.where(valid, t, 0.0)[:, None] * d
        n = np.array(si.n, np.float64).T
        n[~valid] = np.nan
        p[~valid] = np.nan
        return t, p, n

    def occluded(self, o, d, maxt=None):
        """Bool (N,): does any surface cut the ray o + t d for 0 < t < maxt."""
        o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
        if self._scalar:
            t, _, _ = self._intersect_scalar(o, d, maxt)
            return np.isfinite(t)
        return np.array(self._scene.ray_test(self._rays(o, d, maxt)), bool)

    def _intersect_scalar(self, o, d, maxt):
        import mitsuba as mi
        n_rays = len(o)
        t = np.full(n_rays, np.inf)
        p = np.full((n_rays, 3), np.nan)
        nn = np.full((n_rays, 3), np.nan)
        mt = np.broadcast_to(np.inf if maxt is None else maxt, (n_rays,))
        for i in range(n_rays):
            ray = mi.Ray3f(mi.Point3f(*o[i]), mi.Vector3f(*d[i]))
            if np.isfinite(mt[i]):
                ray.maxt = float(mt[i])
            si = self._scene.ray_intersect(ray)
            if si.is_valid():
                t[i] = si.t
                p[i] = o[i] + si.t * d[i]
                nn[i] = list(si.n)
        return t, p, nn
