"""The page's handles, from what nodes declare: where they are in the image, and the
param edits a drag of each means.

Nothing here names a node type. A node type declares ``handles`` (a class
attribute, a dict with a ``kind``):

- ``camera``: ``size`` (its width and height params) and ``row`` (the horizon param);
- ``background``: ``params``, the template params the page draws;
- ``light``: the light is dragged by its *shadow tip*, the ground point where the
  shadow of the object's top falls. ``tip``, ``top``, ``placement`` (set to
  ``tip_placement`` by a drag), ``elevation`` and (optional) ``azimuth`` name its
  params, ``camera`` its camera input, ``object`` the inputs (mask, pixel height) of
  the node it feeds that hold the object; the type also carries the geometry
  (``object_top``, ``shadow_tip``, ``tip_at_elevation``, and optional ``tip_angles``
  and ``tip_at_angles``: ops/light_screen.py and ops/lights.py in the node pack;
  ``tip_at_elevation.elevation_range``, optional, the [lo, hi) degrees it accepts,
  narrows the page's elevation slider in the tip placement). In
  the tip placement the light's angles are those seen from the object's top: a tip
  edit writes them into the ``azimuth``/``elevation`` params, and an edit of those
  params moves the tip (``light_edits``), so the params say what the light is;
- ``height_edit``: a hand edit of a cutout's pixel height (contact points, tilt,
  lying down); ``points``, ``mode``, ``tilt``, ``elevation``, ``lying``, ``lift`` name its
  params, ``mask`` the input with the coverage in its pixels, ``output`` its output;
  ``placed_by`` the params of the downstream node of kind ``place`` reading that output,
  which the type's ``frame(mask, *those)`` turns into the map from its pixels to the
  canvas (``[sx, tx, sy, ty]``: ``X = sx x + tx``, ``Y = sy y + ty``); ``top_point(mask,
  edited, tilt, elevation, lift)`` is the object's top ``(u, v, h, h0)`` for the tilt
  handle, ``foot_point(mask)`` the cutout's foot (where new contact points start);
  optional: ``depth`` and ``thickness`` name params of a body handle and of the top
  handle when lying, ``body_point(mask, edited, tilt, elevation, lift, depth)`` its point
  (asked for only while not lying; None: no body handle);
- any other kind (``shadow``): a node the page may switch between the types of
  that kind (``ServeState.alternatives``).

A graph without such nodes is served all the same, with the param panel only.

**One drag, one run.** A tip drag needs the object's top (from the mask and pixel
height upstream of the light) and the camera: the *anchors*. Every render that
runs those nodes anyway also fetches them (``piggyback``), and they are kept with
the upstream part of the graph they came from; the next drag uses them without a
run of its own as long as that part is unchanged (a light edit never changes it).
"""
from __future__ import annotations

import dataclasses
import math
import sys
import weakref
from typing import Any, Mapping

from pixgraph.graph import Graph

from .errors import ServeError
from .state import ServeState


def _kind(state: ServeState, type_id: str) -> str | None:
    h = state.handles(type_id)
    return h["kind"] if h else None


def roles(state: ServeState) -> dict[str, str | None]:
    """Node ids of the camera, light, background and the node the light feeds whose
    ``object`` inputs are wired (``shadow``); None when absent."""
    g = state.graph
    first = {}
    for nid, inst in g.nodes.items():
        first.setdefault(_kind(state, inst.type), nid)
    light = first.get("light")
    shadow = None
    if light is not None:
        obj = state.handles(g.nodes[light].type).get("object", ())
        shadow = next((nid for nid, inst in g.nodes.items()
                       if any(r.node == light for r in inst.inputs.values())
                       and all(k in inst.inputs for k in obj)), None)
    out = {"camera": first.get("camera"), "light": light, "background": first.get("background"),
           "shadow": shadow}
    if first.get("place") is not None:     # a cutout placed on the photo (own-photo graphs)
        out["place"] = first["place"]
    if first.get("height_edit") is not None:
        out["height_edit"] = first["height_edit"]
    return out


# -- anchors: the camera and the object's top, kept across requests ----------------------

