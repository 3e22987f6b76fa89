// The handles over the image, drawn in screen pixels (the same size at any photo
// size and zoom) at image positions mapped through the view:
//   cutout (green): drag its box to move its foot, the round handle on top scales
//     it (or Shift + wheel over it), the toolbar's "flip" mirrors it;
//   horizon (pink): the Camera's horizon row;
//   wall (blue): the ends of the wall-floor line (BackgroundHeight's
//     junction_points), or the corner and the two slopes of the corner templates;
//   light (yellow): the shadow tip, where the shadow of the object's top falls (set
//     aside, a dotted line on to it, when the tip lies under another handle); it goes
//     where each render (a preview of a cutout drag too) says the tip is;
//   and whatever the modules in `extraHandles` draw (heightedit.js: the cutout's
//   contact points and tilt).
"use strict";

import {$} from "./app.js";
import {finalize, preview, ui} from "./render.js";
import {drawFinder} from "./horizon.js";
import {eventToImage, toScreen, view} from "./view.js";

const SVG = "http://www.w3.org/2000/svg";
export const R = 7;           // handle radius [screen px]

export const extraHandles = [];   // (scene, roles) => draws more handles (added by other modules)

export function svgEl(tag, attrs, parent) {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  (parent || $("handles")).appendChild(el);
  return el;
}

export function round(x, digits = 1) {
  const k = 10 ** digits;
  return Math.round(x * k) / k;
}

// A handle at image point `at`: `drag(p, start)` gets the pointer and the drag's
// start in image pixels and returns {edits, at} (where to draw it) or null.
export function handle(cls, id, at, drag, shape = "circle") {
  const attrs = {class: `handle ${cls}`, id};
  const el = shape === "circle" ? svgEl("circle", {...attrs, r: R})
    : svgEl("rect", {...attrs, width: 2 * R - 2, height: 2 * R - 2});
  const put = ([u, v]) => {
    const [x, y] = toScreen(u, v);
    if (shape === "circle") { el.setAttribute("cx", x); el.setAttribute("cy", y); }
    else { el.setAttribute("x", x - R + 1); el.setAttribute("y", y - R + 1); }
  };
  put(at);
  grab(el, drag, (res) => put(res.at));
  return el;
}

// Pointer drags on `el`: previews while it moves, the final when it is let go.
export function grab(el, drag, draw) {
  el.addEventListener("pointerdown", (ev) => {
    ev.preventDefault();
    ev.stopPropagation();
    // the default (a press moving the focus) is prevented: a panel field typed in last
    // keeps the focus, and syncControls leaves a focused field as it is, so it would go
    // on showing the typed value while the drag changes the param (a typed azimuth, then
    // a tip drag): leave the field, as a press elsewhere does
    const typed = document.activeElement;
    if (typed && typed !== document.body && typed.closest("#nodes")) typed.blur();
    el.setPointerCapture(ev.pointerId);
    ui.drag = {el, last: null, start: eventToImage(ev)};
  });
  el.addEventListener("pointermove", (ev) => {
    if (!ui.drag || ui.drag.el !== el) return;
    const res = drag(eventToImage(ev), ui.drag.start);
    if (!res) return;
    draw(res);
    ui.drag.last = res.edits;
    preview(res.edits);
  });
  const end = () => {
    if (!ui.drag || ui.drag.el !== el) return;
    const last = ui.drag.last;
    ui.drag = null;
    if (last) finalize(last);
    else drawHandles();
  };
  el.addEventListener("pointerup", end);
  el.addEventListener("pointercancel", end);
}

const param = (node, name, value) => ({params: {[`${node}.${name}`]: value}});

