"""Cast the rays of one ground-truth sample: buffers, hard shadow and soft shadow.

Two Mitsuba scenes per sample: ``bg`` (the background template only) and ``obj``
(the object only). The object's shadow is what a compositor adds to a background
photo, so the ground truth is defined as an **irradiance ratio**:

    E_without(P) = sum_i  V_bg(P, Q_i) * cos_r * cos_l / d^2
    E_with(P)    = sum_i  V_bg(P, Q_i) * V_obj(P, Q_i) * cos_r * cos_l / d^2
    darkness(P)  = 1 - E_with / E_without      (0 where E_without = 0)

for a background point P (the camera ray's hit with the object removed), its
normal n_r facing the camera, N stratified samples Q_i on the disk light (a k x k
jittered grid through the concentric disk map, jittered independently per pixel),
``cos_r = max(0, n_r . w)``, ``cos_l = max(0, n_l . -w)`` (one-sided emitter) and
``d = |Q_i - P|``. V_bg is visibility against the background itself (a step can
shade the floor), V_obj against the object. So darkness is "the fraction of the
light the object takes away", 1 = full shadow, and background self-shadowing never
counts as the object's shadow. The hard shadow is the same with the single sample
Q = the light's centre (1 = the object blocks the centre while the background
alone would let it through).

Residual Monte-Carlo noise: per pixel, the delta-method standard error of the ratio
estimator, ``sqrt(sum w_i^2 (o_i - o_bar)^2) / sum w_i`` with o_i = 1 - V_obj
(i.i.d. formula; the stratified estimate is no noisier than this).

Pixels whose cone toward the disk cannot meet the object's bounding sphere get
darkness 0 without tracing (exact: the object cannot block them).
"""
from __future__ import annotations

import math
import time

import numpy as np

from .raycast import RayScene
from .scene import DiskLight, SceneSpec, background_meshes

_EPS = 1e-4  # ray origin offset along the normal, world units per unit distance


