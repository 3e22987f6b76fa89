"""The ``flat`` and ``assembly`` training categories (eighth session): upright thin things
and random assemblies of primitives; ``rest`` and ``branch`` (tenth session): solids lying
at rest on a face, and structures reaching out over the ground; ``heldout3`` (tenth session),
validation only. Invariants over many seeds: a flat object's main panel is thin and upright;
an assembly's parts hold together, each rests on the ground or is held by a lower part, and
the whole stands (its centre of mass over its footprint); a rest object lies on a face, not
upright; a branch object reaches out beyond its grounded pieces; the pieces of rest, branch
and heldout3 objects are closed surfaces."""
import numpy as np
import pytest

pytest.importorskip("trimesh")
pytest.importorskip("scipy")

from pixgraph_lab.datagen.categories import CATEGORIES, make_object  # noqa: E402

FLAT_KINDS = {"frame", "mirror", "divider", "door", "screen", "books", "board_cutting", "board_surf",
              "board_skate", "sandwich_board", "pegboard"}
ASSEMBLY_VARIANTS = {"stack", "legs", "cantilever", "mixed"}


def parts_of(V, F):
    """The vertex index arrays of the mesh's connected pieces (each primitive is one: ``Parts``
    does not weld vertices across parts)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(V), len(V)))
    n, lab = connected_components(g, directed=False)
    used = np.zeros(len(V), bool)
    used[F.ravel()] = True
    return [np.nonzero((lab == k) & used)[0] for k in range(n) if ((lab == k) & used).any()]


def test_new_categories_keep_the_fixed_order_and_are_in_no_mix():
    from pixgraph_lab.height import real
    assert CATEGORIES[:8] == ("person", "animal", "figurine", "furniture", "product", "vehicle", "organic",
                              "heldout")
    assert CATEGORIES.index("flat") == 8 and CATEGORIES.index("assembly") == 9
    for c in ("flat", "assembly"):
        assert c not in real.CATEGORY_P and c not in real.CATEGORY_P_REAL


def test_flat_objects_have_a_thin_upright_main_panel_and_every_kind_is_drawn():
    import trimesh
    kinds = set()
    for s in range(200):
        V, F, L, names, kind = make_object("flat", np.random.default_rng([s, 21]))
        cat, k = kind.split("/")
        assert cat == "flat" and k in FLAT_KINDS, kind
        kinds.add(k)
        assert V[:, 1].min() == 0.0 and L.shape == (len(F),)
        # the main panel: the piece of the largest surface area
        pieces = parts_of(V, F)
        areas = []
        for idx in pieces:
            sel = np.isin(F, idx).all(1)
            areas.append(trimesh.Trimesh(V, F[sel], process=False).area)
        main = V[pieces[int(np.argmax(areas))]]
        T, ext = trimesh.bounds.oriented_bounds(main)
        order = np.argsort(ext)
        thin, width = ext[order[0]], ext[order[1]]
        assert thin < 0.15 * width, (s, kind, ext)
        # upright: the panel's thin axis is near level (leaning back at most ~30 deg)
        normal = np.linalg.inv(T)[:3, order[0]]
        assert abs(normal[1]) < 0.5, (s, kind, normal)
        # facing the camera before the generator's yaw: across the main panel, thin in z
        if k not in ("books", "divider"):      # a row of books and a zigzag screen turn their panels
            assert abs(normal[2]) > 0.8, (s, kind, normal)
    assert kinds == FLAT_KINDS


def _boxes(V, pieces):
    return np.array([[V[i].min(0), V[i].max(0)] for i in pieces])


def _group_of_first(n, joined):
    """The pieces 0..n-1 reached from piece 0 through pairs with ``joined(i, j)`` true (a set)."""
    seen, todo = {0}, [0]
    while todo:
        i = todo.pop()
        for j in range(n):
            if j not in seen and joined(i, j):
                seen.add(j)
                todo.append(j)
    return seen


def _overlap(a, b, tol):
    return bool((a[0] <= b[1] + tol).all() and (b[0] <= a[1] + tol).all())


def test_assemblies_hold_together_rest_on_something_and_stand():
    from scipy.spatial import ConvexHull
    import trimesh
    variants, counts = set(), set()
    for s in range(200):
        V, F, L, names, kind = make_object("assembly", np.random.default_rng([s, 22]))
        cat, var = kind.split("/")
        assert cat == "assembly" and var in ASSEMBLY_VARIANTS, kind
        variants.add(var)
        pieces = parts_of(V, F)
        counts.add(len(pieces))
        assert 2 <= len(pieces) <= 8, (s, kind, len(pieces))
        size = np.ptp(V, 0).max()
        tol = 1e-3 * size
        B = _boxes(V, pieces)
        # one connected structure: the parts' boxes, joined where they touch, form one group
        n = len(pieces)
        seen, todo = {0}, [0]
        while todo:
            i = todo.pop()
            for j in range(n):
                if j not in seen and _overlap(B[i], B[j], tol):
                    seen.add(j)
                    todo.append(j)
        assert len(seen) == n, (s, kind)
        # held from below: every part off the ground is embedded in (its box overlaps by a
        # positive depth) a part whose lowest point is lower, so a chain of parts reaches the ground
        for i in range(n):
            if B[i, 0, 1] <= tol:
                continue
            assert any(B[j, 0, 1] < B[i, 0, 1] and
                       (np.minimum(B[i, 1], B[j, 1]) - np.maximum(B[i, 0], B[j, 0])).min() > 0
                       for j in range(n) if j != i), (s, kind, i)
        # it stands: the centre of mass (uniform density, from the closed parts' volumes) lies
        # inside the convex hull of the points on the ground
        vol, mom = 0.0, np.zeros(3)
        for idx in pieces:
            sel = np.isin(F, idx).all(1)
            m = trimesh.Trimesh(V, F[sel], process=False)
            m.remove_unreferenced_vertices()
            assert m.is_watertight and m.euler_number == 2, (s, kind)   # closed, no hole (no ring)
            vol += abs(m.volume)
            mom += abs(m.volume) * m.center_mass
        com = mom / vol
        hull = ConvexHull(V[V[:, 1] <= tol][:, [0, 2]])
        assert (hull.equations[:, :2] @ com[[0, 2]] + hull.equations[:, 2]).max() < 0, (s, kind)
    assert variants == ASSEMBLY_VARIANTS
    assert min(counts) == 2 and max(counts) >= 7


@pytest.mark.parametrize("cat", ["flat", "assembly", "rest", "branch"])
def test_a_training_kinds_sample_renders_and_is_deterministic(cat):
    pytest.importorskip("mitsuba")
    from pixgraph_lab.datagen.raycast import select_variant
    from pixgraph_lab.height import generate
    select_variant()
    arrays, meta = generate.make_sample("train", 2, seed=0, res=64, mix="real", category=cat)
    assert meta["category"] == cat and meta["object"].startswith(cat + "/")
    mask, h = arrays["mask"], arrays["height"].astype(float)
    assert mask.sum() > 0.004 * 64 * 64
    assert (h[~mask] == 0).all() and (h[mask] > 0).all()
    again, _ = generate.make_sample("train", 2, seed=0, res=64, mix="real", category=cat)
    for k in arrays:
        assert np.array_equal(again[k], arrays[k]), (cat, k)


def test_is_stable_on_boxes_with_a_known_centre_of_mass():
    """``categories.is_stable`` on cases worked by hand: a base 1 x 0.1 x 1 with a block of
    the same volume held at x = X above it has its centre of mass at x = X / 2 over a unit
    square of ground contacts (margin 0.02 x sqrt(area) = 0.02); sunk below the ground, or
    on an edge (fewer than three ground points), nothing stands."""
    from pixgraph_lab.datagen.categories import box, is_stable
    base = lambda: box([0, 0.05, 0], [1, 0.1, 1])                   # noqa: E731
    block = lambda X: box([X, 0.35, 0], [0.2, 0.5, 1])               # noqa: E731  (volume 0.1, y 0.1-0.6)
    assert is_stable([base()])
    assert is_stable([base(), block(0.9)])                           # centre at 0.45: inside by 0.05
    assert not is_stable([base(), block(0.98)])                      # at 0.49: inside, but by < 0.02
    assert is_stable([base(), block(0.98)], rel_margin=0.0)
    assert not is_stable([base(), block(1.1)], rel_margin=0.0)       # at 0.55: outside the foot
    assert not is_stable([box([0, 0.45, 0], [1, 1, 1])])              # 0.05 below the ground
    from pixgraph_lab.datagen.categories import prism
    edge = prism([(-0.5, 0.5), (0.5, 0.5), (0.0, 0.0)], -0.5, 0.5)   # a wedge standing on its edge
    assert not is_stable([edge])                                     # two ground points: no area
    assert is_stable([prism([(-0.5, 0.0), (0.5, 0.0), (0.0, 0.5)], -0.5, 0.5)])   # on its face


# ---------------------------------------------------------------- rest and branch (tenth session)
REST_KINDS = {"superquadric", "revolved", "blob", "prism", "compound"}


def _pieces_mass(V, F):
    """(piece label per vertex, volumes (k,), centres of mass (k, 3), the k pieces' labels) of
    the mesh's closed connected pieces (uniform density): the signed tetrahedra from the origin
    summed per piece."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(V), len(V)))
    n, lab = connected_components(g, directed=False)
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    det = np.einsum("ij,ij->i", A, np.cross(B, C)) / 6.0
    fl = lab[F[:, 0]]
    vol = np.bincount(fl, det, n)
    mom = np.stack([np.bincount(fl, det * (A + B + C)[:, k] / 4.0, n) for k in range(3)], 1)
    used = np.bincount(fl, minlength=n) > 0
    return lab, np.abs(vol[used]), mom[used] / vol[used][:, None], np.nonzero(used)[0]


def _draw(cat, seed, known):
    """``make_object(cat)`` for ``seed``, checked: its kind is one of ``known``, its vertices are
    finite with the lowest on Y = 0, one material slot per face. Returns (V, F, L, names, kind)."""
    V, F, L, names, kind = make_object(cat, np.random.default_rng(seed))
    c, k = kind.split("/")
    assert c == cat and k in known, kind
    assert np.isfinite(V).all() and V[:, 1].min() == 0.0 and L.shape == (len(F),), kind
    return V, F, L, names, k


def _euler_per_piece(V, F, lab, ids):
    """V - E + F of each piece ``ids`` (2 for a closed surface without a hole: no ring)."""
    fl = lab[F[:, 0]]
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), 1), axis=0)
    n = lab.max() + 1
    used = np.zeros(len(V), bool)
    used[F.ravel()] = True
    chi = np.bincount(lab[used], minlength=n) - np.bincount(lab[E[:, 0]], minlength=n) + np.bincount(fl, minlength=n)
    return chi[ids]


