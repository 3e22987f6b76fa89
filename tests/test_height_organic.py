"""The ``organic`` category (smooth rounded things) of the procedural generators: the
objects are closed, non-empty, rest on the ground, and render a non-empty cutout."""
import numpy as np
import pytest

pytest.importorskip("trimesh")
pytest.importorskip("skimage")

from pixgraph_lab.datagen.categories import CATEGORIES, blob_surface, make_object  # noqa: E402


def test_blob_surface_reproduces_a_lone_sphere_and_blends_two():
    m, fs = blob_surface([[0, 0, 0]], [[1.0, 1.0, 1.0]], res=40, slots=[0])
    r = np.linalg.norm(m.vertices, axis=1)
    assert m.is_watertight
    assert abs(r.mean() - 1.0) < 0.02 and r.max() < 1.03
    assert abs(m.volume - 4 / 3 * np.pi) / (4 / 3 * np.pi) < 0.03
    # two overlapping spheres: one closed surface, bigger than either, smaller than their sum;
    # faces near each centre get that sphere's slot
    m2, fs2 = blob_surface([[-0.6, 0, 0], [0.6, 0, 0]], [[1.0] * 3, [1.0] * 3], sharp=4.0, res=48,
                           slots=[3, 5])
    assert m2.is_watertight and m2.body_count == 1
    assert 4 / 3 * np.pi < m2.volume < 2 * 4 / 3 * np.pi
    x = m2.triangles_center[:, 0]
    assert set(fs2[x < -1.0]) == {3} and set(fs2[x > 1.0]) == {5}


def test_organic_objects_build_rest_on_the_ground_and_render():
    from pixgraph_lab.height.real import (CATEGORY_P, CATEGORY_P_REAL, REAL_POSES, make_real_sample,
                                          pose_real)
    import trimesh
    assert "organic" in CATEGORIES
    assert abs(sum(CATEGORY_P.values()) - 1) < 1e-9 and abs(CATEGORY_P["organic"] - 0.2) < 1e-9
    for k, v in CATEGORY_P_REAL.items():   # the others keep their relative proportions
        assert abs(CATEGORY_P[k] - 0.8 * v) < 1e-12
    kinds = set()
    for i in range(12):
        V, F, L, names, kind = make_object("organic", np.random.default_rng([5, i]))
        kinds.add(kind)
        assert kind.startswith("organic/") and len(F) > 100
        assert V[:, 1].min() == 0.0 and np.isfinite(V).all()
        assert L.shape == (len(F),) and L.max() < len(names)
        m = trimesh.Trimesh(V, F, process=False)
        assert m.area > 0 and np.ptp(V, axis=0).min() > 0
        for pose in REAL_POSES:   # posed (rotated, scaled): still resting on the ground
            PV = pose_real(V, pose, np.random.default_rng([6, i]))
            assert abs(PV[:, 1].min()) < 1e-9 and 0.3 - 1e-9 <= PV[:, 1].max() <= 1.6 + 1e-9
    assert len(kinds) >= 4
    # a posed, rendered sample: a non-empty cutout, heights > 0 on it and 0 off it (the
    # contact itself is often hidden under a rounded body, so no visible-foot check)
    pytest.importorskip("mitsuba")
    from pixgraph_lab.datagen.raycast import select_variant
    select_variant()
    arrays, meta = make_real_sample("train", 3, seed=0, res=96, category="organic")
    assert meta["category"] == "organic" and meta["object"].startswith("organic/")
    mask, h = arrays["mask"], arrays["height"].astype(float)
    assert mask.sum() > 0.004 * 96 * 96
    assert (h[~mask] == 0).all() and (h[mask] > 0).all()
    assert (arrays["alpha"][mask] > 0).all()
    # seeded per sample: the same index gives the same sample, another index another one
    again, _ = make_real_sample("train", 3, seed=0, res=96, category="organic")
    assert np.array_equal(again["rgb"], arrays["rgb"])
    other, _ = make_real_sample("train", 4, seed=0, res=96, category="organic")
    assert not np.array_equal(other["mask"], arrays["mask"])
