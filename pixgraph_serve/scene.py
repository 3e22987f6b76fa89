"""The UI's handles: where the light's shadow tip, the wall corner and the horizon
are in the image, and the param edits that a drag of each one means.

This is the one part of the server that knows the built-in shadow nodes
(``pixgraph.Camera``, ``pixgraph.Light``, ``pixgraph.BackgroundHeight`` and a
shadow node fed by the light); a graph without them is served all the same, with
the param panel only.

The light is dragged by its *shadow tip*: the point on the ground where the
shadow of the object's top falls (the Light node's ``shadow_tip`` placement, so
the tip stays under the pointer). The elevation slider then slides the tip along
the same ground direction, to where the light seen from the object's top has
that elevation.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .state import ServeError, ServeState

CAMERA, LIGHT, BACKGROUND = "pixgraph.Camera", "pixgraph.Light", "pixgraph.BackgroundHeight"
PLACE = "pixgraph.PlaceCutout"


def _first(state: ServeState, type_id: str) -> str | None:
    return next((nid for nid, inst in state.graph.nodes.items() if inst.type == type_id), None)


def roles(state: ServeState) -> dict[str, str | None]:
    """Node ids of the camera, light, background template and shadow (None when absent),
    and of the cutout's placement when there is one."""
    g = state.graph
    light = _first(state, LIGHT)
    shadow = None
    if light is not None:
        shadow = next((nid for nid, inst in g.nodes.items()
                       if inst.type in state.method_types()
                       and any(r.node == light for r in inst.inputs.values())), None)
    out = {"camera": _first(state, CAMERA), "light": light, "background": _first(state, BACKGROUND),
           "shadow": shadow}
    place = _first(state, PLACE)
    if place is not None:   # the cutout placed on the photo (own-photo graphs)
        out["place"] = place
    return out


def _anchors(state: ServeState, r: dict) -> tuple[Any, Any, tuple[float, float, float] | None]:
    """(camera value, light value, object top (u, v, h)) computed through the session (cached)."""
    g = state.graph
    shadow = g.nodes[r["shadow"]] if r["shadow"] else None
    outs = [f"{r['light']}.light", f"{g.nodes[r['light']].inputs['camera']}"]
    if shadow is not None and "mask" in shadow.inputs and "fg_height" in shadow.inputs:
        outs += [str(shadow.inputs["mask"]), str(shadow.inputs["fg_height"])]
    values, _ = state.run(outs)
    cam, light = values[outs[1]], values[outs[0]]
    top = None
    if len(outs) == 4:
        top = object_top(values[outs[2]], values[outs[3]])
    return cam, light, top


