"""The simulated user who fixes a wrong pixel height by hand with ``pixgraph.PixelHeightEdit``
(nodes/ops/height_edit.py), shared by ``benchmarks/page_height_fix.py`` (the same edits done
in the page, headless Chromium) and ``pixgraph_lab.height.real_photos`` (docs/height.md's
real-photo check, computed with ``edit_pixel_height``, no browser).

The rules were written before any measurement: the user knows where the object really
touches the ground and how tall its top and its body really are (``known_heights``), and
tries each plan of at most 3 page actions in ``PLANS`` -- contact points dragged from the
foot's hollow handle onto the lowest visible pixel with true height < 1 px in each of k
column bins (``true_contacts``); the tilt handle dragged until the top's height is its true
one, lying down the same square for the thickness; the body's ring (foot depth) dragged
until the body point's height is its true one; the upright and lying toggles; the other
height method (``switch``: the CutoutHeight node's ``method``, ``OTHER``) -- and keeps the
plan whose shadow is closest to the true heights' shadow (the user sees the shadow). Heights
and points are in pixels of the map the edit is applied to.

That is user A. User B (``plan_params``' ``watch``; docs/height-record.md, "Rules fixed
before measuring: a user who watches the shadow") does the same actions but ends each drag
of the top's square or the body's ring where, of a fixed set of handle heights
(``WATCH_*``) and user A's, the shadow comes closest: a compositor drags until the shadow
looks right, not until a height they cannot see is right.
"""
from __future__ import annotations

import numpy as np


