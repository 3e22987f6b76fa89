"""Foreground objects for the ground-truth scenes.

Two sources:

* the ~1000 random meshes of ``pybullet_data/random_urdfs/NNN/NNN.obj`` (ids
  ``urdf:NNN``), randomly rotated, stretched and scaled, standing on the ground;
* procedural shapes (ids ``proc:box``, ``proc:cylinder``, ``proc:capsule``,
  ``proc:figure``) built with trimesh;
* thin open objects (``proc:table``, ``proc:chair``, ``proc:frame``, ``proc:arch``,
  ``proc:bench``): thin legs and bars with large holes, whose shadows are mostly
  gaps. Object mix 2 (``choose_object(..., mix=2)``) draws them a quarter of the
  time; mix 1 (the generator before they existed) never does.

World units: the camera stands ``cam_height`` (1.0 by default) above the ground,
so object sizes are in camera heights. Meshes are returned y-up, resting on the
ground ``Y = 0`` (min Y = 0), centred on ``X = Z = 0`` of their base; the scene
moves them into place.

Split rule (documented in docs/ground-truth.md): an object id goes to **test**
when ``sha256(id) mod 5 == 0`` for urdf meshes (about 20 %), and ``proc:figure``
is test-only while the other procedural kinds are train-only, so test objects are
never seen in training. Thin open objects: ``proc:table``, ``proc:chair`` and
``proc:frame`` are train-only, ``proc:arch`` and ``proc:bench`` test-only.
"""
from __future__ import annotations

import functools
import glob
import hashlib
import os

import numpy as np

PROCEDURAL_TRAIN = ("proc:box", "proc:cylinder", "proc:capsule")
PROCEDURAL_TEST = ("proc:figure",)
THIN_TRAIN = ("proc:table", "proc:chair", "proc:frame")
THIN_TEST = ("proc:arch", "proc:bench")


@functools.lru_cache(maxsize=1)
def urdf_object_ids() -> tuple[str, ...]:
    """Ids ``urdf:NNN`` of every random_urdfs mesh found (empty without pybullet)."""
    try:
        import pybullet_data
    except ImportError:
        return ()
    files = sorted(glob.glob(os.path.join(pybullet_data.getDataPath(), "random_urdfs", "*", "*.obj")))
    return tuple("urdf:" + os.path.splitext(os.path.basename(f))[0] for f in files)


def object_split(obj_id: str) -> str:
    """'train' or 'test' for an object id (deterministic, see module doc)."""
    if obj_id in PROCEDURAL_TEST or obj_id in THIN_TEST:
        return "test"
    if obj_id in PROCEDURAL_TRAIN or obj_id in THIN_TRAIN:
        return "train"
    digest = int(hashlib.sha256(obj_id.encode()).hexdigest(), 16)
    return "test" if digest % 5 == 0 else "train"


def object_ids(split: str) -> list[str]:
    """Every object id belonging to ``split`` ('train' or 'test')."""
    ids = list(urdf_object_ids()) + list(PROCEDURAL_TRAIN) + list(PROCEDURAL_TEST) + list(THIN_TRAIN) \
        + list(THIN_TEST)
    return [i for i in ids if object_split(i) == split]