@dataclasses.dataclass(frozen=True)
class Anchors:
    upstream: dict          # node id -> NodeInstance of every node the anchors depend on
    camera: Any             # the camera value
    top: tuple[float, float, float] | None   # the object's top (u, v, h) [px]
    made_from: tuple = ()   # weak references to the mask and pixel height the top came from


def _weak(x):
    try:
        return weakref.ref(x)
    except TypeError:
        return None


def _refs(state: ServeState, graph: Graph, r: dict) -> list[str] | None:
    """[camera ref, mask ref, pixel height ref] of the light's handle, or None."""
    if r["light"] is None or r["shadow"] is None:
        return None
    h = state.handles(graph.nodes[r["light"]].type)
    cam = graph.nodes[r["light"]].inputs.get(h.get("camera", "camera"))
    mask_in, height_in = h.get("object", ("mask", "fg_height"))
    shadow = graph.nodes[r["shadow"]]
    if cam is None:
        return None
    return [str(cam), str(shadow.inputs[mask_in]), str(shadow.inputs[height_in])]


def _upstream(graph: Graph, node_ids) -> dict:
    """Every node that ``node_ids`` depend on (themselves included), id -> instance."""
    out, stack = {}, list(node_ids)
    while stack:
        nid = stack.pop()
        if nid in out or nid not in graph.nodes:
            continue
        out[nid] = graph.nodes[nid]
        stack.extend(ref.node for ref in graph.nodes[nid].inputs.values())
    return out


def _node_of(ref: str) -> str:
    return ref.partition(".")[0]


def piggyback(state: ServeState, graph: Graph, outputs: list[str] | None) -> list[str]:
    """The anchor refs to fetch along with a run of ``outputs`` of ``graph``: those whose
    nodes the run needs anyway (so nothing more runs), always (a file read upstream may
    have changed on disk with the same params: the session's cache sees it, and so
    does the next drag)."""
    r = roles(state)
    refs = _refs(state, state.graph, r)
    if not refs or outputs is None:
        return []
    needed = _upstream(graph, [_node_of(str(graph.outputs.get(o, o))) for o in outputs])
    up = _upstream(graph, [_node_of(x) for x in refs])
    if not set(up) <= set(needed):
        return []
    return refs


def note(state: ServeState, graph: Graph, refs: list[str], values) -> None:
    """Keep the anchors a run fetched (``piggyback``'s refs) with the graph they came from."""
    if refs and all(x in values for x in refs):
        mask, height = values[refs[1]], values[refs[2]]
        old = state.anchors
        if old is not None and len(old.made_from) == 2 and all(
                w is not None and w() is v for w, v in zip(old.made_from, (mask, height))):
            top = old.top       # the same arrays as last time (the session's memory cache): same top
        else:
            light_cls = state.registry.get(state.graph.nodes[roles(state)["light"]].type).cls
            top = light_cls.object_top(mask, height)
        state.anchors = Anchors(_upstream(graph, [_node_of(x) for x in refs]), values[refs[0]], top,
                                (_weak(mask), _weak(height)))


def tip_refs(state: ServeState, graph: Graph, outputs: list[str], refs: list[str]) -> list[str]:
    """The refs ``shown_tip`` reads (the anchors' and the light's output) when a run of
    ``outputs`` of ``graph`` computes them anyway, at any working resolution (a preview's
    too); else none: nothing more runs for them. ``refs``: ``piggyback``'s for that run."""
    lid = roles(state)["light"]
    if not refs or lid not in _upstream(graph, [_node_of(str(graph.outputs.get(o, o))) for o in outputs]):
        return []
    return [*refs, f"{lid}.{state.registry.get(graph.nodes[lid].type).outputs[0].name}"]