export function drawHandles() {
  const svg = $("handles");
  svg.replaceChildren();
  const box = svg.getBoundingClientRect();
  svgEl("rect", {class: "pan", x: 0, y: 0, width: box.width, height: box.height});
  if (ui.restoring) return;       // an undo's graph, whose scene is still to come (history.js)
  const s = ui.scene || {};
  const roles = s.roles || {};
  const {W, H} = view;
  const line = (cls, a, b) => {
    const [x1, y1] = toScreen(...a), [x2, y2] = toScreen(...b);
    return svgEl("line", {class: `guide ${cls}`, x1, y1, x2, y2});
  };
  if (s.place && roles.place) drawCutout(s.place, roles.place);
  if (s.camera && roles.camera) {
    const v = s.camera.horizon;
    line("horizon", [0, v], [W, v]);
    // at the visible image's left edge, kept on the stage when the horizon is outside it
    const sx = Math.max(view.ox, 0) + 3 * R, sy = toScreen(0, v)[1];
    const inside = Math.min(Math.max(sy, R), box.height - R);
    const el = handle("horizon", "horizon-handle", [0, 0], ([, y]) =>
      ({edits: param(roles.camera, "horizon", round(y)), at: [0, y]}), "rect");
    el.setAttribute("x", sx - R + 1);
    el.setAttribute("y", inside - R + 1);
    if (inside !== sy) el.classList.add("outside");
    el.addEventListener("pointermove", () => el.setAttribute("x", sx - R + 1));
  }
  if (s.background && roles.background) drawWall(s.background, roles.background, line);
  for (const f of extraHandles) f(s, roles);
  if (s.light && s.light.tip_uv) drawLight(s.light, line);
  drawFinder();
}

//: how far the light's handle is drawn from a tip that lies under another handle [screen px]
const LIGHT_ASIDE = 2.6 * R;

// The light's handle on the shadow tip, the dotted line from the object's top ending under
// it. Drawn after the others, to see where they are: a tip under another handle (a lying
// object of thickness ~0, whose top's square sits on its own shadow's tip; a light straight
// above the foot) puts the handle LIGHT_ASIDE screen px from it, on the shadow's side (else
// straight up), with the dotted line on to it: both handles whole and grabbable. The drag
// keeps that offset (the tip is the pointer less it), so the tip never jumps to the pointer.
function drawLight(light, line) {
  const tip = light.tip_uv, top = light.top_uvh ? light.top_uvh.slice(0, 2) : null;
  const [x, y] = toScreen(...tip);
  const under = [...$("handles").querySelectorAll(".handle")].some((el) => {
    const b = el.getBBox();
    return Math.hypot(b.x + b.width / 2 - x, b.y + b.height / 2 - y) < 2 * R + 2;
  });
  let off = [0, 0];                           // handle - tip [image px]
  if (under) {
    const d = top ? [tip[0] - top[0], tip[1] - top[1]] : [0, 0], n = Math.hypot(...d);
    const dir = n > 0.5 ? [d[0] / n, d[1] / n] : [0, -1];   // under half an image px: no direction
    off = [dir[0] * LIGHT_ASIDE / view.k, dir[1] * LIGHT_ASIDE / view.k];
  }
  const guide = top ? line("light", top, tip) : null;
  const aside = under ? line("light", tip, [tip[0] + off[0], tip[1] + off[1]]) : null;
  const el = handle("light", "light-handle", [tip[0] + off[0], tip[1] + off[1]], (p) => {
    const at = [p[0] - off[0], p[1] - off[1]], [tx, ty] = toScreen(...at), [px, py] = toScreen(...p);
    if (guide) {
      guide.setAttribute("x2", tx);
      guide.setAttribute("y2", ty);
    }
    if (aside) {
      aside.setAttribute("x1", tx);
      aside.setAttribute("y1", ty);
      aside.setAttribute("x2", px);
      aside.setAttribute("y2", py);
    }
    return {edits: {light_tip: at.map((v) => round(v))}, at: p};
  });
  if (under) el.classList.add("aside");
  // a render's tip and top (render.js, from the server: e.g. each preview of a cutout drag)
  // move the handle and its lines there; not while the handle itself is held
  ui.followTip = ([tu, tv, ou, ov]) => {
    if (!el.isConnected || (ui.drag && ui.drag.el === el)) return;
    const [tx, ty] = toScreen(tu, tv), [hx, hy] = toScreen(tu + off[0], tv + off[1]);
    el.setAttribute("cx", hx);
    el.setAttribute("cy", hy);
    if (guide) {
      const [ox, oy] = toScreen(ou, ov);
      for (const [k, v] of Object.entries({x1: ox, y1: oy, x2: tx, y2: ty})) guide.setAttribute(k, v);
    }
    if (aside) for (const [k, v] of Object.entries({x1: tx, y1: ty, x2: hx, y2: hy})) aside.setAttribute(k, v);
  };
}

