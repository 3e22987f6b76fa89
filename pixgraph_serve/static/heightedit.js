// The hand edit of the cutout's pixel height (a node declaring handles of kind
// "height_edit", e.g. pixgraph.PixelHeightEdit), drawn over the placed cutout:
//   contact points (orange): where the object touches the ground, in the cutout's
//     pixels mapped to the image by the scene's `frame`; a drag from the hollow
//     handle just under the cutout's foot adds one (or "+ contact", then a press on the
//     image), "- contact" removes the last; each point is dragged on its own;
//   tilt (orange square): on the object's top, a guide down to the ground under it;
//     pulled up the object stands taller, pushed down it leans back (tilt, about the
//     contact); lying down, the same square sets the thickness (how tall it lies);
//   foot depth (orange ring, when the node declares `depth`): on the body (the pixel
//     nearest the cutout's centroid), a guide down to the ground under it; pulled up
//     the body's ground moves toward the camera (the body is taller), pushed down
//     behind the contact (shorter);
//   "lying down" and "upright" (contact_mode) toggles in the toolbar.
// The shadow follows every drag through the page's preview renders.
"use strict";

import {$} from "./app.js";
import {extraHandles, handle, R, round, svgEl} from "./handles.js";
import {finalize, ui} from "./render.js";
import {eventToImage, toScreen, view} from "./view.js";

//: how far under the cutout's foot the "new contact" ring is drawn [screen px]
const GHOST_BELOW = 2.6 * R;

let adding = false;

const edit = () => ui.scene && ui.scene.height_edit;
const param = (e, name, value) => ({params: {[`${e.id}.${e.params[name]}`]: value}});

// cutout pixels <-> image pixels through the placement's similarity [sx, tx, sy, ty]
const toCanvas = (e, [x, y]) => [e.frame[0] * x + e.frame[1], e.frame[2] * y + e.frame[3]];
function toCutout(e, [u, v]) {
  const [w, h] = e.size;
  const x = (u - e.frame[1]) / e.frame[0], y = (v - e.frame[3]) / e.frame[2];
  return [round(Math.min(w, Math.max(0, x))), round(Math.min(h, Math.max(0, y)))];
}

function pairs(flat) {
  const out = [];
  for (let i = 0; i + 1 < flat.length; i += 2) out.push([flat[i], flat[i + 1]]);
  return out;
}

// The tilt [deg] that gives the top (height h0 before tilt) the height `target` [cutout px]:
// tan(tilt) = (h0 / (target - lift) - 1) / tan(elevation), within +-80 deg and at most
// MAX_GAIN times taller (pixgraph_nodes.ops.height_edit.tilt_for_height).
const MAX_GAIN = 10;
function tiltFor(h0, target, lift, elevation) {
  const deg = 180 / Math.PI, ta = Math.tan(elevation / deg), want = target - lift;
  if (h0 <= 0 || ta < 1e-9) return 0;
  if (want <= 1e-6) return 80;
  const lowest = Math.max(-80, Math.atan((1 / MAX_GAIN - 1) / ta) * deg);
  return round(Math.min(80, Math.max(lowest, Math.atan((h0 / want - 1) / ta) * deg)), 2);
}

// The tilt's height gain 1 / (1 + tan(tilt) tan(elevation)) (ops.height_edit.tilt_gain)
function gain(vals) {
  const deg = Math.PI / 180;
  return 1 / (1 + Math.tan((vals.tilt || 0) * deg) * Math.tan((vals.elevation || 0) * deg));
}

// The foot depth [px] that gives the body point (height h0 before it) the height
// `target`: (target - lift) / gain - h0 within [-h0 / 2, h0 / 2] (ops.height_edit.depth_for_height).
function depthFor(h0, target, vals) {
  const g = gain(vals);
  if (h0 <= 0 || g <= 0) return 0;
  return round(Math.min(h0 / 2, Math.max(-h0 / 2, (target - (vals.lift || 0)) / g - h0)), 2);
}

// a vertical drag of a point at (u, v) whose ground point is `h` below it [cutout px]:
// the guide follows, `value(target)` gives the param edit for the new height
function heightHandle(e, cls, id, [u, v, h], shape, value) {
  const at = toCanvas(e, [u, v]);
  const foot = (hh) => toScreen(...toCanvas(e, [u, v + hh]));
  const [x1, y1] = toScreen(...at), [x2, y2] = foot(h);
  const guide = svgEl("line", {class: `guide ${cls}`, x1, y1, x2, y2});
  return handle(cls, id, at, ([, y], start) => {
    const target = h + (start[1] - y) / e.frame[2];    // the point's new height [cutout px]
    guide.setAttribute("y2", foot(target)[1]);
    return {edits: value(target), at: [at[0], y]};
  }, shape);
}

// Where the "new contact" ring goes [image px]: GHOST_BELOW screen px under the foot, or,
// when that is off the stage's bottom edge (a foot on the photo's bottom edge, a view
// panned down to the foot), slid round the foot on the same circle until the whole ring
// (radius R, stroke 2.5) is on the stage: still clear of the foot square, toward the
// stage's middle.
function ghostAt([fu, fv]) {
  const [x, y] = toScreen(fu, fv);
  const box = $("handles").getBoundingClientRect();
  const lowest = box.height - R - 2;                  // the ring's lowest centre on the stage
  if (y + GHOST_BELOW <= lowest) return [fu, fv + GHOST_BELOW / view.k];
  const dy = Math.max(-GHOST_BELOW, lowest - y);
  const dx = Math.sqrt(GHOST_BELOW ** 2 - dy ** 2) * (x > box.width / 2 ? -1 : 1);
  return [fu + dx / view.k, fv + dy / view.k];
}

