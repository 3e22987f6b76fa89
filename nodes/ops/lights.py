"""Lights: point, directional and disk area lights, in 3D and in pixel-height space.

World is y-up, the ground is ``Y = 0``, the camera centre is ``O' = (0, H_cam, 0)``
looking down ``-Z`` (see ``camera.py``). Positions and distances are in world units
(the camera's ``cam_height`` sets the scale), angles in the public API in degrees.

A light is a frozen ``Light`` value described in 3D. The shadow tracers work in
pixel-height space, so a light is handed to them as *light points*
``(u, v, h, s)``: the image point ``(u, v)`` [px] and pixel height ``h`` [px] of the
light (its homogeneous projection through the camera), and ``s = +1`` when the
tracer marches from a receiver toward that image point, ``s = -1`` when the light is
behind the camera plane and the segment receiver->light leaves the image *away*
from the projected point (the projection of a segment that crosses the camera
plane goes through infinity).

Artist controls (``from_controls``): azimuth and elevation of the light seen from a
target point (usually the object's foot), distance (``inf`` = directional) and a
softness (disk radius in world units, or angular radius in degrees for a
directional "sun" light). Azimuth 0 puts the light on the camera's side of the
target (+Z: the shadow falls away from the viewer, onto a back wall), 90 to the
right (+X), 180 behind the target (the shadow falls toward the viewer).

Lights at or below the horizon. A light whose elevation, seen from its target, is
at most 0 cannot light the ground from above; such input is *clamped* to
``MIN_ELEVATION_DEG`` with a ``UserWarning`` and ``Light.clamped = True`` rather
than returning an all-shadow image, because an artist dragging the sun down wants
a long shadow, not a sudden black frame. Area-light samples that fall below the
ground (a huge disk near the floor) are lifted to just above it the same way.
Lights exactly in the camera plane (vanishing point at infinity, e.g. the sun
straight overhead) are nudged off it by a relative ``1e-4`` so that the projection
stays finite; the shadow error this causes is far below a pixel.
"""
from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from .camera import Camera

#: lights are never lower than this above the horizon seen from their target [deg]
MIN_ELEVATION_DEG = 1.0
#: relative distance from the camera plane below which a light is nudged off it
_PLANE_EPS = 1e-4
#: golden angle [rad] for the sunflower (Vogel) disk pattern
_GOLDEN = math.pi * (3.0 - math.sqrt(5.0))

KINDS = ("point", "disk", "directional")
FACINGS = ("target", "down")


@dataclasses.dataclass(frozen=True)
class Light:
    """A light in 3D.

    kind: ``"point"``, ``"disk"`` (area light of ``radius`` world units centred on
        ``position``) or ``"directional"`` (at infinity toward ``direction``; with
        ``angular_radius`` > 0 it is an area light such as the sun's disk).
    position: (X, Y, Z) world units, for point and disk lights; None otherwise.
    direction: unit vector *toward* the light, for directional lights; None otherwise.
    radius: disk radius, world units (0 for point and directional lights).
    angular_radius: angular radius of a directional light, radians.
    normal: unit normal of the disk, pointing from the light toward the scene.
    target: the point the controls were measured from (world), or None.
    controls: the artist controls the light came from, as ``(name, value)`` pairs.
    clamped: True when the input was below the horizon and was raised (see module doc).
    """

    kind: str
    position: tuple[float, float, float] | None = None
    direction: tuple[float, float, float] | None = None
    radius: float = 0.0
    angular_radius: float = 0.0
    normal: tuple[float, float, float] = (0.0, -1.0, 0.0)
    target: tuple[float, float, float] | None = None
    controls: tuple[tuple[str, float | str], ...] = ()
    clamped: bool = False

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"light kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "directional":
            if self.direction is None:
                raise ValueError("a directional light needs a direction")
        elif self.position is None:
            raise ValueError(f"a {self.kind} light needs a position")
        for name in ("radius", "angular_radius"):
            val = getattr(self, name)
            if not (math.isfinite(val) and val >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {val}")

    @property
    def is_area(self) -> bool:
        """True when the light has an extent (softness > 0)."""
        return (self.kind == "disk" and self.radius > 0.0) or (
            self.kind == "directional" and self.angular_radius > 0.0)


# -- constructors -------------------------------------------------------------

def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    n = float(np.linalg.norm(v))
    if not (math.isfinite(n) and n > 0.0):
        raise ValueError(f"direction must be a finite non-zero vector, got {v.tolist()}")
    return v / n


def _tup(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)


def point_light(position) -> Light:
    """A point light at ``position`` (world units). Below-ground positions are lifted."""
    p, clamped = _lift_above_ground(np.asarray(position, dtype=np.float64))
    return Light("point", position=_tup(p), clamped=clamped)


def disk_light(position, radius: float, facing: str = "target", target=(0.0, 0.0, 0.0)) -> Light:
    """A disk area light of ``radius`` world units centred on ``position``.

    facing: ``"target"`` (the disk faces ``target``, like a softbox aimed at the
    object) or ``"down"`` (a horizontal disk, like a ceiling lamp).
    """
    if facing not in FACINGS:
        raise ValueError(f"facing must be one of {', '.join(FACINGS)}, got {facing!r}")
    p, clamped = _lift_above_ground(np.asarray(position, dtype=np.float64))
    t = np.asarray(target, dtype=np.float64)
    if facing == "down" or np.linalg.norm(t - p) == 0.0:
        n = np.array([0.0, -1.0, 0.0])
    else:
        n = _unit(t - p)
    return Light("disk", position=_tup(p), radius=float(radius), normal=_tup(n),
                 target=_tup(t), clamped=clamped)


def directional_light(direction, angular_radius_deg: float = 0.0) -> Light:
    """A light at infinity toward ``direction`` (need not be unit), optionally with an
    angular radius [deg] (a sun-like area light). Directions below the horizon are
    raised to ``MIN_ELEVATION_DEG``."""
    d, clamped = _raise_direction(_unit(direction))
    return Light("directional", direction=_tup(d), angular_radius=math.radians(angular_radius_deg),
                 normal=_tup(-d), clamped=clamped)


def _controls_direction(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, bool]:
    clamped = False
    if not math.isfinite(elevation_deg) or elevation_deg < MIN_ELEVATION_DEG:
        warnings.warn(f"light elevation {elevation_deg} deg is at or below the horizon; "
                      f"clamped to {MIN_ELEVATION_DEG} deg", UserWarning, stacklevel=3)
        elevation_deg = MIN_ELEVATION_DEG
        clamped = True
    elevation_deg = min(elevation_deg, 90.0)
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)]), clamped