def _ground_hull_holds(V, com, tol):
    """Whether the centre of mass ``com`` lies inside the convex hull of the points within
    ``tol`` of the ground (the object stands)."""
    from scipy.spatial import ConvexHull
    g = V[V[:, 1] <= tol][:, [0, 2]]
    if len(g) < 3 or np.linalg.matrix_rank(g - g.mean(0), tol=1e-9) < 2:
        return False
    hull = ConvexHull(g)
    return bool((hull.equations[:, :2] @ com[[0, 2]] + hull.equations[:, 2]).max() < 0)


def test_rest_and_branch_are_appended_and_in_no_mix():
    from pixgraph_lab.height import real
    assert CATEGORIES[:11] == ("person", "animal", "figurine", "furniture", "product", "vehicle", "organic",
                               "heldout", "flat", "assembly", "heldout2")
    assert CATEGORIES.index("rest") == 11 and CATEGORIES.index("branch") == 12
    for c in ("rest", "branch"):
        assert c not in real.CATEGORY_P and c not in real.CATEGORY_P_REAL


def test_existing_categories_and_mixes_are_unchanged():
    """The meshes of every earlier category over fixed seeds (and the random stream each leaves
    behind), and two ``--mix real`` / ``real_organic`` samples, are those recorded before
    ``rest`` and ``branch`` were added (tenth session), so existing data sets regenerate."""
    import hashlib
    h = hashlib.sha256()
    for c in CATEGORIES[:11]:
        for s in range(3):
            rng = np.random.default_rng([s, 77])
            V, F, L, names, kind = make_object(c, rng)
            h.update(np.round(V, 6).tobytes())
            h.update(F.tobytes())
            h.update(L.tobytes())
            h.update(("|".join(names) + kind).encode())
            h.update(rng.random(1).tobytes())
    assert h.hexdigest() == "e014f6cd04836360586c0682b5f0850966f82cd27308c5a7e6c2ecea4832dadd"
    pytest.importorskip("mitsuba")
    from pixgraph_lab.datagen.raycast import select_variant
    from pixgraph_lab.height import generate
    select_variant()
    recorded = {("real", 1): ("person/standing", "upright", 38, 31.281531293888616),
                ("real_organic", 1): ("animal/bird", "tilted", 78, 54.023027113062525)}
    for (mix, i), (obj, pose, px, hfov) in recorded.items():
        arrays, meta = generate.make_sample("train", i, seed=0, res=48, mix=mix)
        assert (meta["object"], meta["pose"], meta["mask_px"]) == (obj, pose, px), (mix, meta)
        assert meta["camera"]["hfov"] == pytest.approx(hfov, rel=1e-12)