def shown_tip(state: ServeState, graph: Graph, refs: list[str], values, scale: float) -> list[float] | None:
    """[tip u, v, top u, v] [full-size px]: where the light of a run of ``graph`` at working
    resolution ``scale`` casts the shadow of the object's top, and that top
    (``describe``'s ``tip_uv`` and ``top_uvh``, from that run's camera and light: a
    preview's handle follows a drag without a run of its own); None without one. The top
    is the anchors' (full-size, scaled) while the mask and pixel height they came from
    are unchanged (a light, camera or horizon edit); else, in a drag of the object, it is
    found on the run's scaled mask, to about 1 / ``scale`` px."""
    if not refs or not all(x in values for x in refs):
        return None
    light_cls = state.registry.get(state.graph.nodes[roles(state)["light"]].type).cls
    cam, mask, height, light = (values[x] for x in refs)
    a, up = state.anchors, _upstream(graph, [_node_of(x) for x in refs[1:3]])
    if a is not None and a.top is not None and all(a.upstream.get(k) == v for k, v in up.items()):
        top = tuple(x * scale for x in a.top)
    else:
        top = light_cls.object_top(mask, height)
    tip = light_cls.shadow_tip(cam, light, top)
    if tip is None:
        return None
    return [round(x / scale, 2) for x in (*tip, *top[:2])]


def anchors(state: ServeState, r: dict) -> Anchors:
    """The camera and object top for the current graph: kept from an earlier run when the
    nodes they depend on are unchanged, else from a run of those nodes only."""
    g = state.graph
    refs = _refs(state, g, r)
    if refs is None:
        raise ServeError(400, "the light's handle needs its camera input and a node it feeds with the object's "
                              "mask and pixel height")
    up = _upstream(g, [_node_of(x) for x in refs])
    if state.anchors is None or state.anchors.upstream != up:
        note(state, g, refs, state.run(refs))
    return state.anchors


def _camera(state: ServeState, r: dict):
    """The light's camera: the anchors' when they are fresh, else from a run of the camera
    node alone (a horizon drag need not run the object's mask and heights for it)."""
    g = state.graph
    refs = _refs(state, g, r)
    if refs is None:
        return anchors(state, r).camera          # says why there is none
    if state.anchors is not None and state.anchors.upstream == _upstream(g, [_node_of(x) for x in refs]):
        return state.anchors.camera
    return state.run(refs[:1])[refs[0]]


# -- what the page draws -------------------------------------------------------------------

def _bbox(coverage) -> list[float] | None:
    """[u0, v0, u1, v1] [px], pixel edges, of the pixels a coverage covers (> 0.5)."""
    import numpy as np

    m = np.asarray(coverage)
    m = (m[:, :, 0] if m.ndim == 3 else m) > 0.5
    rows, cols = np.nonzero(m.any(axis=1))[0], np.nonzero(m.any(axis=0))[0]
    if not len(rows):
        return None
    return [float(cols[0]), float(rows[0]), float(cols[-1] + 1), float(rows[-1] + 1)]


def _values(state: ServeState, nid: str) -> dict:
    inst = state.graph.nodes[nid]
    v = state.registry.get(inst.type).coerce_params(inst.params)
    return {k: list(x) if isinstance(x, tuple) else x for k, x in v.items()}