def from_controls(target, azimuth_deg: float, elevation_deg: float, distance: float = math.inf,
                  kind: str | None = None, radius: float = 0.0, angular_radius_deg: float = 0.0,
                  facing: str = "target") -> Light:
    """A light placed by artist controls around ``target`` (world point, usually the
    object's foot on the ground).

    azimuth_deg: around the vertical axis; 0 = toward the camera (+Z), 90 = right (+X).
    elevation_deg: above the horizontal plane through the target, degrees.
    distance: from the target, world units; ``inf`` gives a directional light.
    kind: ``"point"``, ``"disk"`` or ``"directional"``; by default directional when the
        distance is infinite, a disk when ``radius`` > 0, else a point.
    radius: disk radius, world units. angular_radius_deg: sun-disk radius, degrees.
    """
    d, clamped = _controls_direction(azimuth_deg, elevation_deg)
    if kind is None:
        kind = "directional" if math.isinf(distance) else ("disk" if radius > 0.0 else "point")
    if kind != "directional" and not (math.isfinite(distance) and distance > 0.0):
        raise ValueError(f"a {kind} light needs a finite distance > 0, got {distance}")
    t = np.asarray(target, dtype=np.float64)
    controls = (("azimuth", float(azimuth_deg)), ("elevation", float(elevation_deg)),
                ("distance", float(distance)), ("radius", float(radius)),
                ("angular_radius", float(angular_radius_deg)))
    if kind == "directional":
        light = directional_light(d, angular_radius_deg)
    elif kind == "point":
        light = point_light(t + distance * d)
    elif kind == "disk":
        light = disk_light(t + distance * d, radius, facing, t)
    else:
        raise ValueError(f"light kind must be one of {', '.join(KINDS)}, got {kind!r}")
    return dataclasses.replace(light, target=_tup(t), controls=controls,
                               clamped=light.clamped or clamped)


def from_shadow_tip(camera: Camera, tip_uv, top_uvh, distance: float = math.inf,
                    kind: str | None = None, radius: float = 0.0, angular_radius_deg: float = 0.0,
                    facing: str = "target") -> Light:
    """The light that casts the shadow of an object's top point onto a given ground pixel.

    tip_uv: (u, v) [px] of the shadow tip on the ground (below the horizon).
    top_uvh: (u, v, h) [px] of the object's top point and its pixel height (h > 0).
    The light lies on the 3D ray from the tip through the top; ``distance`` is
    measured from the top point along it (``inf``: directional).
    Raises ValueError when either point cannot be reconstructed.
    """
    P, az, el = _tip_top(camera, tip_uv, top_uvh)
    light = from_controls(P, az, el, distance, kind, radius, angular_radius_deg, facing)
    return dataclasses.replace(light, controls=light.controls + (
        ("tip_u", float(tip_uv[0])), ("tip_v", float(tip_uv[1])),
        ("top_u", float(top_uvh[0])), ("top_v", float(top_uvh[1])), ("top_h", float(top_uvh[2]))))