def test_rest_objects_lie_stably_on_a_face_not_upright():
    from scipy.spatial import ConvexHull
    kinds, upright, elong, apart = set(), 0, [], []
    n = 120
    for s in range(n):
        V, F, L, names, k = _draw("rest", [s, 23], REST_KINDS)
        kind = "rest/" + k
        kinds.add(k)
        # the longest principal axis (vertices' covariance) is far from vertical in most draws
        # (built upright, they are turned onto a side; near-round ones may end either way)
        w, vec = np.linalg.eigh(np.cov((V - V.mean(0)).T))
        upright += abs(vec[1, -1]) > 0.8
        ext = np.ptp(V @ vec, 0)                             # extents along the principal axes
        elong.append(ext.max() / ext.min())
        # at rest: the centre of mass over the convex hull of the points touching the ground
        tol = 1e-3 * np.ptp(V, 0).max()
        lab, vol, com_i, ids = _pieces_mass(V, F)
        assert _ground_hull_holds(V, (vol[:, None] * com_i).sum(0) / vol.sum(), tol), (s, kind)
        assert (_euler_per_piece(V, F, lab, ids) == 2).all(), (s, kind)      # closed, no ring
        # one body, or a compound's 2-3 fused: its pieces are joined where their convex hulls meet
        pieces = parts_of(V, F)                              # (a linear program; necessary)
        assert len(pieces) >= 2 or k != "compound", (s, kind)
        if len(pieces) > 1:
            hulls = [ConvexHull(V[idx]).equations for idx in pieces]
            joined = _group_of_first(len(pieces), lambda i, j: _convex_pieces_touch(
                V[pieces[i]], V[pieces[j]], tol, hulls[i], hulls[j]))
            apart += [s] if len(joined) < len(pieces) else []
    assert kinds == REST_KINDS
    # a soft union of ellipsoids (``blob``, alone or in a compound) came out of the grid in
    # pieces that did not touch on seeds 5 (a piece a quarter of the size up in the air), 22 and
    # 49 before the builder kept only the largest piece (train_rest of the tenth session was
    # made before that: docs/height-record.md, "Measured: generic kinds on a lent GPU")
    assert apart == [], apart
    assert upright <= 0.1 * n, upright                      # 2 of 120 when written
    # elongations (longest : shortest extent along the principal axes) from about 1:1 to past 1:6
    elong = np.array(elong)
    assert elong.min() < 1.3 and elong.max() > 6, (elong.min(), elong.max())
    assert (elong < 2).mean() > 0.15 and (elong > 4).mean() > 0.15, np.percentile(elong, [25, 50, 75])