def describe(state: ServeState) -> dict:
    """Everything the page draws handles for, in image pixels."""
    r = roles(state)
    out: dict[str, Any] = {"roles": r}
    g = state.graph
    if r["camera"]:
        h, v = state.handles(g.nodes[r["camera"]].type), _values(state, r["camera"])
        w_name, h_name = h.get("size", ("width", "height"))
        w, hh = v.get(w_name), v.get(h_name)
        if not (w and hh):     # a camera that takes its size from its image: ask the camera value
            spec = state.registry.get(g.nodes[r["camera"]].type)
            cam = state.run([f"{r['camera']}.{spec.outputs[0].name}"])
            cam = next(iter(cam.values()))
            w, hh = getattr(cam, "width", w), getattr(cam, "height", hh)
        out["camera"] = {"width": w, "height": hh, "horizon": v.get(h.get("row"))}
    if r.get("place"):
        h = state.handles(g.nodes[r["place"]].type)
        ref = f"{r['place']}.{h.get('coverage', 'alpha')}"
        out["place"] = {**_values(state, r["place"]), "bbox": _bbox(state.run([ref])[ref])}
    if r["background"]:
        h, v = state.handles(g.nodes[r["background"]].type), _values(state, r["background"])
        names = h.get("params")
        out["background"] = {k: x for k, x in v.items() if names is None or k in names}
    if r.get("height_edit"):
        out["height_edit"] = _height_edit(state, r["height_edit"])
    if r["shadow"]:
        out["shadow"] = {"type": g.nodes[r["shadow"]].type,
                         "alternatives": state.alternatives(g.nodes[r["shadow"]].type)}
    if r["light"] and _refs(state, g, r):
        lid = r["light"]
        light_cls = state.registry.get(g.nodes[lid].type).cls
        v = _values(state, lid)
        a = anchors(state, r)
        light = state.run([f"{lid}.{state.registry.get(g.nodes[lid].type).outputs[0].name}"])
        light = next(iter(light.values()))
        controls = dict(getattr(light, "controls", ()))
        tip = light_cls.shadow_tip(a.camera, light, a.top)
        h = state.handles(g.nodes[lid].type)
        if v.get(h["placement"]) == h["tip_placement"] and "azimuth" in h and controls.get("azimuth") is not None:
            # the light's azimuth in its param's convention (350, not -10: ``_azimuth_in_convention``)
            controls["azimuth"] = _azimuth_in_convention(state, lid, h, controls["azimuth"])
        out["light"] = {**v, "azimuth_deg": controls.get("azimuth"), "elevation_deg": controls.get("elevation"),
                        "top_uvh": list(a.top) if a.top else None, "tip_uv": list(tip) if tip else None,
                        # what the panel shows for the angle params: the light's own (in the tip
                        # placement a graph may carry params it ignores), to 0.01 deg as a light
                        # edit writes them there; in the controls placement they are the params
                        "angles": {f"{lid}.{h[k]}": round(controls[k], 2) for k in ("azimuth", "elevation")
                                   if k in h and controls.get(k) is not None}
                        if v.get(h["placement"]) == h["tip_placement"] else {},
                        "elevation_range": _elevation_range(state, lid, h, light_cls,
                                                            v.get(h["placement"]) == h["tip_placement"])}
    return out


def _elevation_range(state: ServeState, lid: str, h: dict, light_cls, tip: bool) -> list:
    """[min, max] [deg] of the page's elevation slider: the ``elevation`` param's declared
    range (None where it declares none), from the handles' ``elevation_min`` up (a light
    placed by its angles is raised to that); in the tip placement narrowed to the elevations
    the tip geometry gives (``tip_at_elevation.elevation_range``, [lo, hi): the max is
    0.01 deg, the step the angles are written to, under its hi)."""
    spec = state.registry.get(state.graph.nodes[lid].type).param(h["elevation"])
    lo, hi = (spec.min, spec.max) if spec is not None else (None, None)
    if not tip and h.get("elevation_min") is not None:   # below it the light is raised to it
        lo = h["elevation_min"] if lo is None else max(lo, h["elevation_min"])
    ends = _tip_elevation_ends(light_cls)
    if tip and ends is not None:
        lo = ends[0] if lo is None else max(lo, ends[0])
        hi = ends[1] if hi is None else min(hi, ends[1])
    return [lo, hi]


def _tip_elevation_ends(light_cls):
    """(lo, hi) [deg]: the elevations the light type's tip geometry takes
    (``tip_at_elevation.elevation_range``, [lo, hi)) as they are written, to 0.01 deg:
    hi is 0.01 under the geometry's; None when the type declares no range."""
    rng = getattr(getattr(light_cls, "tip_at_elevation", None), "elevation_range", None)
    return None if rng is None else (rng[0], round(rng[1] - 0.01, 2))