def choose_object(split: str, rng: np.random.Generator, p_procedural: float = 0.2, mix: int = 1,
                  p_thin: float = 0.25) -> str:
    """Draw an object id of ``split``; procedural shapes with probability p_procedural.

    mix 2 first draws a thin open object of the split with probability ``p_thin``;
    mix 1 draws nothing extra, so its samples are exactly those generated before
    thin objects existed.
    """
    if mix >= 2 and rng.random() < p_thin:
        thin = [i for i in THIN_TRAIN + THIN_TEST if object_split(i) == split]
        return thin[rng.integers(len(thin))]
    procs = [i for i in PROCEDURAL_TRAIN + PROCEDURAL_TEST if object_split(i) == split]
    urdfs = [i for i in urdf_object_ids() if object_split(i) == split]
    if urdfs and (not procs or rng.random() >= p_procedural):
        return urdfs[rng.integers(len(urdfs))]
    return procs[rng.integers(len(procs))]


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """Uniform random 3x3 rotation (QR of a Gaussian matrix, sign-fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _procedural(kind: str, rng: np.random.Generator):
    import trimesh
    c = trimesh.creation
    if kind == "proc:box":
        m = c.box(extents=rng.uniform([0.3, 0.4, 0.3], [1.0, 1.6, 1.0]))
    elif kind == "proc:cylinder":
        m = c.cylinder(radius=rng.uniform(0.15, 0.5), height=rng.uniform(0.4, 1.8), sections=32)
        m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))  # z-up -> y-up
    elif kind == "proc:capsule":
        m = c.capsule(radius=rng.uniform(0.12, 0.4), height=rng.uniform(0.3, 1.2), count=[24, 24])
        m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    elif kind == "proc:figure":
        # A crude standing figure: two legs, torso, head (a stack of capsules + sphere),
        # so the shadow has thin gaps between the legs like the paper's human cutouts.
        parts = []
        leg_h, leg_r = rng.uniform(0.5, 0.8), rng.uniform(0.05, 0.09)
        gap = rng.uniform(0.06, 0.15)
        for sx in (-1, 1):
            leg = c.capsule(radius=leg_r, height=leg_h, count=[12, 12])
            leg.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
            leg.apply_translation([sx * (gap / 2 + leg_r), leg_h / 2 + leg_r, 0])
            parts.append(leg)
        torso_h, torso_r = rng.uniform(0.4, 0.6), rng.uniform(0.14, 0.22)
        torso = c.capsule(radius=torso_r, height=torso_h, count=[16, 16])
        torso.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
        torso.apply_translation([0, leg_h + 2 * leg_r + torso_h / 2 + torso_r * 0.5, 0])
        parts.append(torso)
        head_r = rng.uniform(0.09, 0.14)
        head = c.icosphere(subdivisions=2, radius=head_r)
        head.apply_translation([0, leg_h + 2 * leg_r + torso_h + torso_r * 1.5 + head_r, 0])
        parts.append(head)
        m = trimesh.util.concatenate(parts)
    elif kind in THIN_TRAIN + THIN_TEST:
        m = trimesh.util.concatenate(_thin_parts(kind, rng))
    else:
        raise ValueError(f"unknown procedural object {kind!r}")
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _bar(x0, x1, y0, y1, z0, z1):
    import trimesh
    return trimesh.creation.box(bounds=[[x0, y0, z0], [x1, y1, z1]])


def _thin_parts(kind: str, rng: np.random.Generator) -> list:
    """Boxes of a thin open object, y up, resting on Y = 0 [world units = camera heights]."""
    u = rng.uniform
    parts = []
    if kind in ("proc:table", "proc:chair", "proc:bench"):
        if kind == "proc:table":
            w, d, h, leg, top = u(0.6, 1.4), u(0.4, 0.9), u(0.45, 0.9), u(0.025, 0.06), u(0.02, 0.06)
        elif kind == "proc:chair":
            w, d, h, leg, top = u(0.35, 0.55), u(0.35, 0.55), u(0.38, 0.5), u(0.02, 0.045), u(0.02, 0.05)
        else:
            w, d, h, leg, top = u(0.9, 1.8), u(0.25, 0.45), u(0.35, 0.5), u(0.04, 0.1), u(0.03, 0.07)
        parts.append(_bar(-w / 2, w / 2, h - top, h, -d / 2, d / 2))
        for sx in (-1, 1):
            for sz in (-1, 1):
                x, z = sx * (w / 2 - leg), sz * (d / 2 - leg)
                parts.append(_bar(x - leg / 2, x + leg / 2, 0, h - top, z - leg / 2, z + leg / 2))
        if kind == "proc:chair":        # backrest: two posts and 2-3 rails
            hb = u(0.35, 0.6)
            for sx in (-1, 1):
                x = sx * (w / 2 - leg)
                parts.append(_bar(x - leg / 2, x + leg / 2, h, h + hb, -d / 2, -d / 2 + leg))
            for k in range(int(rng.integers(2, 4))):
                y = h + hb * (0.45 + 0.5 * k / 2)
                parts.append(_bar(-w / 2 + leg / 2, w / 2 - leg / 2, y - leg, y, -d / 2, -d / 2 + leg))
        if kind == "proc:table" and rng.random() < 0.5:   # a stretcher between the legs
            y = u(0.1, 0.3) * h
            parts.append(_bar(-w / 2 + leg, w / 2 - leg, y, y + leg, -leg / 2, leg / 2))
    elif kind == "proc:frame":
        # an upright rectangular frame (door frame, easel, picture frame on feet)
        w, h, t, dep = u(0.4, 1.2), u(0.6, 1.6), u(0.025, 0.08), u(0.03, 0.12)
        parts += [_bar(-w / 2, -w / 2 + t, 0, h, -dep / 2, dep / 2), _bar(w / 2 - t, w / 2, 0, h, -dep / 2, dep / 2),
                  _bar(-w / 2, w / 2, h - t, h, -dep / 2, dep / 2)]
        if rng.random() < 0.6:
            y = u(0.05, 0.5) * h
            parts.append(_bar(-w / 2, w / 2, y, y + t, -dep / 2, dep / 2))
        if rng.random() < 0.5:          # feet across the frame so it could stand
            f = u(0.15, 0.35)
            for sx in (-1, 1):
                x = sx * (w / 2 - t / 2)
                parts.append(_bar(x - t / 2, x + t / 2, 0, t, -f, f))
    elif kind == "proc:arch":
        # two pillars and a semicircular top made of short boxes
        span, hp, t, dep = u(0.4, 1.0), u(0.4, 1.0), u(0.06, 0.18), u(0.08, 0.3)
        for sx in (-1, 1):
            x = sx * (span / 2 + t / 2)
            parts.append(_bar(x - t / 2, x + t / 2, 0, hp, -dep / 2, dep / 2))
        r = span / 2 + t / 2
        n = 12
        for k in range(n):
            a0, a1 = np.pi * k / n, np.pi * (k + 1) / n
            am = (a0 + a1) / 2
            seg = _bar(-t / 2, t / 2, -r * (a1 - a0) / 2 - 0.005, r * (a1 - a0) / 2 + 0.005, -dep / 2, dep / 2)
            import trimesh
            seg.apply_transform(trimesh.transformations.rotation_matrix(am, [0, 0, 1]))
            seg.apply_translation([r * np.cos(am), hp + r * np.sin(am), 0])
            parts.append(seg)
    else:
        raise ValueError(f"unknown thin object {kind!r}")
    return parts


def read_urdf_mesh(obj_id: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) float64 (z up, as in the file) and faces (F, 3) int64 of the
    pybullet ``random_urdfs`` mesh ``"urdf:NUM"``; ``ValueError`` for a broken one."""
    import pybullet_data
    import trimesh
    num = obj_id.split(":", 1)[1]
    path = os.path.join(pybullet_data.getDataPath(), "random_urdfs", num, num + ".obj")
    m = trimesh.load(path, force="mesh", process=False)
    V = np.asarray(m.vertices, np.float64)
    if not np.isfinite(V).all() or len(m.faces) == 0:
        # a few random_urdfs files are broken (168.obj is all "v nan nan nan")
        raise ValueError(f"{obj_id}: mesh has non-finite vertices or no faces")
    return V, np.asarray(m.faces, np.int64)


def load_object(obj_id: str, rng: np.random.Generator, height_range=(0.4, 1.6)):
    """Vertices (V, 3) float64 world units and faces (F, 3) int64 of a posed object.

    urdf meshes get a uniformly random 3D rotation, a random vertical stretch
    (x1-2.5, so very tall thin objects occur) and are scaled to a random height in
    ``height_range``; every object gets a random yaw. The result rests on Y = 0
    with its base bounding-box centre at X = Z = 0.
    """
    if obj_id.startswith("urdf:"):
        V, F = read_urdf_mesh(obj_id)
        V = V @ _random_rotation(rng).T
        V[:, 1] *= rng.uniform(1.0, 2.5)
    else:
        V, F = _procedural(obj_id, rng)
    V = V @ _yaw(rng.uniform(0, 2 * np.pi)).T
    lo, hi = V.min(0), V.max(0)
    target = rng.uniform(*height_range)
    if obj_id.startswith("urdf:"):
        V = V * (target / (hi[1] - lo[1]))
    lo, hi = V.min(0), V.max(0)
    V = V - np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])
    return V, F