def test_rest_pose_keeps_a_box_off_its_ends_and_rolls_a_wedge_off_a_face_it_overhangs():
    """``rest_pose`` worked by hand: a 1 x 4 x 0.5 box (x, y, z) built upright rests on any
    face, but never ends on its small ends (the build's vertical axis is avoided); an obtuse
    triangular prism (z, y) (0, 0), (1, 0), (3, 1) has its centre of mass at z = 4/3, beyond
    its base (z 0 to 1), so it rolls off the base onto another face from every drop (the
    avoidance of the vertical axis switched off: ``avoid_up`` > 1 keeps the first drop), and
    the face it ends on holds it (its centre of mass over that face)."""
    from pixgraph_lab.datagen.categories import box, prism, rest_pose
    for s in range(20):
        R = rest_pose([box([0, 0, 0], [1, 4, 0.5])], np.random.default_rng(s))
        assert np.abs(R @ R.T - np.eye(3)).max() < 1e-12 and np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
        down = R.T @ np.array([0.0, -1.0, 0.0])              # the face turned down, build frame
        assert np.abs(down).max() == pytest.approx(1.0, abs=1e-9), (s, down)
        assert abs(down[1]) < 1e-9, (s, down)
    ends = 0
    wedge = prism([(0, 0), (1, 0), (3, 1)], -0.5, 0.5)
    W, com = np.asarray(wedge.vertices), np.array([0.0, 1 / 3, 4 / 3])   # (x, y, z)
    for s in range(40):
        R = rest_pose([wedge], np.random.default_rng(s), avoid_up=2.0)
        assert np.abs(R @ R.T - np.eye(3)).max() < 1e-12 and np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
        down = R.T @ np.array([0.0, -1.0, 0.0])
        assert down[1] > -0.99, (s, down)                     # never on the base y = 0
        ends += abs(down[0]) > 0.99                             # on a triangular end (stable)
        # turned, it rests on that face: the centre of mass over the points on the ground
        lift = (W @ R.T)[:, 1].min()
        assert _ground_hull_holds(W @ R.T - [0, lift, 0], R @ com - [0, lift, 0], 1e-9), (s, down)
    assert ends < 40


