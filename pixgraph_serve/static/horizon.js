// "find horizon": two lines the user lays along lines that are parallel on the floor
// (floorboards, tile joints, the edges of a rug or a table); where they meet is on the
// horizon, and "set horizon" makes that row the camera's horizon (docs/own-photo.md,
// "The horizon"). The four ends are dragged locally: nothing renders until it is set.
"use strict";

import {$} from "./app.js";
import {finalize, ui} from "./render.js";
import {eventToImage, toScreen, view} from "./view.js";

const SVG = "http://www.w3.org/2000/svg";
export const finder = {on: false, lines: null, size: null};

// Where lines a and b (each two image points) meet, or null when they are parallel.
export function meet(a, b) {
  const [[x1, y1], [x2, y2]] = a, [[x3, y3], [x4, y4]] = b;
  const d = (x1 - x2) * (y3 - y4) - (y1 - y2) * (x3 - x4);
  if (Math.abs(d) < 1e-9) return null;
  const t = ((x1 - x3) * (y3 - y4) - (y1 - y3) * (x3 - x4)) / d;
  return [x1 + t * (x2 - x1), y1 + t * (y2 - y1)];
}

export function toggleFinder() {
  finder.on = !finder.on;
  $("find-horizon").classList.toggle("on", finder.on);
  drawFinder();
}

// The lines laid on the floor of the image shown; again on an image of another size (a
// photo opened since, whether the finder was on or off meanwhile): the lines were in
// the first image's pixels.
function layLines() {
  const {W, H} = view;
  if (!finder.lines || finder.size[0] !== W || finder.size[1] !== H) {
    finder.lines = [[[0.25 * W, 0.95 * H], [0.35 * W, 0.7 * H]], [[0.75 * W, 0.95 * H], [0.65 * W, 0.7 * H]]];
    finder.size = [W, H];
  }
}

function el(tag, attrs, parent) {
  const e = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  parent.appendChild(e);
  return e;
}

// Drawn on the handle layer after the other handles (drawHandles calls it).
export function drawFinder() {
  const old = $("finder");
  if (old) old.remove();
  $("horizon-apply").hidden = !finder.on;
  if (!finder.on) return;
  layLines();
  const g = el("g", {id: "finder"}, $("handles"));
  const guides = finder.lines.map(() => el("line", {class: "guide finder"}, g));
  const mark = el("circle", {class: "finder-meet", r: 5}, g);
  const update = () => {
    const m = meet(...finder.lines);
    finder.lines.forEach(([p], i) => {   // from the line's first end through the other, to where they meet
      const [x1, y1] = toScreen(...p);
      const end = m && (m[1] < p[1]) ? m : finder.lines[i][1];
      const [x2, y2] = toScreen(...end);
      Object.entries({x1, y1, x2, y2}).forEach(([k, v]) => guides[i].setAttribute(k, v));
    });
    const ok = m && m[1] < Math.max(finder.lines[0][0][1], finder.lines[1][0][1]);
    mark.setAttribute("visibility", ok ? "visible" : "hidden");
    if (ok) { const [x, y] = toScreen(...m); mark.setAttribute("cx", x); mark.setAttribute("cy", y); }
    $("horizon-apply").disabled = !ok;
    $("horizon-apply").textContent = ok ? `set horizon (row ${Math.round(m[1])})` : "set horizon";
    finder.row = ok ? m[1] : null;
  };
  finder.lines.forEach((line, i) => line.forEach((p, j) => {
    const pin = el("rect", {class: "handle finder", id: `finder-${i}-${j}`, width: 10, height: 10}, g);
    const put = () => { const [x, y] = toScreen(...finder.lines[i][j]); pin.setAttribute("x", x - 5); pin.setAttribute("y", y - 5); };
    put();
    pin.addEventListener("pointerdown", (ev) => { ev.preventDefault(); ev.stopPropagation(); pin.setPointerCapture(ev.pointerId); });
    pin.addEventListener("pointermove", (ev) => {
      if (!pin.hasPointerCapture(ev.pointerId)) return;
      finder.lines[i][j] = eventToImage(ev);
      put();
      update();
    });
  }));
  update();
}

export function applyFinder() {
  const cam = ui.scene && ui.scene.roles.camera;
  if (cam && finder.row != null) finalize({params: {[`${cam}.horizon`]: Math.round(finder.row * 10) / 10}});
}
