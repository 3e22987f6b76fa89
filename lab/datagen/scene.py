"""3D scenes for ground truth: an object on a background, our camera, a disk light.

Everything is in world units with the camera ``cam_height`` above the ground
(``Camera`` of ``nodes/ops/camera.py``: no pitch, horizon by lens shift, camera at
``(0, H_cam, 0)`` looking down ``-Z``). Nothing is path traced: the camera's
primary rays and the shadow rays are cast with Mitsuba 3 (``raycast.RayScene``),
which is exact for visibility and much faster than rendering images.

Background templates (``BG_KINDS``), all built around the object's base point
``B = (Xo, 0, Zo)`` and rotated about the vertical through B by ``yaw``:

* ``ground``: the plane Y = 0 only;
* ``wall``: ground + one vertical wall ``gap`` behind the object's footprint;
* ``corner``: ground + two walls meeting in a concave vertical edge; each wall makes
  ``angle_left`` / ``angle_right`` with the image plane;
* ``two_corners``: ground + back wall + left and right side walls (a U);
* ``steps``: ground + 1-3 steps of ``riser`` height and ``tread`` depth, then a wall;
* ``curved``: ground bending up into a wall along a quarter circle of ``radius`` (a cove).

Split rule for backgrounds (docs/ground-truth.md): ``two_corners`` and ``curved`` are
test-only kinds; ``wall`` (|yaw| < 12 deg test, 12-40 deg train), ``corner``
(angles 45-70 deg test, 20-45 deg train) and ``steps`` (riser 0.15-0.30 test,
0.05-0.15 train) hold out a parameter range for test; ``ground`` has no parameter.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from pixgraph_nodes.ops.camera import Camera

BG_KINDS = ("ground", "wall", "corner", "two_corners", "steps", "curved")
WALL_KINDS_TRAIN = ("wall", "corner", "steps")
WALL_KINDS_TEST = ("wall", "corner", "two_corners", "steps", "curved")
_BIG = 400.0    # half-extent of the "infinite" planes, world units
_TALL = 60.0    # wall height, world units (the camera never sees the top)


# -- mesh helpers -------------------------------------------------------------

def _quad(p0, p1, p2, p3):
    V = np.array([p0, p1, p2, p3], np.float64)
    return V, np.array([[0, 1, 2], [0, 2, 3]], np.int64)


def _vertical_strip(a, b, y0=-1.0, y1=_TALL):
    """Vertical wall between horizontal points a and b (x, z)."""
    return _quad((a[0], y0, a[1]), (b[0], y0, b[1]), (b[0], y1, b[1]), (a[0], y1, a[1]))


def _box(x0, x1, y0, y1, z0, z1):
    import trimesh
    m = trimesh.creation.box(bounds=[[x0, y0, z0], [x1, y1, z1]])
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _ground():
    return _quad((-_BIG, 0, -_BIG), (_BIG, 0, -_BIG), (_BIG, 0, _BIG), (-_BIG, 0, _BIG))


def _rotate_about(meshes, base, yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    out = []
    for V, F in meshes:
        out.append(((V - base) @ R.T + base, F))
    return out


def background_meshes(kind: str, params: dict, base: np.ndarray):
    """Triangle meshes [(V, F), ...] of a background template around base point B.

    params (world units / degrees): ``gap`` (distance from the object's footprint
    centre to the first non-ground surface along -Z before yaw), ``yaw`` [deg],
    and the kind's own: corner ``angle_left``/``angle_right`` [deg],
    two_corners ``half_width_left``/``half_width_right``, steps ``n_steps``,
    ``riser``, ``tread``, curved ``radius``.
    """
    meshes = [_ground()]
    if kind == "ground":
        return meshes
    bx, bz = float(base[0]), float(base[2])
    zw = bz - params["gap"]                       # z of the first wall / riser / cove start
    if kind == "wall":
        meshes.append(_vertical_strip((bx - _BIG, zw), (bx + _BIG, zw)))
    elif kind == "corner":
        k = (bx + params.get("offset", 0.0), zw)
        al, ar = math.radians(params["angle_left"]), math.radians(params["angle_right"])
        meshes.append(_vertical_strip((k[0] - _BIG * math.cos(al), k[1] + _BIG * math.sin(al)), k))
        meshes.append(_vertical_strip(k, (k[0] + _BIG * math.cos(ar), k[1] + _BIG * math.sin(ar))))
    elif kind == "two_corners":
        xl, xr = bx - params["half_width_left"], bx + params["half_width_right"]
        meshes.append(_vertical_strip((xl, zw), (xr, zw)))
        meshes.append(_vertical_strip((xl, _BIG), (xl, zw)))
        meshes.append(_vertical_strip((xr, zw), (xr, _BIG)))
    elif kind == "steps":
        n, hr, tr = int(params["n_steps"]), params["riser"], params["tread"]
        for k in range(n):
            z1 = zw - k * tr
            meshes.append(_box(bx - _BIG, bx + _BIG, -1.0, (k + 1) * hr, z1 - _BIG, z1))
        meshes.append(_vertical_strip((bx - _BIG, zw - n * tr), (bx + _BIG, zw - n * tr)))
    elif kind == "curved":
        r, seg = params["radius"], 48
        phi = np.linspace(0.0, math.pi / 2, seg + 1)
        zs, ys = zw - r * np.sin(phi), r - r * np.cos(phi)
        zs, ys = np.append(zs, zs[-1]), np.append(ys, _TALL)   # then straight up
        x0, x1 = bx - _BIG, bx + _BIG
        V = np.concatenate([np.stack([np.full_like(zs, x0), ys, zs], 1),
                            np.stack([np.full_like(zs, x1), ys, zs], 1)])
        m = len(zs)
        F = [[i, m + i, m + i + 1] for i in range(m - 1)] + [[i, m + i + 1, i + 1] for i in range(m - 1)]
        meshes.append((V, np.array(F, np.int64)))
    else:
        raise ValueError(f"unknown background kind {kind!r}; one of {', '.join(BG_KINDS)}")
    return [meshes[0]] + _rotate_about(meshes[1:], np.array([bx, 0.0, bz]), math.radians(params.get("yaw", 0.0)))


def sample_background_params(kind: str, split: str, rng: np.random.Generator, obj_radius: float) -> dict:
    """Random template parameters of ``kind`` from the ``split``'s range (module doc).

    obj_radius: horizontal radius of the object's footprint [world]; the wall is
    placed ``clearance`` in [0.02, 1.5] world units behind it (log-uniform, so
    contact shadows and far walls both occur)."""
    test = split == "test"
    clearance = float(np.exp(rng.uniform(np.log(0.02), np.log(1.5))))
    p = {"clearance": clearance, "gap": obj_radius + clearance}
    if kind == "ground":
        return {}
    if kind == "wall":
        mag = rng.uniform(0.0, 12.0) if test else rng.uniform(12.0, 40.0)
        p["yaw"] = float(mag * rng.choice([-1, 1]))
    elif kind == "corner":
        lo, hi = (45.0, 70.0) if test else (20.0, 45.0)
        p.update(angle_left=float(rng.uniform(lo, hi)), angle_right=float(rng.uniform(lo, hi)),
                 offset=float(rng.uniform(-0.6, 0.6)), yaw=0.0)
        # push the corner edge back until both walls are `clearance` from the
        # footprint circle: distance of B to the left wall = gap cos(al) - offset sin(al),
        # to the right wall = gap cos(ar) + offset sin(ar)
        al, ar, off, need = (math.radians(p["angle_left"]), math.radians(p["angle_right"]),
                             p["offset"], obj_radius + clearance)
        p["gap"] = max((need + off * math.sin(al)) / math.cos(al), (need - off * math.sin(ar)) / math.cos(ar))
    elif kind == "two_corners":
        p.update(half_width_left=float(obj_radius + rng.uniform(0.1, 2.0)),
                 half_width_right=float(obj_radius + rng.uniform(0.1, 2.0)),
                 yaw=float(rng.uniform(-20.0, 20.0)))
    elif kind == "steps":
        p.update(n_steps=int(rng.integers(1, 4)),
                 riser=float(rng.uniform(0.15, 0.30) if test else rng.uniform(0.05, 0.15)),
                 tread=float(rng.uniform(0.15, 0.6)), yaw=float(rng.uniform(-20.0, 20.0)))
    elif kind == "curved":
        p.update(radius=float(rng.uniform(0.2, 1.2)), yaw=float(rng.uniform(-20.0, 20.0)))
    else:
        raise ValueError(f"unknown background kind {kind!r}")
    return p


# -- scene description ----------------------------------------------------------

@dataclasses.dataclass
class SceneSpec:
    """Everything needed to cast rays for one sample (plain data, JSON-able via to_json)."""

    camera: Camera
    obj_id: str
    obj_V: np.ndarray          # (n, 3) world, already placed
    obj_F: np.ndarray
    bg_kind: str
    bg_params: dict
    base: np.ndarray           # (3,) object's base point B (world)

    @property
    def obj_center(self) -> np.ndarray:
        lo, hi = self.obj_V.min(0), self.obj_V.max(0)
        return (lo + hi) / 2

    @property
    def obj_radius(self) -> float:
        """Bounding-sphere radius around obj_center [world]."""
        return float(np.linalg.norm(self.obj_V - self.obj_center, axis=1).max())

    def to_json(self) -> dict:
        return {"camera": self.camera.to_dict(), "object": self.obj_id, "background": self.bg_kind,
                "background_params": self.bg_params, "base": [float(x) for x in self.base],
                "object_height": float(self.obj_V[:, 1].max())}


@dataclasses.dataclass
class DiskLight:
    """A one-sided disk area light: centre C [world], radius r [world], unit normal n
    (the emitting side, pointing toward the object's centre)."""

    center: np.ndarray
    radius: float
    normal: np.ndarray
    elevation_deg: float = float("nan")   # seen from the object's centre
    azimuth_deg: float = float("nan")     # 0 = toward the camera (+Z), 90 = +X
    distance: float = float("nan")        # from the object's centre

    def basis(self):
        n = self.normal / np.linalg.norm(self.normal)
        e1 = np.cross([0.0, 1.0, 0.0], n)
        if np.linalg.norm(e1) < 1e-9:
            e1 = np.array([1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        return e1, np.cross(n, e1)

    def uvhs(self, camera: Camera) -> np.ndarray:
        """(u, v, h, s) of the centre through the camera: s = +1 if depth > 0 else -1."""
        uvh, D = camera.project(self.center)
        return np.array([uvh[0], uvh[1], uvh[2], 1.0 if D > 0 else -1.0])

    def to_json(self) -> dict:
        return {"center": [float(x) for x in self.center], "radius": float(self.radius),
                "normal": [float(x) for x in self.normal], "elevation_deg": float(self.elevation_deg),
                "azimuth_deg": float(self.azimuth_deg), "distance": float(self.distance),
                "relative_radius": float(self.radius / self.distance)}


def make_camera(res: int, rng: np.random.Generator) -> Camera:
    """Our camera at res x res with a random hfov in [35, 65] deg; the horizon is set later."""
    return Camera(res, res, hfov=float(rng.uniform(35.0, 65.0)), horizon=0.0, cam_height=1.0)


def place_object(camera: Camera, V: np.ndarray, rng: np.random.Generator, tries: int = 50):
    """Choose depth, X and the horizon so the object fits in the image with a margin.

    The object's image height is drawn in [0.25, 0.7] of the image, its foot row in
    [0.6, 0.93] of the image height and its centre column in [0.3, 0.7] of the
    width. Returns ``(camera_with_horizon, placed_V, base)`` or None when no try fits.
    """
    W, H, f = camera.width, camera.height, camera.focal
    ht = float(V[:, 1].max())
    margin = 3
    for _ in range(tries):
        frac = rng.uniform(0.25, 0.7)
        D = f * ht / (frac * H)
        D = max(D, 1.5 + float(np.abs(V[:, [0, 2]]).max()))
        x = (rng.uniform(0.3, 0.7) * W - W / 2) * D / f
        v_foot = rng.uniform(0.6, 0.93) * H
        cam = dataclasses.replace(camera, horizon=float(v_foot - f * camera.cam_height / D))
        P = V + np.array([x, 0.0, -D])
        uvh, depth = cam.project(P)
        if (depth > 0.2).all() and uvh[:, 0].min() > margin and uvh[:, 0].max() < W - margin \
                and uvh[:, 1].min() > margin and uvh[:, 1].max() < H - margin:
            return cam, P, np.array([x, 0.0, -D])
    return None


def sample_light(spec: SceneSpec, rng: np.random.Generator, elevation_range=(5.0, 80.0),
                 rel_radius_range=(0.015, 0.45), distance_range=(1.5, 6.0)) -> DiskLight:
    """A random disk light around the object's centre (not yet checked against walls).

    Elevation uniform in degrees, azimuth uniform, distance uniform in
    ``distance_range`` (but at least 1.2 bounding radii + the disk radius away from
    the object's centre), relative radius r / distance log-uniform in
    ``rel_radius_range`` (0.015 = nearly hard, 0.45 = very soft).
    """
    c = spec.obj_center
    el = math.radians(rng.uniform(*elevation_range))
    az = math.radians(rng.uniform(0.0, 360.0))
    rel = float(np.exp(rng.uniform(np.log(rel_radius_range[0]), np.log(rel_radius_range[1]))))
    dist = float(rng.uniform(*distance_range))
    dist = max(dist, 1.2 * spec.obj_radius / max(1e-6, 1.0 - rel))
    d = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    C = c + dist * d
    return DiskLight(center=C, radius=rel * dist, normal=-d, elevation_deg=math.degrees(el),
                     azimuth_deg=math.degrees(az) % 360.0, distance=dist)