BRANCH_KINDS = {"tree", "shrub", "coat_stand", "candelabra", "antler", "coral", "arc_lamp", "cantilever"}


def test_branches_hold_together_reach_out_over_the_ground_and_stand():
    from scipy.spatial import ConvexHull
    kinds, overhangs = set(), []
    n = 60
    for s in range(n):
        V, F, L, names, k = _draw("branch", [s, 24], BRANCH_KINDS)
        kind = "branch/" + k
        kinds.add(k)
        lab, vol, com_i, ids = _pieces_mass(V, F)
        assert (_euler_per_piece(V, F, lab, ids) == 2).all(), (s, kind)      # closed, no ring
        height = V[:, 1].max()
        tol = 1e-3 * height
        # held: the pieces' bounding boxes, joined where they overlap, form one structure
        B = np.array([[V[lab == i].min(0), V[lab == i].max(0)] for i in ids])
        adj = ((B[:, None, 0] <= B[None, :, 1] + tol) & (B[None, :, 0] <= B[:, None, 1] + tol)).all(-1)
        assert len(_group_of_first(len(ids), lambda i, j: adj[i, j])) == len(ids), (s, kind)
        # stands: the centre of mass over the hull of the points on the ground
        assert _ground_hull_holds(V, (vol[:, None] * com_i).sum(0) / vol.sum(), tol), (s, kind)
        # overhang: how far (share of the height) the parts off the ground reach outside the
        # footprint of the pieces touching it (their whole plan, not only their contacts)
        on = np.isin(lab, ids[B[:, 0, 1] <= tol])
        foot = ConvexHull(V[on][:, [0, 2]])
        out = (V[~on][:, [0, 2]] @ foot.equations[:, :2].T + foot.equations[:, 2]).max(1)
        overhangs.append(max(float(out.max()), 0.0) / height)
    assert kinds == BRANCH_KINDS
    overhangs = np.array(overhangs)
    assert (overhangs > 0.1).mean() >= 0.75, np.round(overhangs, 2)     # 0.86 when written
    assert np.median(overhangs) > 0.3, np.round(overhangs, 2)            # 0.47 when written


