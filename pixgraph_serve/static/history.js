// Undo and redo. The server keeps the history of the graph's states (POST /api/undo,
// POST /api/redo; one step per user action: render.js sends each edit with its action's
// id, so a whole drag is one step), so it outlives a reload of the page. The toolbar's
// two buttons and Ctrl+Z / Ctrl+Shift+Z / Ctrl+Y (Cmd+Z / Cmd+Shift+Z on macOS; not
// while typing in a text field, where the field's own undo works) take a step back or
// forward; the answer is the restored graph (its panel drawn at once), then as after an
// edit a preview (large photos), the handles and the final.
"use strict";

import {$, api, showError} from "./app.js";
import {RELEASE_PIXELS, refresh, render, ui} from "./render.js";
import {view} from "./view.js";

const MAC = /Mac|iPhone|iPad/.test(navigator.platform || navigator.userAgent);
const KEY = MAC ? "\u2318" : "Ctrl+";
let queue = Promise.resolve();
let restoring = 0;                     // the newest undo or redo whose handles are still to come

const counts = () => (ui.info && ui.info.history) || {undo: 0, redo: 0};

export function syncHistory() {
  const h = counts();
  $("undo").disabled = !h.undo;
  $("redo").disabled = !h.redo;
  $("undo").title = `undo the last edit (${KEY}Z)` + (h.undo ? `: ${h.undo} step${h.undo > 1 ? "s" : ""}` : ": nothing to undo");
  $("redo").title = `redo the edit undone (${KEY}Shift+Z${MAC ? "" : " or Ctrl+Y"})` +
    (h.redo ? `: ${h.redo} step${h.redo > 1 ? "s" : ""}` : ": nothing to redo");
}

async function step(which) {
  if (ui.drag) return;                 // the pointer is still down: the drag has not ended
  await ui.editing;                    // the last edit's final: its edits are in the graph first
  let res;
  try {
    // the client and a new seq: this page's render still running (a final of the state being
    // left, never of an edit: those were waited for) is cancelled, not waited for
    res = await api("POST", `/api/${which}`, {client: ui.client, seq: ++ui.seq, scene: false});
  } catch (err) {
    if (err.status !== 409) showError(err.message);
    else $("status").textContent = `nothing to ${which}`;    // the server's history is the one that counts
    return;
  }
  ui.info = res.graph;
  // the restored graph's panel now; its handles when its scene comes (those drawn are the
  // state left: hidden meanwhile, so none is dragged from where it no longer is)
  ui.restoring = ++restoring;
  for (const f of ui.onScene) f();
  $("status").textContent = `${which === "undo" ? "undone" : "redone"}; rendering\u2026`;
  restored(restoring);               // not waited for: a next undo supersedes its renders
}

// The restored graph's image and handles, as after an edit: a large photo first gets a
// screen-sized preview (the scene may run its full-size nodes: seconds at 20 MP), then the
// scene (its handles) and the final. `id`: this undo's; a newer undo takes over.
async function restored(id) {
  const shown = () => {
    if (ui.restoring !== id) return;
    ui.restoring = 0;
    for (const f of ui.onScene) f();
  };
  if (view.W * view.H > RELEASE_PIXELS && await render({}, "preview", "release") === "stale") return shown();
  await refresh().catch((err) => showError(err.message));
  shown();
  if (restoring !== id) return;
  if (await render({}, "final") === true) await refresh().catch((err) => showError(err.message));
}

// Steps one after the other (a held Ctrl+Z repeats).
export function historyStep(which) {
  queue = queue.then(() => step(which)).catch((err) => showError(err.message));
  return queue;
}

function typing(el) {
  if (!el || el.isContentEditable || el.tagName === "TEXTAREA") return true;
  return el.tagName === "INPUT" && !["checkbox", "radio", "range", "button", "submit", "file", "color"].includes(el.type);
}

export function wireHistory() {
  window.pixgraphHistory = () => queue;   // for tests: settles when every step asked for is done
  ui.onScene.push(syncHistory);
  $("undo").addEventListener("click", () => historyStep("undo"));
  $("redo").addEventListener("click", () => historyStep("redo"));
  document.addEventListener("keydown", (ev) => {
    if (!(MAC ? ev.metaKey && !ev.ctrlKey : ev.ctrlKey && !ev.metaKey) || ev.altKey || typing(ev.target)) return;
    const key = ev.key.toLowerCase();
    const which = key === "z" ? (ev.shiftKey ? "redo" : "undo") : key === "y" && !MAC && !ev.shiftKey ? "redo" : null;
    if (!which) return;
    ev.preventDefault();
    historyStep(which);
  });
  syncHistory();
}