function drawHeightEdit(s) {
  const e = s.height_edit;
  if (!e) return;
  const vals = e.values;
  const pts = pairs(vals.points || []);
  const lying = !!vals.lying;
  // the line through the contact points (two or more), sorted along u; redrawn while a
  // point is held, so it follows the pointer before the drag's final comes
  const line = svgEl("polyline", {class: `guide contact on-cutout${lying ? " off" : ""}`});
  const drawLine = (flat) => {
    const at = pairs(flat).sort((a, b) => a[0] - b[0]).map((p) => toScreen(...toCanvas(e, p)).join(","));
    line.setAttribute("points", at.length > 1 ? at.join(" ") : "");
  };
  drawLine(vals.points || []);
  if (!lying) {
    // just under the cutout's foot (GHOST_BELOW screen px, clear of the cutout's own foot
    // square, which moves the cutout): dragged from there, a new contact point where it is
    // let go (the first replaces the input's implicit contact, the lowest row; more: a
    // line, several feet)
    const el = handle("contact ghost on-cutout", "contact-new", ghostAt(toCanvas(e, e.foot)), (p) => {
      const next = [...(vals.points || []), ...toCutout(e, p)];
      drawLine(next);
      return {edits: param(e, "points", next), at: p};
    });
    el.setAttribute("title", "drag from the cutout's foot to where it touches the ground: a contact point");
  }
  pts.forEach((pt, i) => {
    const el = handle(`contact on-cutout${lying ? " off" : ""}`, `contact-${i}`, toCanvas(e, pt), (p) => {
      const next = (vals.points || []).slice();
      [next[2 * i], next[2 * i + 1]] = toCutout(e, p);
      drawLine(next);
      return {edits: param(e, "points", next), at: p};
    });
    el.setAttribute("title", "a contact point: where the object touches the ground");
  });
  if (e.top && !lying) {
    // the tilt handle on the object's top, a guide down to the ground under it: pulled up
    // the object stands taller (leans toward the camera), pushed down shorter (leans back)
    const [tu, tv, h, h0] = e.top;
    const el = heightHandle(e, "tilt on-cutout", "tilt-handle", [tu, tv, h], "rect",
      (target) => param(e, "tilt", tiltFor(h0, target, vals.lift || 0, vals.elevation)));
    el.setAttribute("title", "the object's top: drag up = taller (leaning forward), down = shorter (leaning back)");
  } else if (e.top && lying && e.params.thickness) {
    // lying: the same square sets how tall the object lies (its thickness; at least 0.01 px,
    // ops.height_edit.MIN_THICKNESS: 0 means the default, half the median column extent)
    const [tu, tv, h] = e.top;
    const el = heightHandle(e, "tilt on-cutout", "tilt-handle", [tu, tv, h], "rect", (target) => param(e, "thickness",
      Math.max(0.01, round((target - (vals.lift || 0)) / gain(vals), 2))));
    el.setAttribute("title", "lying: the object's top; drag up = thicker, down = flatter");
  }
  if (e.body && !lying && e.params.depth) {
    // the body's ground point: pulled up, the ground under the body lies in front of
    // the contact (the body is taller), pushed down, behind it
    const [bu, bv, h, h0] = e.body;
    const el = heightHandle(e, "depth on-cutout", "depth-handle", [bu, bv, h], "circle",
      (target) => param(e, "depth", depthFor(h0, target, vals)));
    el.setAttribute("title", "the body: drag up = its ground lies in front of the contact (taller), "
      + "down = behind it (shorter)");
  }
}

export function syncHeightTools() {
  const e = edit();
  $("height-tools").hidden = !e;
  if (!e) return;
  $("lying").checked = !!e.values.lying;
  $("upright").checked = e.values.mode === "upright";
  $("remove-contact").disabled = !(e.values.points || []).length;
  $("add-contact").classList.toggle("on", adding);
}

export function wireHeightTools() {
  extraHandles.push(drawHeightEdit);
  $("lying").addEventListener("change", () => finalize(param(edit(), "lying", $("lying").checked)));
  $("upright").addEventListener("change", () =>
    finalize(param(edit(), "mode", $("upright").checked ? "upright" : "shift")));
  $("remove-contact").addEventListener("click", () => {
    const e = edit();
    finalize(param(e, "points", (e.values.points || []).slice(0, -2)));
  });
  $("add-contact").addEventListener("click", () => { adding = !adding; syncHeightTools(); });
  // armed by "+ contact": the next press on the image adds a contact point there
  $("handles").addEventListener("pointerdown", (ev) => {
    const e = edit();
    if (!adding || !e) return;
    ev.preventDefault();
    ev.stopPropagation();
    adding = false;
    syncHeightTools();
    finalize(param(e, "points", [...(e.values.points || []), ...toCutout(e, eventToImage(ev))]));
  }, true);
}