# ---------------------------------------------------------------- heldout3 (tenth session)
HELDOUT3 = {"kick_scooter", "tent", "suitcase", "kettle_barbecue", "anvil_on_stump", "pram", "sled",
            "step_ladder"}
KINDS_BEFORE_HELDOUT3 = ("person", "animal", "figurine", "furniture", "product", "vehicle", "organic", "heldout",
                         "flat", "assembly", "heldout2")


def test_heldout3_comes_after_the_existing_categories_and_no_mix_draws_it():
    """``heldout3`` judges the tenth session's candidates: it is appended after every existing
    category (their numbers seed ``--category`` streams, so those samples are unchanged), and
    the training mixes are what they were, none drawing a held-out set."""
    from pixgraph_lab.datagen.categories import HELDOUT3_KINDS
    from pixgraph_lab.height import real
    assert CATEGORIES[:len(KINDS_BEFORE_HELDOUT3)] == KINDS_BEFORE_HELDOUT3
    assert CATEGORIES.index("heldout3") >= len(KINDS_BEFORE_HELDOUT3)
    assert set(HELDOUT3_KINDS) == HELDOUT3 and len(HELDOUT3_KINDS) == 8
    assert real.CATEGORY_P_REAL == {"person": 0.3, "animal": 0.15, "figurine": 0.15, "furniture": 0.17,
                                    "product": 0.13, "vehicle": 0.1}
    assert set(real.CATEGORY_P) == set(real.CATEGORY_P_REAL) | {"organic"}
    assert real.CATEGORY_P["organic"] == pytest.approx(0.2)
    for c, p in real.CATEGORY_P_REAL.items():
        assert real.CATEGORY_P[c] == pytest.approx(0.8 * p)
    for mix in (real.CATEGORY_P, real.CATEGORY_P_REAL):
        assert not {"heldout", "heldout2", "heldout3"} & set(mix)


def _convex_pieces_touch(P, Q, tol, EP=None, EQ=None):
    """Whether the convex hulls of the point sets P and Q come within about ``tol`` of each
    other: some point satisfies both hulls' face inequalities loosened by ``tol`` (a linear
    program; exact for convex pieces, as every primitive of ``heldout3`` is). ``EP``, ``EQ``:
    the hulls' equations if known. A point of one inside the other answers without the program."""
    from scipy.optimize import linprog
    from scipy.spatial import ConvexHull
    EP = ConvexHull(P).equations if EP is None else EP
    EQ = ConvexHull(Q).equations if EQ is None else EQ
    if ((P @ EQ[:, :3].T + EQ[:, 3]).max(1) <= tol).any() or ((Q @ EP[:, :3].T + EP[:, 3]).max(1) <= tol).any():
        return True
    E = np.concatenate([EP, EQ])
    r = linprog(np.zeros(3), A_ub=E[:, :3], b_ub=tol - E[:, 3], bounds=[(None, None)] * 3, method="highs")
    return r.status == 0


def test_convex_pieces_touch_on_boxes_placed_by_hand():
    """Two unit cubes: face to face, edge across face (no vertex of either inside the other),
    crossing like a plus sign, and 0.01 apart (touching only with a tolerance above 0.01)."""
    from pixgraph_lab.datagen.categories import box
    a = np.asarray(box([0, 0, 0], [1, 1, 1]).vertices)
    v = lambda c, e: np.asarray(box(c, e).vertices)                       # noqa: E731
    assert _convex_pieces_touch(a, v([1, 0, 0], [1, 1, 1]), 1e-9)           # face to face
    assert _convex_pieces_touch(v([0, 0, 0], [3, 0.2, 0.2]), v([0, 0, 0], [0.2, 3, 0.2]), 1e-9)   # a plus sign
    assert _convex_pieces_touch(a, v([0, 0.6, 0], [3, 0.2, 3]), 1e-9)       # a wide plate through its top
    assert not _convex_pieces_touch(a, v([1.01, 0, 0], [1, 1, 1]), 1e-3)
    assert _convex_pieces_touch(a, v([1.01, 0, 0], [1, 1, 1]), 0.02)