def tip_angles(camera: Camera, tip_uv, top_uvh) -> tuple[float, float]:
    """(azimuth, elevation) [deg] of the light ``from_shadow_tip`` makes: its direction
    seen from the object's top (``from_controls``' angles around the top). Raises
    ValueError as ``from_shadow_tip`` does."""
    return _tip_top(camera, tip_uv, top_uvh)[1:]


def _tip_top(camera: Camera, tip_uv, top_uvh):
    """The top's 3D point and the (azimuth, elevation) [deg] of the ray from the tip through it."""
    (P, okp) = camera.back_project(top_uvh[0], top_uvh[1], top_uvh[2])
    (T, okt) = camera.back_project(tip_uv[0], tip_uv[1], 0.0)
    if not okt:
        raise ValueError(f"shadow tip {tuple(tip_uv)} is at or above the horizon ({camera.horizon})")
    if not okp or top_uvh[2] <= 0.0:
        raise ValueError(f"object top {tuple(top_uvh)} needs h > 0 and its foot below the horizon")
    d = _unit(P - T)
    horiz = math.hypot(d[0], d[2])
    return P, math.degrees(math.atan2(d[0], d[2])), math.degrees(math.atan2(d[1], horiz))


def _lift_above_ground(p: np.ndarray, floor: float = 1e-3) -> tuple[np.ndarray, bool]:
    """Raise points with Y below ``floor`` world units to it; returns (points, any raised)."""
    low = ~(p[..., 1] >= floor)
    if np.any(low):
        p = p.copy()
        p[..., 1] = np.where(low, floor, p[..., 1])
        warnings.warn("light position below the ground raised to just above it", UserWarning, stacklevel=3)
    return p, bool(np.any(low))


def _raise_direction(d: np.ndarray) -> tuple[np.ndarray, bool]:
    """Raise unit directions (..., 3) whose elevation is below MIN_ELEVATION_DEG to it,
    keeping their azimuth. Returns (directions, any raised)."""
    smin = math.sin(math.radians(MIN_ELEVATION_DEG))
    low = d[..., 1] < smin
    if not np.any(low):
        return d, False
    d = d.copy()
    horiz = np.hypot(d[..., 0], d[..., 2])
    # a purely vertical-downward direction has no azimuth: pick toward the camera
    hx = np.where(horiz > 0, d[..., 0] / np.where(horiz > 0, horiz, 1.0), 0.0)
    hz = np.where(horiz > 0, d[..., 2] / np.where(horiz > 0, horiz, 1.0), 1.0)
    c = math.cos(math.radians(MIN_ELEVATION_DEG))
    d[..., 0] = np.where(low, c * hx, d[..., 0])
    d[..., 1] = np.where(low, smin, d[..., 1])
    d[..., 2] = np.where(low, c * hz, d[..., 2])
    warnings.warn(f"light direction below the horizon raised to {MIN_ELEVATION_DEG} deg",
                  UserWarning, stacklevel=3)
    return d, True


# -- 3D sampling ----------------------------------------------------------------

