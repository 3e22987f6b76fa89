// The image in the window. The canvas and the handle layer both cover the stage
// (the part of the window left of the panel); the image is drawn at
// screen = offset + image * k. "fit" shows all of it (never enlarged past 1:1);
// with a margin for the handles on its edges; the wheel, a trackpad pinch or two fingers zoom about the pointer, a drag on
// the image (not on a handle) pans, and the toolbar's buttons fit, show 1:1 and zoom.
"use strict";

import {$} from "./app.js";

export const view = {
  W: 512, H: 512,           // the image's size [image px]
  k: 1, ox: 0, oy: 0,       // screen = (ox, oy) + image * k  [CSS px]
  bitmap: null, scale: 1,   // the shown image, and the factor it was downscaled by
  fitted: true,
  listeners: [],            // called after every zoom, pan or resize
  wheelHook: null,          // (event, [u, v]) -> true when it used the wheel event
  holdFit: null,            // () -> true while a handle is dragged: the stage resized, the view stays
};

export function toScreen(u, v) { return [view.ox + u * view.k, view.oy + v * view.k]; }
export function toImage(sx, sy) { return [(sx - view.ox) / view.k, (sy - view.oy) / view.k]; }

// Pointer event -> image pixels.
export function eventToImage(ev) {
  const box = $("stage").getBoundingClientRect();
  return toImage(ev.clientX - box.left, ev.clientY - box.top);
}

function stageSize() {
  const box = $("stage").getBoundingClientRect();
  return [Math.max(1, box.width), Math.max(1, box.height)];
}

export function setImageSize(W, H) {
  const changed = W !== view.W || H !== view.H;
  view.W = W;
  view.H = H;
  if (changed || view.fitted) fit();
}

export const MARGIN = 16;   // [screen px] around the fitted image: room for the handles on its edges

export function fit() {
  const [sw, sh] = stageSize();
  view.k = Math.min(1, (sw - 2 * MARGIN) / view.W, (sh - 2 * MARGIN) / view.H);
  view.ox = (sw - view.W * view.k) / 2;
  view.oy = (sh - view.H * view.k) / 2;
  view.fitted = true;
  changed();
}

export function zoomAt(sx, sy, factor) {
  const [sw, sh] = stageSize();
  const kmin = Math.min(1, sw / view.W, sh / view.H) / 4;
  const k = Math.min(32, Math.max(kmin, view.k * factor));
  const [u, v] = toImage(sx, sy);
  view.k = k;
  view.ox = sx - u * k;
  view.oy = sy - v * k;
  view.fitted = false;
  changed();
}

export function zoomCentre(factor) {
  const [sw, sh] = stageSize();
  zoomAt(sw / 2, sh / 2, factor);
}

export function oneToOne() {
  const [sw, sh] = stageSize();
  zoomAt(sw / 2, sh / 2, 1 / view.k);
}

function changed() {
  draw();
  for (const f of view.listeners) f();
}

// Show a new image: `scale` is the factor the server downscaled it by.
export function show(bitmap, scale) {
  if (view.bitmap && view.bitmap.close) view.bitmap.close();
  view.bitmap = bitmap;
  view.scale = scale;
  draw();
}

export function draw() {
  const canvas = $("view");
  const [sw, sh] = stageSize();
  const dpr = window.devicePixelRatio || 1;
  const bw = Math.round(sw * dpr), bh = Math.round(sh * dpr);
  if (canvas.width !== bw || canvas.height !== bh) { canvas.width = bw; canvas.height = bh; }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.clearRect(0, 0, bw, bh);
  if (!view.bitmap) return;
  ctx.setTransform(dpr * view.k, 0, 0, dpr * view.k, dpr * view.ox, dpr * view.oy);
  ctx.imageSmoothingEnabled = view.k * view.scale < 2;   // pixels stay sharp when zoomed far in
  ctx.imageSmoothingQuality = "high";
  ctx.drawImage(view.bitmap, 0, 0, view.W, view.H);   // whatever size it came at, it is the whole image
}

// The shown image at its own resolution as a PNG data URL (tests read its pixels).
export function imageDataURL() {
  const b = view.bitmap;
  if (!b) return null;
  const c = document.createElement("canvas");
  c.width = b.width;
  c.height = b.height;
  c.getContext("2d").drawImage(b, 0, 0);
  return c.toDataURL("image/png");
}

export function wireView() {
  const stage = $("stage");
  const pointers = new Map();
  let pan = null, pinch = null;
  stage.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    if (view.wheelHook && view.wheelHook(ev, eventToImage(ev))) return;
    const box = stage.getBoundingClientRect();
    const unit = ev.deltaMode === 1 ? 16 : ev.deltaMode === 2 ? 400 : 1;
    zoomAt(ev.clientX - box.left, ev.clientY - box.top, Math.exp(-ev.deltaY * unit * (ev.ctrlKey ? 0.01 : 0.0015)));
  }, {passive: false});
  // drags that start on the image itself (the handle layer's background) pan; two pinch
  const bg = $("handles");
  bg.addEventListener("pointerdown", (ev) => {
    if (ev.target !== bg && !ev.target.classList.contains("pan")) return;
    bg.setPointerCapture(ev.pointerId);
    pointers.set(ev.pointerId, [ev.clientX, ev.clientY]);
    if (pointers.size === 1) pan = {x: ev.clientX, y: ev.clientY};
    if (pointers.size === 2) {
      const [a, b] = [...pointers.values()];
      pinch = {d: Math.hypot(a[0] - b[0], a[1] - b[1])};
      pan = null;
    }
  });
  bg.addEventListener("pointermove", (ev) => {
    if (!pointers.has(ev.pointerId)) return;
    pointers.set(ev.pointerId, [ev.clientX, ev.clientY]);
    if (pinch && pointers.size === 2) {
      const [a, b] = [...pointers.values()];
      const d = Math.hypot(a[0] - b[0], a[1] - b[1]);
      const box = stage.getBoundingClientRect();
      zoomAt((a[0] + b[0]) / 2 - box.left, (a[1] + b[1]) / 2 - box.top, d / Math.max(1, pinch.d));
      pinch.d = d;
    } else if (pan) {
      view.ox += ev.clientX - pan.x;
      view.oy += ev.clientY - pan.y;
      pan = {x: ev.clientX, y: ev.clientY};
      view.fitted = false;
      changed();
    }
  });
  const up = (ev) => {
    pointers.delete(ev.pointerId);
    if (pointers.size < 2) pinch = null;
    if (pointers.size === 0) pan = null;
  };
  bg.addEventListener("pointerup", up);
  bg.addEventListener("pointercancel", up);
  $("zoom-fit").addEventListener("click", fit);
  $("zoom-1").addEventListener("click", oneToOne);
  $("zoom-in").addEventListener("click", () => zoomCentre(1.5));
  $("zoom-out").addEventListener("click", () => zoomCentre(1 / 1.5));
  // a fitted view re-fits when the stage changes size (the window, or a message under the
  // image), except while a handle is dragged: the image would move under the pointer
  new ResizeObserver(() => (view.fitted && !(view.holdFit && view.holdFit()) ? fit() : changed())).observe(stage);
  window.pixgraphView = {toScreen, toImage, imageDataURL, state: view};
}