def known_heights(true_h: np.ndarray, rendered: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """What the simulated user knows of the true heights [px] over the pixels it sees
    (``seen``): the render's where it covered the pixel (``rendered``), else the nearest
    rendered pixel's. The 8-bit alpha covers a few outline pixels the render's mask does
    not (its antialiased edge); their stored true height is 0, which is no height the
    user believes: the top row of a mug, a duck, the teddy is such a pixel, so "the
    top's true height" was 0 there and the top drag was skipped."""
    from scipy import ndimage
    good = rendered & seen
    if not good.any():
        return np.where(seen, true_h, 0.0)
    iy, ix = ndimage.distance_transform_edt(~good, return_distances=False, return_indices=True)
    return np.where(seen, np.where(good, true_h, true_h[iy, ix]), 0.0)


def true_contacts(true_h: np.ndarray, mask: np.ndarray, k: int, *, fallback_rows: int | None = None,
                  v_at: float = 0.5) -> list:
    """Up to ``k`` contact points (u, v) [px]: the lowest visible pixel whose true height is
    < 1 px in each of ``k`` equal column bins of those pixels (one bin: the lowest of all;
    fewer bins when those pixels span fewer than ``k`` columns).

    With no such pixel the mask's own pixels stand in, only its lowest ``fallback_rows``
    rows when that is given. ``v_at``: where in the chosen pixel the point lies, 0.5 its
    centre (inside the mask), 1.0 its bottom edge (``real_photos``' old plans)."""
    ys, xs = np.nonzero(mask & (true_h < 1.0))
    if len(xs) == 0:
        ys, xs = np.nonzero(mask)
        if fallback_rows is not None:
            keep = ys >= ys.max() - (fallback_rows - 1)
            ys, xs = ys[keep], xs[keep]
    edges = np.linspace(xs.min(), xs.max() + 1, min(k, len(np.unique(xs))) + 1)
    pts = []
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (xs >= a) & (xs < b)
        if sel.any():
            i = np.argmax(np.where(sel, ys, -1))
            pts.append((float(xs[i] + 0.5), float(ys[i] + v_at)))
    return pts


#: the simulated user's plans: each a list of page actions (at most 3: drags, or a toggle)
PLANS = {
    "1 contact": ["contact:1"],
    "2 contacts": ["contact:2"],
    "3 contacts": ["contact:3"],
    "2 contacts, upright": ["contact:2", "upright"],
    "1 contact + top": ["contact:1", "top"],
    "2 contacts + top": ["contact:2", "top"],
    "top": ["top"],
    "lying": ["lying"],
    # the other height method (the CutoutHeight node's `method` select in the page's panel: one click)
    "other method": ["switch"],
    "other method + 2 contacts": ["switch", "contact:2"],
    "other method + 1 contact + top": ["switch", "contact:1", "top"],
    "other method + top": ["switch", "top"],
    # lying down, the top square dragged until the top's height is its true one (the thickness)
    "lying + thickness": ["lying", "thickness"],
    # the body's ring (foot depth) dragged until the body's ground point is its true one
    "depth": ["depth"],
    "depth + top": ["depth", "top"],
    "top + depth": ["top", "depth"],
    "1 contact + depth + top": ["contact:1", "depth", "top"],
    "other method + depth": ["switch", "depth"],
    "other method + depth + top": ["switch", "depth", "top"],
    "other method + top + depth": ["switch", "top", "depth"],
}
#: the plans added with the foot-depth ring and the lying thickness drag (fourth session)
NEW_PLANS = ("lying + thickness", "depth", "depth + top", "top + depth", "1 contact + depth + top",
             "other method + depth", "other method + depth + top", "other method + top + depth")
#: the other height method of each (the ``switch`` action)
OTHER = {"learned": "contact_line", "contact_line": "learned"}


def plan_method(plan: list, method: str) -> str:
    """The height method after the plan: the other one if it switches (``switch``)."""
    return OTHER[method] if "switch" in plan else method


#: user B's handle heights (docs/height-record.md, "Rules fixed before measuring: a user who
#: watches the shadow"): the top's square at ``h0`` times these, the body's ring at ``h0 + bh``
#: times these, the lying thickness at ``bh`` times these (``h0`` the handle point's height
#: before the drag, ``bh`` the cutout's box height) [px]
WATCH_TOP = tuple(round(0.4 + 0.1 * i, 2) for i in range(13))
WATCH_DEPTH = tuple(round(-0.3 + 0.05 * i, 2) for i in range(13))
WATCH_THICKNESS = tuple(round(0.05 * i, 2) for i in range(1, 21))


def box_height(mask: np.ndarray) -> float:
    """The cutout's box height [px]: rows from its highest to its lowest covered pixel."""
    rows = np.nonzero(np.asarray(mask).any(axis=1))[0]
    return float(rows.max() - rows.min() + 1) if len(rows) else 0.0


def plan_params(plan: list, known_h: np.ndarray, mask: np.ndarray, edited, watch=None,
                targets: dict | None = None) -> dict:
    """The edit's params after the plan's actions, in order (``known_h``: the heights the
    user knows [px], ``edited(params)``: the edited map with those params, params named as
    the node's: ``contact_points``, ``contact_mode``, ``tilt`` [deg], ``lying``,
    ``thickness`` [px], ``foot_depth`` [px]). ``top`` drags the tilt handle until the top's
    height is its true one, ``thickness`` (lying) the same square, ``depth`` the body's
    ring until the body point's height is its true one (the node's elevation: 20 deg).

    ``watch`` (user B, who watches the shadow): ``watch(candidates)`` gets the params each
    of the drag's handle heights would give (``WATCH_*`` and user A's own) and returns the
    index of the one whose shadow it keeps. ``targets`` (a dict, filled in): the handle
    height [px] each drag ended at, by action name, for the page's drags."""
    from pixgraph_nodes.ops.height_edit import (body_point, depth_for_height, thickness_for_height, tilt_for_height,
                                                tilt_gain, top_point)
    p = {}
    bh = box_height(mask)

    def drag(key, heights, to_param):
        """``p[key]`` for user A's height (``heights[0]``, None when it has none) or, with
        ``watch``, for the watched one; records the height in ``targets``."""
        cands = [h for h in heights if h is not None and h >= 0]
        if watch is None:
            cands = cands[:1] if heights[0] is not None else []
        seen, options = set(), []
        for h in cands:
            v = round(to_param(h), 2)
            if v not in seen:
                seen.add(v)
                options.append((h, v))
        if not options:
            return
        k = watch([{**p, key: v} for _, v in options]) if watch is not None and len(options) > 1 else 0
        p[key] = options[k][1]
        if targets is not None:
            targets[key] = options[k][0]

    for act in plan:
        if act.startswith("contact:"):
            p["contact_points"] = [c for pt in true_contacts(known_h, mask, int(act[8:])) for c in pt]
        elif act == "upright":
            p["contact_mode"] = "upright"
        elif act == "lying":
            p["lying"] = True
        elif act == "top":
            top = top_point(mask, edited({k: v for k, v in p.items() if k != "tilt"}))
            true_top = top_point(mask, known_h)
            if top is not None:
                drag("tilt", [true_top[2] if true_top is not None else None, *(top[2] * f for f in WATCH_TOP)],
                     lambda h, h0=top[3]: tilt_for_height(h0, h, 0.0, 20.0))
        elif act == "thickness":
            true_top = top_point(mask, known_h)
            g = tilt_gain(p.get("tilt", 0.0), 20.0)
            drag("thickness", [true_top[2] if true_top is not None else None, *(bh * f for f in WATCH_THICKNESS)],
                 lambda h: thickness_for_height(h, g))
        elif act == "depth":
            g = tilt_gain(p.get("tilt", 0.0), 20.0)
            body = body_point(mask, edited({k: v for k, v in p.items() if k != "foot_depth"}), p.get("tilt", 0.0))
            true_body = body_point(mask, known_h)
            if body is not None:
                drag("foot_depth", [true_body[2] if true_body is not None else None,
                                    *(body[2] + bh * f for f in WATCH_DEPTH)],
                     lambda h, h0=body[3]: depth_for_height(h0, h, g))
    return p


def edit_with(height: np.ndarray, mask: np.ndarray, params: dict) -> np.ndarray:
    """``edit_pixel_height`` of ``height`` with the node's params (``plan_params``'s names;
    ``contact_points`` flat u1, v1, ...), the node's defaults for the rest."""
    from pixgraph_nodes.ops.height_edit import edit_pixel_height
    pts = params.get("contact_points", [])
    return edit_pixel_height(height, mask, [(pts[i], pts[i + 1]) for i in range(0, len(pts), 2)],
                             contact_mode=params.get("contact_mode", "shift"), tilt_deg=params.get("tilt", 0.0),
                             elevation_deg=20.0, lying=params.get("lying", False),
                             thickness=params.get("thickness", 0.0), foot_depth=params.get("foot_depth", 0.0))