def _disk_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the disk's plane: e1 horizontal (left/right as seen
    from the scene), e2 = normal x e1 (up/down). For a horizontal disk e1 = +X, e2 = +Z."""
    n = _unit(normal)
    e1 = np.cross(np.array([0.0, 1.0, 0.0]), n)
    if np.linalg.norm(e1) < 1e-9:
        e1 = np.array([1.0, 0.0, 0.0])
    e1 = _unit(e1)
    e2 = _unit(np.cross(n, e1))
    return e1, e2


def unit_disk_samples(n: int, seed: int = 0) -> np.ndarray:
    """``n`` stratified points in the unit disk, (n, 2): the sunflower (Vogel) pattern,
    radius sqrt((i + 0.5) / n), angle i * golden angle, rotated by a seed-derived
    angle. Deterministic; each point covers an equal area, so the mean is close to
    the centre and the hard-shadow average converges like a stratified estimate."""
    if n < 1:
        raise ValueError(f"need at least one sample, got {n}")
    rot = (np.random.default_rng(seed).random() * 2.0 * math.pi) if seed else 0.0
    i = np.arange(n, dtype=np.float64)
    r = np.sqrt((i + 0.5) / n)
    a = i * _GOLDEN + rot
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=-1)


def sample_points_3d(light: Light, n: int, seed: int = 0) -> np.ndarray:
    """``n`` stratified samples of the light in 3D, (n, 3).

    Point/disk lights: positions on the disk [world units]. Directional lights:
    unit directions toward the light, spread over the cone of ``angular_radius``
    (a disk of radius tan(angular_radius) at unit distance, normalised).
    Samples below the ground / horizon are lifted (module doc).
    """
    disk = unit_disk_samples(n, seed)
    return _disk_points(light, disk)


def extreme_points_3d(light: Light) -> np.ndarray:
    """The 4 extreme points of the light's disk, (4, 3): +e1, -e1, +e2, -e2 (right,
    left, top, bottom as seen from the scene). The paper's sparse hard shadows are
    cast from these; for a point light all four are its centre."""
    return _disk_points(light, np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]))


def _disk_points(light: Light, disk: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the light itself already warned when it was built
        if light.kind == "directional":
            d = np.asarray(light.direction, dtype=np.float64)
            if light.angular_radius <= 0.0:
                return np.repeat(d[None], len(disk), axis=0)
            e1, e2 = _disk_basis(-d)
            t = math.tan(min(light.angular_radius, math.radians(89.0)))
            pts = d[None] + t * (disk[:, :1] * e1[None] + disk[:, 1:] * e2[None])
            pts = pts / np.linalg.norm(pts, axis=-1, keepdims=True)
            return _raise_direction(pts)[0]
        c = np.asarray(light.position, dtype=np.float64)
        if light.kind == "point" or light.radius <= 0.0:
            return np.repeat(c[None], len(disk), axis=0)
        e1, e2 = _disk_basis(np.asarray(light.normal))
        pts = c[None] + light.radius * (disk[:, :1] * e1[None] + disk[:, 1:] * e2[None])
        return _lift_above_ground(pts)[0]


# -- pixel-height space ---------------------------------------------------------

def project_homogeneous(camera: Camera, q: np.ndarray, w: float) -> np.ndarray:
    """(u, v, h, s) [px, px, px, sign] of homogeneous world points, (..., 4) float64.

    q: (..., 3) a point P (w = 1) or a direction d toward a light at infinity (w = 0).
    For a point, ``D = -Z``; for a direction ``D = -d_z``. Then
    ``u = W/2 + f X'/D``, ``v = horizon - f (Y - w H_cam)/D``, ``h = f Y/D`` with
    ``X' = X`` and ``s = sign(D)``. For a direction this gives ``v + h = horizon``:
    a directional light's image point lies on the horizon. Points with |D| below
    1e-4 of their distance from the camera are nudged off the camera plane.
    """
    q = np.asarray(q, dtype=np.float64)
    rel = q - w * np.array([0.0, camera.cam_height, 0.0])  # vector from the camera centre
    D = -rel[..., 2]
    scale = np.linalg.norm(rel, axis=-1)
    eps = _PLANE_EPS * np.maximum(scale, 1e-12)
    D = np.where(np.abs(D) < eps, np.where(D < 0, -eps, eps), D)
    f = camera.focal
    u = camera.width / 2.0 + f * rel[..., 0] / D
    v = camera.horizon - f * rel[..., 1] / D
    h = f * q[..., 1] / D
    return np.stack([u, v, h, np.sign(D)], axis=-1)


def _project(light: Light, camera: Camera, pts: np.ndarray) -> np.ndarray:
    w = 0.0 if light.kind == "directional" else 1.0
    return project_homogeneous(camera, pts, w).astype(np.float32)


def light_point(light: Light, camera: Camera) -> np.ndarray:
    """The light's centre in pixel-height space: float32 (4,) ``(u, v, h, s)`` [px, px, px, +-1]."""
    c = np.asarray(light.direction if light.kind == "directional" else light.position, dtype=np.float64)
    return _project(light, camera, c[None])[0]


def disk_samples(light: Light, camera: Camera, n: int, seed: int = 0) -> np.ndarray:
    """``n`` stratified samples of the light in pixel-height space, float32 (n, 4)
    ``(u, v, h, s)``; deterministic for a given seed (sunflower pattern on the disk)."""
    return _project(light, camera, sample_points_3d(light, n, seed))


def disk_extremes(light: Light, camera: Camera) -> np.ndarray:
    """The 4 extreme points of the light's disk in pixel-height space, float32 (4, 4)
    (right, left, top, bottom; the paper's sparse hard shadows)."""
    return _project(light, camera, extreme_points_3d(light))


def foot_of_mask(mask: np.ndarray) -> tuple[float, float]:
    """(u, v) [px] of an object's foot: the centre of the columns that reach the
    mask's lowest row, at the bottom edge of that row (where the object meets the
    ground). Raises ValueError for an empty mask."""
    m = np.asarray(mask) > 0.5
    if not m.any():
        raise ValueError("empty mask: cannot find the object's foot")
    rows = np.nonzero(m.any(axis=1))[0]
    bottom = rows[-1]
    cols = np.nonzero(m[bottom])[0]
    return float(cols.mean() + 0.5), float(bottom + 1.0)