def _height_edit(state: ServeState, nid: str) -> dict:
    """The hand edit's params, its frame on the canvas, the cutout's size and foot and
    the object's top, in the edit's pixels (see the module doc, ``height_edit``)."""
    g = state.graph
    inst = g.nodes[nid]
    spec = state.registry.get(inst.type)
    h, v = state.handles(inst.type), _values(state, nid)
    mask_ref = str(inst.inputs[h.get("mask", "mask")])
    out_ref = f"{nid}.{h.get('output', spec.outputs[0].name)}"
    vals = state.run([mask_ref, out_ref])
    mask, edited = vals[mask_ref], vals[out_ref]
    rows, cols = mask.shape[:2]
    place = next((pid for pid, p in g.nodes.items() if _kind(state, p.type) == "place"
                  and any(ref.node == nid for ref in p.inputs.values())), None)
    if place is not None:
        pv = _values(state, place)
        sx, tx, sy, ty = spec.cls.frame(mask, *(pv[k] for k in h.get("placed_by", ())))
    else:
        sx, tx, sy, ty = 1.0, 0.0, 1.0, 0.0
    box = _bbox(mask)
    if getattr(spec.cls, "foot_point", None) is not None and box is not None:
        foot = list(spec.cls.foot_point(mask[..., 0] if mask.ndim == 3 else mask))
    else:
        foot = [(box[0] + box[2]) / 2, box[3]] if box else [cols / 2, rows]
    names = {k: h.get(k, k) for k in ("points", "mode", "tilt", "elevation", "lying", "lift")}
    names.update({k: h[k] for k in ("depth", "thickness") if k in h})     # optional handles
    top = spec.cls.top_point(mask, edited, v[names["tilt"]], v[names["elevation"]], v[names["lift"]])
    body = None     # the body handle; none while lying (the foot depth does not apply then)
    if "depth" in names and not v[names["lying"]] and getattr(spec.cls, "body_point", None) is not None:
        body = spec.cls.body_point(mask, edited, v[names["tilt"]], v[names["elevation"]], v[names["lift"]],
                                   v[names["depth"]])
    # the nodes whose output the edit edits (not its coverage): the page opens their params
    sources = sorted({ref.node for port, ref in inst.inputs.items() if port != h.get("mask", "mask")})
    return {"id": nid, "params": names, "values": {k: v[p] for k, p in names.items()},
            "frame": [sx, tx, sy, ty], "size": [cols, rows], "foot": foot, "place": place,
            "top": list(top) if top else None, "body": list(body) if body else None, "sources": sources}


# -- what a drag means -------------------------------------------------------------------

def light_edits(state: ServeState, tip_uv=None, elevation=None, azimuth=None) -> dict:
    """Param edits for a drag of the shadow tip to ``tip_uv`` and/or a light elevation and
    azimuth [deg]. In the tip placement (or when ``tip_uv`` puts the light there) the
    angles are those of the light seen from the object's top: the tip moves to give them
    (the elevation alone keeps the tip's ground direction), and the light's
    ``azimuth``/``elevation`` params are set to the angles the light then has (to 0.01
    deg), so the graph's params, the panel and the light agree; in the controls
    placement they are the params."""
    r = roles(state)
    if r["light"] is None:
        raise ServeError(400, "the graph has no light with a draggable handle")
    lid = r["light"]
    h = state.handles(state.graph.nodes[lid].type)
    light_cls = state.registry.get(state.graph.nodes[lid].type).cls
    p_tip, p_top, p_place = (f"{lid}.{h[k]}" for k in ("tip", "top", "placement"))
    edits: dict[str, Any] = {}
    if tip_uv is not None:
        tip = _pair(tip_uv, "light_tip")
        top = anchors(state, r).top
        if top is None:
            raise ServeError(400, "cannot drag the shadow tip: the object's mask is empty", field="light_tip")
        edits = {p_place: h["tip_placement"], p_tip: list(tip), p_top: list(top)}
    for name, x in (("light_elevation", elevation), ("light_azimuth", azimuth)):
        if x is not None and not _finite(x):
            raise ServeError(400, f"{name} must be a number of degrees, got {_shown(x)}", field=name)
    if elevation is not None or azimuth is not None:
        v = _values(state, lid)
        if edits or v[h["placement"]] == h["tip_placement"]:
            tip = edits.get(p_tip, v[h["tip"]])
            top = edits.get(p_top, v[h["top"]])
            cam = anchors(state, r).camera
            if azimuth is None or getattr(light_cls, "tip_at_angles", None) is None:
                new = _tip_for(lambda: light_cls.tip_at_elevation(cam, tip, top, float(elevation)),
                               "light_elevation")
            elif elevation is None:      # the azimuth alone: the light keeps its elevation
                el = _tip_for(lambda: light_cls.tip_angles(cam, tip, top), "light_azimuth")[1]
                if el >= 90.0:
                    raise ServeError(400, "light_azimuth: the light is straight above the object's top (its "
                                          "shadow tip at the top's foot): its azimuth turns nothing; lower its "
                                          "elevation first", field="light_azimuth")
                new = _tip_for(lambda: light_cls.tip_at_angles(cam, top, float(azimuth), el), "light_azimuth")
            else:                        # both: the top alone places the light
                # refused: the elevation's fault when it fails at azimuth 0 too (the tip falls
                # back, away from the camera), else the azimuth's (it turns the tip out of view)
                try:
                    light_cls.tip_at_angles(cam, top, 0.0, float(elevation))
                    blame = "light_azimuth"
                except ValueError:
                    blame = "light_elevation"
                new = _tip_for(lambda: light_cls.tip_at_angles(cam, top, float(azimuth), float(elevation)), blame)
            edits.update({p_place: h["tip_placement"], p_top: list(top), p_tip: list(new)})
        else:
            if elevation is not None:
                edits[f"{lid}.{h['elevation']}"] = float(elevation)
            if azimuth is not None and "azimuth" in h:
                edits[f"{lid}.{h['azimuth']}"] = float(azimuth)
    if edits.get(p_place) == h["tip_placement"]:
        edits.update(_tip_angle_params(state, r, lid, h, light_cls, edits[p_tip], edits[p_top]))
    return edits


