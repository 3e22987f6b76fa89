"""Foreground objects for the ground-truth scenes.

Two sources:

* the ~1000 random meshes of ``pybullet_data/random_urdfs/NNN/NNN.obj`` (ids
  ``urdf:NNN``), randomly rotated, stretched and scaled, standing on the ground;
* procedural shapes (ids ``proc:box``, ``proc:cylinder``, ``proc:capsule``,
  ``proc:figure``) built with trimesh.

World units: the camera stands ``cam_height`` (1.0 by default) above the ground,
so object sizes are in camera heights. Meshes are returned y-up, resting on the
ground ``Y = 0`` (min Y = 0), centred on ``X = Z = 0`` of their base; the scene
moves them into place.

Split rule (documented in docs/ground-truth.md): an object id goes to **test**
when ``sha256(id) mod 5 == 0`` for urdf meshes (about 20 %), and ``proc:figure``
is test-only while the other procedural kinds are train-only, so test objects are
never seen in training.
"""
from __future__ import annotations

import functools
import glob
import hashlib
import os

import numpy as np

PROCEDURAL_TRAIN = ("proc:box", "proc:cylinder", "proc:capsule")
PROCEDURAL_TEST = ("proc:figure",)


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
    if obj_id in PROCEDURAL_TEST:
        return "test"
    if obj_id in PROCEDURAL_TRAIN:
        return "train"
    digest = int(hashlib.sha256(obj_id.encode()).hexdigest(), 16)
    return "test" if digest % 5 == 0 else "train"


def object_ids(split: str) -> list[str]:
    """Every object id belonging to ``split`` ('train' or 'test')."""
    ids = list(urdf_object_ids()) + list(PROCEDURAL_TRAIN) + list(PROCEDURAL_TEST)
    return [i for i in ids if object_split(i) == split]


def choose_object(split: str, rng: np.random.Generator, p_procedural: float = 0.2) -> str:
    """Draw an object id of ``split``; procedural shapes with probability p_procedural."""
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
    else:
        raise ValueError(f"unknown procedural object {kind!r}")
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


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