def test_heldout3_kinds_are_all_drawn_rest_on_the_ground_hold_together_and_stand():
    """Over 160 fixed seeds every kind occurs; each mesh is finite, rests on Y = 0 with a valid
    material slot per face, its parts form one connected structure (no floating part: the
    parts, joined where their convex hulls come within 0.2 % of the object's size, form one
    group), every part is closed, it stands (centre of mass over the ground contacts; a kick
    scooter when its kickstand is out), a sled lies low and long, a step ladder stands taller
    than wide."""
    drawn = check_heldout3_objects(range(160))
    assert set(drawn) == HELDOUT3, drawn


def check_heldout3_objects(seeds):
    """The invariants of ``test_heldout3_kinds_...`` over ``seeds``; returns {kind: count}."""
    import trimesh
    from scipy.spatial import ConvexHull
    drawn = {}
    for s in seeds:
        V, F, L, names, kind = make_object("heldout3", np.random.default_rng([s, 33]))
        cat, k = kind.split("/")
        assert cat == "heldout3" and k in HELDOUT3, kind
        drawn[k] = drawn.get(k, 0) + 1
        assert np.isfinite(V).all() and V[:, 1].min() == 0.0
        assert L.shape == (len(F),) and 0 <= L.min() and L.max() < len(names) and F.max() < len(V)
        assert len(set(L.tolist())) >= 2, (s, kind)          # at least two materials to colour
        pieces = parts_of(V, F)
        ext = np.ptp(V, 0)
        size = ext.max()
        tol = 2e-3 * size
        B = _boxes(V, pieces)
        hulls = [ConvexHull(V[idx]).equations for idx in pieces]
        seen = _group_of_first(len(pieces), lambda i, j: _overlap(B[i], B[j], tol) and _convex_pieces_touch(
            V[pieces[i]], V[pieces[j]], tol, hulls[i], hulls[j]))
        assert len(seen) == len(pieces), (s, kind, [(names[L[np.isin(F, pieces[j]).all(1)][0]], B[j].round(3))
                                                    for j in sorted(set(range(len(pieces))) - seen)][:3])
        vol, mom = 0.0, np.zeros(3)           # uniform density over the closed parts
        for idx in pieces:
            m = trimesh.Trimesh(V, F[np.isin(F, idx).all(1)], process=False)
            m.remove_unreferenced_vertices()
            assert m.is_watertight, (s, kind)
            vol += abs(m.volume)
            mom += abs(m.volume) * m.center_mass
        stands = _ground_hull_holds(V, mom / vol, 1e-3 * size)
        if k == "kick_scooter":               # on its kickstand if it has one (the wheels: |x| < 0.021)
            assert stands or not ((np.abs(V[:, 0]) > 0.03) & (V[:, 1] <= 1e-3 * size)).any(), (s, kind)
        else:
            assert stands, (s, kind)
        if k == "sled":
            assert ext[1] < 0.4 * max(ext[0], ext[2]), (s, kind, ext)
        if k == "step_ladder":
            assert ext[1] > ext[0] and ext[1] > ext[2], (s, kind, ext)
    return drawn


def test_a_heldout3_sample_renders_and_is_deterministic():
    pytest.importorskip("mitsuba")
    from pixgraph_lab.datagen.raycast import select_variant
    from pixgraph_lab.height import generate
    select_variant()
    arrays, meta = generate.make_sample("val", 1, seed=3, res=48, mix="real", category="heldout3")
    assert meta["category"] == "heldout3" and meta["object"].startswith("heldout3/")
    mask, h = arrays["mask"], arrays["height"].astype(float)
    assert mask.sum() > 0.004 * 48 * 48 and (h[~mask] == 0).all() and (h[mask] > 0).all()
    again, meta2 = generate.make_sample("val", 1, seed=3, res=48, mix="real", category="heldout3")
    assert meta2["object"] == meta["object"]
    for k in arrays:
        assert np.array_equal(again[k], arrays[k]), k
