// The render queue. Every edit is sent as one POST /api/render {edits, mode, scale,
// client, seq}: while a handle or slider moves, "preview" renders (hard shadow)
// go out one at a time, the newest edit waiting in `pending`; when the pointer
// stops a "final" render follows at once. Finals come back at about the screen's
// size (`scale`: the server box-filters the image by that integer factor).
// Previews run the whole graph at a working resolution (`work`: the engine scales
// the photo and every param in pixels) of at most PREVIEW_PIXELS while the pointer
// moves (a drag on a 20 MP photo computes ~0.5 MP) and come back as JPEG; on
// release a photo over RELEASE_PIXELS first gets one screen-sized (~1 MP) preview,
// then the final. Every render says where its light puts the shadow tip (the header
// X-Pixgraph-Tip), and the light's handle goes there. The server drops or cancels renders superseded by a newer seq
// (409), and the page never shows an image older than the one shown.
// Each render carries the id of the user action it belongs to (`action`): a drag's
// previews and its final share one, so the server's undo history (history.js) takes
// the whole drag back in one step.
"use strict";

import {$, api, request, showError} from "./app.js";
import {show, view} from "./view.js";

//: pixels a preview computes while the pointer moves, at most
const PREVIEW_PIXELS = 0.5e6;
//: photos larger than this get a screen-sized preview on release before the final [pixels]
export const RELEASE_PIXELS = 4e6;

export const ui = {
  client: Math.random().toString(36).slice(2), seq: 0, shownSeq: 0,
  inflight: false, pending: null, info: null, scene: null, savedSeq: 0,
  finalSeq: 0, statusLine: "",  // the final on its way (0: none), the last shown render's line
  drag: null, renders: 0, onScene: [],
  followTip: null,            // (tip u, v, top u, v) => moves the light's handle (handles.js)
  action: null, actions: 0,   // the user action in progress (previews sent, final to come), how many so far
  editing: Promise.resolve(), // the last finalize that carried edits (undo waits for it)
  restoring: 0,               // an undo whose graph's handles are still to come (history.js)
};

window.pixgraphShown = [];   // what was displayed, for tests and timing
window.pixgraphQueue = () => ({inflight: ui.inflight, pending: !!ui.pending, drag: !!ui.drag});

// The integer downscale that still gives at least one image pixel per screen pixel.
function screenScale() {
  const k = view.k * (window.devicePixelRatio || 1);
  return Math.max(1, Math.min(16, Math.floor(1 / Math.max(k, 1e-6))));
}

function merge(a, b) {
  return {...(a || {}), ...b, params: {...((a || {}).params || {}), ...(b.params || {})}};
}

// kind: "move" (while the pointer moves: <= PREVIEW_PIXELS), "release" (screen-sized).
// Returns true (shown, or a newer image was), "stale" (superseded) or false (failed).
export async function render(edits, mode, kind = "move") {
  const seq = ++ui.seq;
  if (mode === "final") {
    ui.finalSeq = seq;
    showStatus();
  }
  try {
    return await ask(seq, edits, mode, kind);
  } finally {
    if (ui.finalSeq === seq) {
      ui.finalSeq = 0;
      showStatus();
    }
  }
}

// The status line: the last shown render's line, led by "rendering the final..." while a
// final asked after it is on its way (seconds on a 20 MP photo: the previews' line alone
// said nothing of it). "saved PATH" (files.js) stays until a render asked after the save
// (a final asked before it may come after it) is asked or shown.
function showStatus() {
  if (Math.max(ui.finalSeq, ui.shownSeq) <= ui.savedSeq) return;
  const line = ui.statusLine;
  $("status").textContent = ui.finalSeq > ui.savedSeq
    ? `rendering the final\u2026${line ? ` (shown: ${line})` : ""}` : line;
}