def object_top(mask: np.ndarray, fg_height: np.ndarray) -> tuple[float, float, float] | None:
    """(u, v, h) [px] of the object's top: the middle of the mask's highest row, and its pixel height."""
    m = np.asarray(mask) > 0.5
    if not m.any():
        return None
    row = int(np.nonzero(m.any(axis=1))[0][0])
    cols = np.nonzero(m[row])[0]
    col = int(cols[len(cols) // 2])
    return float(col + 0.5), float(row + 0.5), float(fg_height[row, col])


def shadow_tip(cam, light, top) -> tuple[float, float] | None:
    """Image point (u, v) [px] where the shadow of ``top`` (u, v, h) falls on the
    ground plane, or None when there is none in front of the camera."""
    if top is None or top[2] <= 0:
        return None
    P, ok = cam.back_project(*top)
    if not ok:
        return None
    if light.kind == "directional":
        d = np.asarray(light.direction, dtype=np.float64)
        if d[1] <= 1e-9:
            return None
        T = P - d * (P[1] / d[1])
    else:
        L = np.asarray(light.position, dtype=np.float64)
        if L[1] <= P[1] + 1e-9:
            return None
        T = L + (P - L) * (L[1] / (L[1] - P[1]))
    uvh, D = cam.project(T)
    if not (D > 0 and np.all(np.isfinite(uvh))):
        return None
    return float(uvh[0]), float(uvh[1])


def describe(state: ServeState) -> dict:
    """Everything the UI draws handles for, in image pixels."""
    r = roles(state)
    out: dict[str, Any] = {"roles": r}
    g = state.graph
    if r["camera"]:
        v = state.registry.get(CAMERA).coerce_params(g.nodes[r["camera"]].params)
        w, h = v["width"], v["height"]
        if not (w and h):  # the camera takes its size from its image: ask the camera value
            cam = state.run([f"{r['camera']}.camera"])[0][f"{r['camera']}.camera"]
            w, h = cam.width, cam.height
        out["camera"] = {"width": w, "height": h, "horizon": v["horizon"]}
    if r.get("place"):
        values, _ = state.run([f"{r['place']}.alpha"])
        out["place"] = {**_values(state, r["place"]), "bbox": _bbox(values[f"{r['place']}.alpha"])}
    if r["background"]:
        out["background"] = _values(state, r["background"])
    if r["shadow"]:
        out["shadow"] = {"type": g.nodes[r["shadow"]].type}
    if r["light"] and "camera" in g.nodes[r["light"]].inputs:
        v = _values(state, r["light"])
        cam, light, top = _anchors(state, r)
        controls = dict(light.controls)
        out["light"] = {**v, "azimuth_deg": controls.get("azimuth"), "elevation_deg": controls.get("elevation"),
                        "top_uvh": list(top) if top else None,
                        "tip_uv": list(shadow_tip(cam, light, top) or []) or None}
    return out


def _bbox(alpha) -> list[float] | None:
    """[u0, v0, u1, v1] [px] of the pixels an alpha covers (> 0.5), edges of pixels."""
    m = np.asarray(alpha) > 0.5
    rows, cols = np.nonzero(m.any(axis=1))[0], np.nonzero(m.any(axis=0))[0]
    if not len(rows):
        return None
    return [float(cols[0]), float(rows[0]), float(cols[-1] + 1), float(rows[-1] + 1)]


def _values(state: ServeState, nid: str) -> dict:
    inst = state.graph.nodes[nid]
    v = state.registry.get(inst.type).coerce_params(inst.params)
    return {k: list(x) if isinstance(x, tuple) else x for k, x in v.items()}


def light_edits(state: ServeState, tip_uv=None, elevation=None) -> dict:
    """Param edits for a drag of the shadow tip to ``tip_uv`` and/or an elevation [deg]."""
    r = roles(state)
    if r["light"] is None:
        raise ServeError(400, "the graph has no pixgraph.Light node to drag")
    lid = r["light"]
    edits: dict[str, Any] = {}
    if tip_uv is not None:
        tip = _pair(tip_uv, "light_tip")
        cam, light, top = _anchors(state, r)
        if top is None:
            raise ServeError(400, "cannot drag the shadow tip: the shadow node has no cutout to find its top")
        edits = {f"{lid}.placement": "shadow_tip", f"{lid}.tip_uv": list(tip), f"{lid}.top_uvh": list(top)}
    if elevation is not None:
        if isinstance(elevation, bool) or not isinstance(elevation, (int, float)) or not math.isfinite(elevation):
            raise ServeError(400, f"light_elevation must be a number of degrees, got {elevation!r}",
                             field="light_elevation")
        el = float(elevation)
        v = _values(state, lid)
        if edits or v["placement"] == "shadow_tip":
            tip = edits.get(f"{lid}.tip_uv", v["tip_uv"])
            top = edits.get(f"{lid}.top_uvh", v["top_uvh"])
            cam, _, _ = _anchors(state, r)
            edits.update({f"{lid}.placement": "shadow_tip", f"{lid}.top_uvh": list(top),
                          f"{lid}.tip_uv": list(_tip_at_elevation(cam, tip, top, el))})
        else:
            edits[f"{lid}.elevation"] = el
    return edits


def _pair(v, name) -> tuple[float, float]:
    if (not isinstance(v, (list, tuple)) or len(v) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)):
        raise ServeError(400, f"{name} must be [u, v] in pixels, got {v!r}", field=name)
    return float(v[0]), float(v[1])


def _tip_at_elevation(cam, tip_uv, top_uvh, elevation_deg: float) -> tuple[float, float]:
    """The ground point, in the direction of ``tip_uv`` from below the top point, from
    which the top is seen at ``elevation_deg``."""
    if not 0.5 <= elevation_deg < 90.0:
        raise ServeError(400, f"light_elevation must be in [0.5, 90) degrees, got {elevation_deg}",
                         field="light_elevation")
    P, okp = cam.back_project(*top_uvh)
    T, okt = cam.back_project(tip_uv[0], tip_uv[1], 0.0)
    if not (okp and okt):
        raise ServeError(400, "the shadow tip or the object's top is above the horizon", field="light_elevation")
    foot = np.array([P[0], 0.0, P[2]])
    d = T - foot
    n = math.hypot(d[0], d[2])
    d = d / n if n > 1e-9 else np.array([0.0, 0.0, -1.0])
    new = foot + d * (P[1] / math.tan(math.radians(elevation_deg)))
    uvh, D = cam.project(new)
    if not (D > 0 and np.all(np.isfinite(uvh))):
        raise ServeError(400, f"at elevation {elevation_deg} the shadow tip leaves the ground in view",
                         field="light_elevation")
    return float(uvh[0]), float(uvh[1])