function drawWall(bg, id, line) {
  const {W} = view;
  const pts = bg.junction_points || [];
  const walls = ["back_wall", "wall_corner", "two_corners"].includes(bg.kind);
  if (walls && pts.length >= 4) {
    const xy = [];
    for (let i = 0; i + 1 < pts.length; i += 2) xy.push([pts[i], pts[i + 1]]);
    svgEl("polyline", {class: "guide wall", points: xy.map((p) => toScreen(...p).join(",")).join(" ")});
    xy.forEach(([u, v], i) => handle("wall", `junction-${i}`, [u, v], (p) => {
      const next = pts.slice();
      next[2 * i] = round(p[0]);
      next[2 * i + 1] = round(p[1]);
      return {edits: param(id, "junction_points", next), at: p};
    }, "rect"));
  } else if (bg.kind === "back_wall") {
    // the row and slope form: its two ends become junction_points when dragged
    const at = (u) => [u, bg.junction_row + bg.junction_slope * (u - W / 2)];
    const ends = [at(0), at(W)];
    line("wall", ends[0], ends[1]);
    ends.forEach((end, i) => handle("wall", `junction-${i}`, end, (p) => {
      const next = ends.map((e) => e.map((x) => round(x)));
      next[i] = p.map((x) => round(x));
      return {edits: param(id, "junction_points", next.flat()), at: p};
    }, "rect"));
  } else if (bg.kind === "wall_corner" || bg.kind === "two_corners") {
    const [cu, cv] = bg.corner;
    const rx = bg.kind === "two_corners" ? bg.corner2 : bg.corner;
    const lu = 0.03 * W, ru = 0.97 * W;      // the slope handles, just inside the image's edges
    const lv = cv + bg.left_slope * (lu - cu), rv = rx[1] + bg.right_slope * (ru - rx[0]);
    const ends = [[0, cv - bg.left_slope * cu], [W, rx[1] + bg.right_slope * (W - rx[0])]];
    const pts2 = bg.kind === "two_corners" ? [ends[0], bg.corner, bg.corner2, ends[1]] : [ends[0], bg.corner, ends[1]];
    svgEl("polyline", {class: "guide wall", points: pts2.map((p) => toScreen(...p).join(",")).join(" ")});
    handle("wall", "corner-handle", [cu, cv], (p) => ({edits: param(id, "corner", p.map((x) => round(x))), at: p}), "rect");
    if (bg.kind === "two_corners") {
      handle("wall", "corner2-handle", bg.corner2, (p) => ({edits: param(id, "corner2", p.map((x) => round(x))), at: p}), "rect");
    }
    handle("wall", "left-wall-handle", [lu, lv], ([, v]) =>
      ({edits: param(id, "left_slope", round((v - cv) / (lu - cu), 4)), at: [lu, v]}));
    handle("wall", "right-wall-handle", [ru, rv], ([, v]) =>
      ({edits: param(id, "right_slope", round((v - rx[1]) / (ru - rx[0]), 4)), at: [ru, v]}));
  }
}

function drawCutout(pl, id) {
  if (!pl.bbox) return;
  const [u0, v0, u1, v1] = pl.bbox;
  const [fu, fv] = pl.foot;
  const [x0, y0] = toScreen(u0, v0), [x1, y1] = toScreen(u1, v1);
  const box = svgEl("rect", {class: "cutout-box on-cutout", id: "cutout-box", x: x0, y: y0,
                             width: Math.max(1, x1 - x0), height: Math.max(1, y1 - y0)});
  // the box: move the foot by the drag
  grab(box, (p, start) => {
    const foot = [round(fu + p[0] - start[0]), round(fv + p[1] - start[1])];
    return {edits: param(id, "foot", foot), at: foot, dx: p[0] - start[0], dy: p[1] - start[1]};
  }, (res) => followCutout([fu, fv], 1, res.dx, res.dy));
  handle("cutout on-cutout", "foot-handle", [fu, fv], (p) => {
    followCutout([fu, fv], 1, p[0] - fu, p[1] - fv);
    return {edits: param(id, "foot", p.map((x) => round(x))), at: p};
  }, "rect");
  // the top right corner: scale about the foot
  const top = [u1, v0];
  handle("cutout on-cutout", "scale-handle", top, (p) => {
    const s = scaledBy(pl, (fv - p[1]) / Math.max(1e-6, fv - v0));
    const k = s / pl.scale;
    followCutout([fu, fv], k, 0, 0);
    return {edits: param(id, "scale", s), at: [fu + (u1 - fu) * k, fv - (fv - v0) * k]};
  });
}