async function ask(seq, edits, mode, kind) {
  // previews at least at half resolution, and while moving at most PREVIEW_PIXELS
  let scale = mode === "preview" ? Math.max(2, screenScale()) : screenScale();
  if (mode === "preview" && kind === "move") scale = Math.max(scale, Math.sqrt(view.W * view.H / PREVIEW_PIXELS));
  // previews run the whole graph at that working resolution (1/scale) and come as JPEG;
  // finals at full size, downscaled by the integer `scale`, as PNG
  const size = mode === "preview" ? {scale: 1, work: 1 / scale, format: "jpeg"} : {scale};
  const t0 = performance.now();
  let r;
  try {
    r = await request("/api/render", {method: "POST", headers: {"Content-Type": "application/json"},
      body: JSON.stringify({...edits, mode, ...size, output: "final", client: ui.client, seq})});
  } catch (err) {
    showError(`server unreachable: ${err.message}`);
    return false;
  }
  if (r.status === 409) return "stale";        // superseded by a newer render: dropped
  if (!r.ok) {
    const data = await r.json().catch(() => ({error: r.statusText}));
    showError(data.error);
    markBad(data);
    return false;
  }
  const blob = await r.blob();
  if (seq < ui.shownSeq) return true;           // a newer image is already shown
  ui.shownSeq = seq;
  const bmp = await createImageBitmap(blob);
  show(bmp, scale);
  ui.renders++;
  // where this render's light casts the top's shadow (X-Pixgraph-Tip, full-size px): the
  // light's handle follows a drag of the cutout with the previews, not only with the final
  const tip = (r.headers.get("X-Pixgraph-Tip") || "").split(",").map(Number);
  if (tip.length === 4 && tip.every(Number.isFinite) && ui.followTip) ui.followTip(tip);
  const ms = Math.round(performance.now() - t0);
  if (ui.finalSeq === seq) ui.finalSeq = 0;
  ui.statusLine = `${mode} ${bmp.width}x${bmp.height} (1/${round2(scale)}) in ${ms} ms; ` +
    `ran: ${r.headers.get("X-Pixgraph-Ran") || "nothing (cached)"}`;
  showStatus();
  const entry = {seq, mode, kind: mode === "preview" ? kind : "final", ms, scale, width: bmp.width,
                 height: bmp.height, server_ms: 1000 * Number(r.headers.get("X-Pixgraph-Seconds") || 0),
                 ran: r.headers.get("X-Pixgraph-Ran") || ""};
  window.pixgraphShown.push(entry);
  // painted: the next frame after the canvas was drawn (ms counts from the request, sent in
  // the pointer event's handler when no preview is in flight)
  requestAnimationFrame(() => { entry.painted_ms = Math.round(performance.now() - t0); });
  showError("");
  markBad(null);
  return true;
}

// The id of a new user action (unique across the page's reloads: the client id is new each time)
const newAction = () => `${ui.client}:${++ui.actions}`;

// Previews one at a time, the newest edit waiting; a final render goes out at once.
// The first preview of a drag opens its action; the final that ends it closes it.
export function preview(edits) {
  if (!ui.action) ui.action = newAction();
  ui.pending = merge(ui.pending, {...edits, action: ui.action});
  if (ui.inflight) return;
  const next = ui.pending;
  ui.pending = null;
  ui.inflight = true;
  render(next, "preview").finally(() => {
    ui.inflight = false;
    if (ui.pending && ui.drag) preview({});
  });
}

const round2 = (x) => Math.round(x * 100) / 100;

// The final render of one user action: the drag whose previews went out, or an edit of its
// own (a param, a toggle, a type switch). Undo waits for the last one that carried edits.
export function finalize(edits) {
  const action = ui.action || newAction();
  ui.action = null;
  const done = settle({...edits, action});
  if (Object.keys(edits).length) ui.editing = done.catch(() => false);
  return done;
}

async function settle(edits) {
  ui.pending = null;
  // a large photo's final takes seconds: first a sharper, screen-sized preview of the same
  // edits; not for a render that edits nothing (a zoom's finer image: the final is cached,
  // and a preview at a new working resolution would run the whole graph first)
  const edited = Object.keys(edits).some((k) => k !== "action");
  if (edited && view.W * view.H > RELEASE_PIXELS && await render(edits, "preview", "release") === "stale") return false;
  const ok = await render(edits, "final");
  // refused edits too: the handles go back where the graph has them
  if (ok !== "stale") await refresh().catch((err) => showError(err.message));
  return ok === true;
}

// Graph and handles from the server, after an edit has been applied. When the scene
// cannot be described (a node of the graph refuses its params, e.g. a served graph whose
// cutout lies off the photo), the graph and its param panel still come, without
// handles, and the scene's error is thrown after them: the param can be fixed here.
export async function refresh() {
  let notes, failed = null;
  [ui.info, ui.scene, notes] = await Promise.all([
    api("GET", "/api/graph"),
    api("GET", "/api/scene").catch((err) => { failed = err; return {roles: {}}; }),
    api("GET", "/api/notes").catch(() => ({notes: []}))]);
  showNotes(notes.notes);
  showLines("logs", notes.logs);
  for (const f of ui.onScene) f();
  document.body.dataset.synced = ui.shownSeq;
  if (failed) throw failed;
}

// Lines of text: the graph check's warnings under the image (#notes, e.g. a horizon
// above the cutout's foot) and what the nodes said in the last final (#logs, ctx.log:
// e.g. a height predictor's confidence, or that it fell back to another method), over
// the stage's bottom left corner: a method that says something and one that does not
// would otherwise resize the stage, and the image would jump at every switch.
function showLines(id, lines) {
  const el = $(id);
  el.replaceChildren(...(lines || []).map((n) => Object.assign(document.createElement("div"), {textContent: n})));
  el.hidden = !(lines && lines.length);
}

export function showNotes(notes) { showLines("notes", notes); }

export function markBad(data) {
  for (const el of document.querySelectorAll(".param .bad")) el.classList.remove("bad");
  if (data && data.node && data.field && data.field.startsWith("params.")) {
    const el = document.querySelector(`[data-param="${data.node}.${data.field.slice(7)}"]`);
    if (el) el.classList.add("bad");
  }
}
