// Undo and redo. The server keeps the history of the graph's states (POST /api/undo,
// POST /api/redo; one step per user action: render.js sends each edit with its action's
// id, so a whole drag is one step), so it outlives a reload of the page. The toolbar's
// two buttons and Ctrl+Z / Ctrl+Shift+Z / Ctrl+Y (Cmd+Z / Cmd+Shift+Z on macOS; not
// while typing in a text field, where the field's own undo works) take a step back or
// forward; the answer is the restored graph and its handles, drawn at once, then a
// preview (large photos) and the final as after any edit.
"use strict";

import {$, api, showError} from "./app.js";
import {finalize, ui} from "./render.js";

const MAC = /Mac|iPhone|iPad/.test(navigator.platform || navigator.userAgent);
const KEY = MAC ? "\u2318" : "Ctrl+";
let queue = Promise.resolve();

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
    res = await api("POST", `/api/${which}`, {client: ui.client, seq: ++ui.seq});
  } catch (err) {
    if (err.status !== 409) showError(err.message);
    else $("status").textContent = `nothing to ${which}`;    // the server's history is the one that counts
    return;
  }
  ui.info = res.graph;
  ui.scene = res.scene || {roles: {}};
  for (const f of ui.onScene) f();     // the panel, the toolbar, the handles of the restored graph
  $("status").textContent = `${which === "undo" ? "undone" : "redone"}; rendering\u2026`;
  if (res.scene_error) showError(res.scene_error.error);
  finalize({});                        // a preview (large photos), the final, the scene again
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