// While the cutout is moved (its box or foot: by du, dv image px) or scaled about its
// foot (by k), the handles and guides drawn on it (class "on-cutout": its box, foot and
// scale handles, heightedit.js's contact points, top and body) follow at once, before the
// drag's final brings the new scene: each point p goes to foot + (p - foot) k + (du, dv),
// handles keeping their size on the screen, lines their stroke. The held one places itself.
function followCutout(foot, k, du, dv) {
  const [fx, fy] = toScreen(...foot), tx = du * view.k + fx * (1 - k), ty = dv * view.k + fy * (1 - k);
  for (const el of $("handles").querySelectorAll(".on-cutout")) {
    if (ui.drag && el === ui.drag.el && el.id !== "cutout-box") continue;
    if (el.classList.contains("handle")) {
      const b = el.getBBox(), cx = b.x + b.width / 2, cy = b.y + b.height / 2;
      el.setAttribute("transform", `translate(${tx + cx * (k - 1)} ${ty + cy * (k - 1)})`);
    } else {
      el.setAttribute("transform", `translate(${tx} ${ty}) scale(${k})`);
    }
  }
}

function scaledBy(pl, factor) {
  return round(Math.min(100, Math.max(0.01, pl.scale * factor)), 4);
}

// Shift + wheel over the cutout scales it: previews while the wheel turns (the handles on
// the cutout following at once), then the final.
let wheelTimer = null, wheelScale = null;
export function cutoutWheel(ev, [u, v]) {
  const pl = ui.scene && ui.scene.place, id = ui.scene && ui.scene.roles.place;
  if (!ev.shiftKey || !pl || !pl.bbox) return false;
  const [u0, v0, u1, v1] = pl.bbox;
  if (u < u0 || u > u1 || v < v0 || v > v1) return false;
  wheelScale = scaledBy({scale: wheelScale ?? pl.scale}, Math.exp(-(ev.deltaY || ev.deltaX) * 0.001));
  ui.drag = ui.drag || {el: "wheel"};
  followCutout(pl.foot, wheelScale / pl.scale, 0, 0);   // its handles scale with it, as in a drag
  preview(param(id, "scale", wheelScale));
  clearTimeout(wheelTimer);
  wheelTimer = setTimeout(() => {
    const s = wheelScale;
    wheelScale = null;
    ui.drag = null;
    finalize(param(id, "scale", s));
  }, 300);
  return true;
}

export function flipCutout() {
  const pl = ui.scene && ui.scene.place;
  if (!pl) return;
  mirrorCutout(pl);
  finalize(param(ui.scene.roles.place, "flip", !pl.flip));
}

// "flip" mirrors the cutout about its foot's vertical: the handles and guides on it go
// there at once (the scale handle to the mirrored box's top right corner), before the
// final's scene draws them anew.
function mirrorCutout(pl) {
  if (!pl.bbox) return;
  const [fx] = toScreen(...pl.foot), [x0] = toScreen(pl.bbox[0], 0), [x1] = toScreen(pl.bbox[2], 0);
  for (const el of $("handles").querySelectorAll(".on-cutout")) {
    const old = el.getAttribute("transform") || "";
    if (el.classList.contains("handle")) {
      const t = el.transform.baseVal.consolidate();      // a drag's follow, its final not come yet
      const b = el.getBBox(), cx = b.x + b.width / 2 + (t ? t.matrix.e : 0);
      // the scale handle sits on the top right corner: the mirrored box's is the old top left's mirror
      const to = el.id === "scale-handle" ? 2 * fx - x0 - (x1 - cx) : 2 * fx - cx;
      el.setAttribute("transform", `translate(${to - cx} 0) ${old}`);
    } else {
      el.setAttribute("transform", `translate(${2 * fx} 0) scale(-1 1) ${old}`);
    }
  }
}