def _tip_for(geometry, field: str):
    """``geometry()`` (the light type's tip geometry); its ValueError as a 400 naming ``field``."""
    try:
        return geometry()
    except ValueError as e:
        raise ServeError(400, f"{field}: {e}", field=field) from None


def _tip_angle_params(state, r, lid, h, light_cls, tip, top) -> dict:
    """The light's ``azimuth`` and ``elevation`` params set to the angles the light at
    ``tip``/``top`` has (``tip_angles``, to 0.01 deg, the elevation kept inside the range
    the tip geometry takes back, ``_elevation_range``'s); none when the type has no such
    geometry or the tip has no light (the render says why)."""
    if getattr(light_cls, "tip_angles", None) is None:
        return {}
    try:
        az, el = light_cls.tip_angles(_camera(state, r), tip, top)
    except ValueError:
        return {}
    el = round(el, 2)
    ends = _tip_elevation_ends(light_cls)
    if ends is not None:     # a tip within 0.005 deg of the geometry's hi would round to hi itself
        el = min(max(el, ends[0]), ends[1])
    out = {f"{lid}.{h['elevation']}": el}
    if "azimuth" in h:
        out[f"{lid}.{h['azimuth']}"] = round(_azimuth_in_convention(state, lid, h, az), 2)
    return out


def _azimuth_in_convention(state: ServeState, lid: str, h: dict, az: float) -> float:
    """The azimuth ``az`` [deg] (the geometry gives (-180, 180]) written in the
    convention of the light's ``azimuth`` param: in [-180, 180) while the param is
    there, in [0, 360) once it is 180 or more, in [-360, 0) below -180, and within
    the param's declared min/max (the nearest turn that fits when that window's does
    not). A light typed as 350 deg keeps 350-ish, not -10; a drag across 0 then reads
    359.5, and jumps of the tip never walk the number round and round."""
    spec = state.registry.get(state.graph.nodes[lid].type).param(h["azimuth"])
    prev = _values(state, lid).get(h["azimuth"])
    prev = float(prev) if isinstance(prev, (int, float)) and math.isfinite(prev) else 0.0
    base = -180.0 if -180.0 <= prev < 180.0 else (0.0 if prev >= 180.0 else -360.0)
    a = base + (float(az) - base) % 360.0
    lo = -math.inf if spec is None or spec.min is None else spec.min
    hi = math.inf if spec is None or spec.max is None else spec.max
    if lo <= a <= hi:
        return a
    fits = [t for t in (a - 360.0, a + 360.0) if lo <= t <= hi]
    return min(fits, key=lambda t: abs(t - prev)) if fits else a