def _unit(a):
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def concentric_disk(u1, u2):
    """Shirley-Chiu concentric map of [0,1)^2 onto the unit disk (area preserving)."""
    a, b = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    big_a = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(big_a, a, b)
        phi = np.where(big_a, (math.pi / 4) * (b / a), math.pi / 2 - (math.pi / 4) * (a / b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return r * np.cos(phi), r * np.sin(phi)


class SampleRenderer:
    """Ray casting for one SceneSpec (builds its two Mitsuba scenes once)."""

    def __init__(self, spec: SceneSpec):
        self.spec = spec
        self.bg = RayScene(background_meshes(spec.bg_kind, spec.bg_params, spec.base))
        self.obj = RayScene([(spec.obj_V, spec.obj_F)])
        self._primary = None

    # -- camera rays ----------------------------------------------------------------
    def primary(self, subsamples: int = 2) -> dict:
        """Buffers seen by the camera (cached): see ``render`` for the keys."""
        if self._primary is not None:
            return self._primary
        cam = self.spec.camera
        W, H, f = cam.width, cam.height, cam.focal
        u, v = cam.pixel_grid()
        o = np.array([0.0, cam.cam_height, 0.0])

        def cast(uu, vv):
            d = _unit(cam.ray(uu.ravel(), vv.ravel()))
            O = np.broadcast_to(o, d.shape)
            tb, pb, nb = self.bg.intersect(O, d)
            to, po, no = self.obj.intersect(O, d)
            return d, (tb, pb, nb), (to, po, no)

        d, (tb, pb, nb), (to, po, no) = cast(u, v)
        hit_obj = np.isfinite(to) & (to < tb)
        hit_bg = np.isfinite(tb)
        # coverage: a subsamples x subsamples grid inside each pixel
        cov = np.zeros(H * W)
        offs = (np.arange(subsamples) + 0.5) / subsamples - 0.5
        for dy in offs:
            for dx in offs:
                _, (tb2, _, _), (to2, _, _) = cast(u + dx, v + dy)
                cov += np.isfinite(to2) & (to2 < tb2)
        alpha = cov / subsamples ** 2

        def pix_height(p, ok):
            Y = np.where(ok, p[:, 1], 0.0)
            Y = np.where(np.abs(Y) < 1e-6, 0.0, Y)       # the ground is exactly Y = 0
            D = np.where(ok, -p[:, 2], 1.0)
            return np.where(ok, f * Y / D, 0.0)

        def facing(n, ok):
            n = np.where(ok[:, None], n, 0.0)
            flip = np.sum(n * d, axis=1) > 0             # make normals face the camera
            return np.where(flip[:, None], -n, n)

        def depth(p, ok):
            return np.where(ok, -np.nan_to_num(p[:, 2]), 0.0)

        self._primary = {
            "fg_depth": depth(po, hit_obj).reshape(H, W), "bg_depth": depth(pb, hit_bg).reshape(H, W),
            "mask": hit_obj.reshape(H, W), "alpha": alpha.reshape(H, W),
            "fg_height": pix_height(po, hit_obj).reshape(H, W),
            "bg_height": pix_height(pb, hit_bg).reshape(H, W),
            "bg_valid": hit_bg.reshape(H, W),
            "bg_is_ground": (hit_bg & (np.abs(np.nan_to_num(pb[:, 1])) < 1e-5)).reshape(H, W),
            "bg_points": np.where(hit_bg[:, None], pb, 0.0), "bg_normals": facing(nb, hit_bg),
            "obj_points": np.where(hit_obj[:, None], po, 0.0), "obj_normals": facing(no, hit_obj),
        }
        return self._primary

    # -- light validity -------------------------------------------------------------
    def light_ok(self, light: DiskLight) -> bool:
        """The light is inside the room: the segment from the object's centre to the
        light's centre, and the disk itself, are not cut by the background."""
        c = self.spec.obj_center
        w = light.center - c
        dist = float(np.linalg.norm(w))
        if self.bg.occluded(c[None], (w / dist)[None], np.array([dist]))[0]:
            return False
        e1, e2 = light.basis()
        ang = np.linspace(0, 2 * math.pi, 12, endpoint=False)
        dirs = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
        return not self.bg.occluded(np.broadcast_to(light.center, dirs.shape), dirs,
                                    np.full(len(dirs), light.radius)).any()

    # -- shadows --------------------------------------------------------------------
    def hard_shadow(self, light: DiskLight) -> np.ndarray:
        """Darkness (H, W) float32 in {0, 1} from the light's centre (module doc)."""
        pr = self.primary()
        P, N, ok = pr["bg_points"], pr["bg_normals"], pr["bg_valid"].ravel()
        idx = np.nonzero(ok)[0]
        out = np.zeros(len(ok), np.float32)
        if len(idx):
            w = light.center - P[idx]
            d = np.linalg.norm(w, axis=1)
            w /= d[:, None]
            front = (np.sum(w * N[idx], 1) > 0) & (np.sum(-w * light.normal, 1) > 0)
            org = P[idx] + N[idx] * _EPS * (1.0 + d[:, None])
            lit = front & ~self.bg.occluded(org, w, d * (1 - 1e-4))
            blocked = self.obj.occluded(org, w, d * (1 - 1e-4))
            out[idx] = (lit & blocked).astype(np.float32)
        cam = self.spec.camera
        return out.reshape(cam.height, cam.width)

    def candidates(self, light: DiskLight) -> np.ndarray:
        """Flat indices of background pixels the object might shadow (conservative
        cone-vs-bounding-sphere test, see module doc)."""
        pr = self.primary()
        ok = pr["bg_valid"].ravel()
        P = pr["bg_points"]
        S, R = self.spec.obj_center, self.spec.obj_radius * 1.001 + 1e-4
        a_vec = light.center - P
        a = np.linalg.norm(a_vec, axis=1)
        b_vec = S - P
        b = np.linalg.norm(b_vec, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            alpha = np.arcsin(np.clip(light.radius / a, 0, 1))
            beta = np.arcsin(np.clip(R / b, 0, 1))
            cosg = np.sum(a_vec * b_vec, 1) / (a * b)
        gamma = np.arccos(np.clip(cosg, -1, 1))
        cand = ok & ((b <= R) | (gamma <= alpha + beta + 1e-3))
        return np.nonzero(cand)[0]

    def soft_shadow(self, light: DiskLight, n_samples: int, rng: np.random.Generator,
                    max_rays: int = 1 << 20):
        """Darkness (H, W) float32 and its per-pixel standard error (module doc).

        n_samples is rounded up to a square k*k (stratified jittered grid)."""
        k = max(1, int(math.ceil(math.sqrt(n_samples))))
        n = k * k
        cam = self.spec.camera
        pr = self.primary()
        P, Nr = pr["bg_points"], pr["bg_normals"]
        dark = np.zeros(cam.width * cam.height, np.float32)
        err = np.zeros_like(dark)
        idx = self.candidates(light)
        e1, e2 = light.basis()
        gi, gj = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        gi, gj = gi.ravel(), gj.ravel()
        chunk = max(1, max_rays // n)
        for s in range(0, len(idx), chunk):
            ids = idx[s:s + chunk]
            m = len(ids)
            j1 = rng.random((m, n))
            j2 = rng.random((m, n))
            dx, dy = concentric_disk((gi[None] + j1) / k, (gj[None] + j2) / k)
            Q = light.center + light.radius * (dx[..., None] * e1 + dy[..., None] * e2)   # (m, n, 3)
            p = P[ids][:, None, :]
            nr = Nr[ids][:, None, :]
            w = Q - p
            d = np.linalg.norm(w, axis=2)
            w /= d[..., None]
            cos_r = np.sum(w * nr, 2)
            cos_l = -np.sum(w * light.normal, 2)
            weight = np.where((cos_r > 0) & (cos_l > 0), cos_r * cos_l / (d * d), 0.0)
            org = (p + nr * _EPS * (1.0 + d[..., None])).reshape(-1, 3)
            ww, dd = w.reshape(-1, 3), (d * (1 - 1e-4)).ravel()
            live = weight.ravel() > 0                     # no rays for samples that carry no light
            vis_bg = np.zeros(m * n, bool)
            occ_obj = np.zeros(m * n, bool)
            if live.any():
                vis_bg[live] = ~self.bg.occluded(org[live], ww[live], dd[live])
                l2 = live & vis_bg
                if l2.any():
                    occ_obj[l2] = self.obj.occluded(org[l2], ww[l2], dd[l2])
            wt = weight * vis_bg.reshape(m, n)
            o = occ_obj.reshape(m, n).astype(np.float64)
            e0 = wt.sum(1)
            safe = np.where(e0 > 0, e0, 1.0)
            dk = np.where(e0 > 0, (wt * o).sum(1) / safe, 0.0)
            se = np.where(e0 > 0, np.sqrt((wt ** 2 * (o - dk[:, None]) ** 2).sum(1)) / safe, 0.0)
            dark[ids] = dk
            err[ids] = se
        return dark.reshape(cam.height, cam.width), err.reshape(cam.height, cam.width), n

    def cutout_rgb(self, light: DiskLight, albedo) -> np.ndarray:
        """Linear RGB (H, W, 3) of the cutout: albedo * (0.25 + 0.75 * cos * V_self)
        lit from the light's centre (a flat-shaded preview for compositing, not a
        path-traced render; 0 outside the mask)."""
        pr = self.primary()
        cam = self.spec.camera
        m = pr["mask"].ravel()
        out = np.zeros((m.size, 3), np.float32)
        idx = np.nonzero(m)[0]
        if len(idx):
            P, N = pr["obj_points"][idx], pr["obj_normals"][idx]
            w = light.center - P
            d = np.linalg.norm(w, axis=1)
            w /= d[:, None]
            cos = np.clip(np.sum(w * N, 1), 0, 1)
            vis = ~self.obj.occluded(P + N * _EPS * (1 + d[:, None]), w, d)
            out[idx] = np.asarray(albedo)[None] * (0.25 + 0.75 * cos * vis)[:, None]
        return out.reshape(cam.height, cam.width, 3)


def render(spec: SceneSpec, light: DiskLight, n_samples: int, rng: np.random.Generator,
           renderer: SampleRenderer | None = None, albedo=(0.7, 0.7, 0.7)) -> dict:
    """All arrays of one sample (the .npz content, see docs/ground-truth.md)."""
    t0 = time.perf_counter()
    r = renderer or SampleRenderer(spec)
    pr = r.primary()
    hard = r.hard_shadow(light)
    soft, err, n = r.soft_shadow(light, n_samples, rng)
    rgb = r.cutout_rgb(light, albedo)
    return {
        "rgb": rgb.astype(np.float16), "alpha": pr["alpha"].astype(np.float32), "mask": pr["mask"],
        "fg_height": pr["fg_height"].astype(np.float32), "bg_height": pr["bg_height"].astype(np.float32),
        "bg_valid": pr["bg_valid"], "bg_is_ground": pr["bg_is_ground"],
        "fg_depth": pr["fg_depth"].astype(np.float32), "bg_depth": pr["bg_depth"].astype(np.float32),
        "shadow": soft.astype(np.float32), "shadow_stderr": err.astype(np.float16),
        "hard_shadow": hard.astype(np.uint8), "light_samples": np.int32(n),
        "light_uvhs": light.uvhs(spec.camera).astype(np.float64),
        "light_center": light.center.astype(np.float64), "light_radius": np.float64(light.radius),
        "light_normal": light.normal.astype(np.float64),
        "render_seconds": np.float64(time.perf_counter() - t0),
    }