def light_angle_edits(state: ServeState, params) -> tuple[Any, dict, bool]:
    """``params`` (a request's ``{"node.param": value}`` or ``{"node": {...}}``) split into
    the rest, the light's azimuth/elevation ``{"azimuth": deg, "elevation": deg}`` found
    in it, and whether the rest edits the light or its camera. Set the rest, then ``angle_edits``: in
    the tip placement an angle typed in the panel moves the tip as the slider does (the
    placement does not read the params)."""
    r = roles(state) if isinstance(params, Mapping) else {"light": None}
    lid = r["light"]
    if lid is None:
        return params, {}, False
    h = state.handles(state.graph.nodes[lid].type)
    names = {h[k]: k for k in ("azimuth", "elevation") if k in h}
    rest, angles = {}, {}
    for key, value in params.items():
        nid, _, pname = str(key).partition(".")
        if pname and nid == lid and pname in names:
            angles[names[pname]] = value
        elif not pname and key == lid and isinstance(value, Mapping):
            inner = {k: x for k, x in value.items() if k not in names}
            angles.update({names[k]: x for k, x in value.items() if k in names})
            if inner:
                rest[key] = inner
        else:
            rest[key] = value
    # the light's own params, or its camera's (the horizon, the field of view: they turn
    # the light the tip makes, seen from the top)
    cam = state.graph.nodes[lid].inputs.get(h.get("camera", "camera"))
    moves = {lid, *(_upstream(state.graph, [_node_of(str(cam))]) if cam is not None else ())}
    touched = any(str(key).partition(".")[0] in moves for key in rest)
    return rest, angles, touched


def angle_edits(state: ServeState, angles: dict, touched: bool = False) -> dict:
    """Param edits for the light's angles split off by ``light_angle_edits``: the params
    themselves (checked as any param, errors naming them), and in the tip placement the
    tip that gives them; with no angles but other params of the light or its camera
    edited (``touched``: its tip, top or placement typed in the panel, the horizon
    dragged), in the tip placement the angles the light now has."""
    r = roles(state)
    lid = r["light"]
    if lid is None:
        return {}
    h = state.handles(state.graph.nodes[lid].type)
    light_cls = state.registry.get(state.graph.nodes[lid].type).cls
    plain = {f"{lid}.{h[k]}": x for k, x in angles.items()}
    v = _values(state, lid)
    if v[h["placement"]] != h["tip_placement"]:
        return plain
    if not angles:
        return _tip_angle_params(state, r, lid, h, light_cls, v[h["tip"]], v[h["top"]]) if touched else {}
    state.set_params(plain)              # checked (type, range) as any param, naming it
    v = _values(state, lid)
    if "azimuth" in angles and getattr(light_cls, "tip_at_angles", None) is None:
        raise ServeError(400, f"{h['azimuth']}: this light type cannot be turned by its azimuth in its tip "
                              "placement: drag its shadow tip", node=lid, field=f"params.{h['azimuth']}")
    try:
        return light_edits(state, **{k: v[h[k]] for k in angles})
    except ServeError as e:
        # light_edits names the request's light_azimuth/light_elevation: here the param typed
        field = str(e.where.get("field", ""))
        name = field.removeprefix("light_") if field.removeprefix("light_") in angles else next(iter(angles))
        message = e.message.removeprefix(f"{field}: ")
        raise ServeError(e.status, f"{h[name]} {v[h[name]]:g}: {message}", node=lid,
                         field=f"params.{h[name]}") from None


def _finite(x) -> bool:
    """A number a float holds: not a bool, NaN or an infinity, nor an integer beyond a
    float's range (``math.isfinite`` of one raised OverflowError: a 500)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and abs(x) <= sys.float_info.max


def _pair(v, name) -> tuple[float, float]:
    if not isinstance(v, (list, tuple)) or len(v) != 2 or not all(_finite(x) for x in v):
        raise ServeError(400, f"{name} must be [u, v] in pixels, got {_shown(v)}", field=name)
    return float(v[0]), float(v[1])


def _shown(v) -> str:
    """``repr(v)`` up to 100 characters (that of an integer over 4300 digits raises)."""
    try:
        text = repr(v)
    except ValueError:
        text = "a number too large to show"
    return text if len(text) <= 100 else text[:100] + "..."
