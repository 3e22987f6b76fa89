// pixgraph serve: the page's start-up (see app.js for the map of the modules).
"use strict";

import {$, showError} from "./app.js";
import {setSaveName, wireFiles} from "./files.js";
import {cutoutWheel, drawHandles} from "./handles.js";
import {syncHeightTools, wireHeightTools} from "./heightedit.js";
import {wireHistory} from "./history.js";
import {buildPanel, syncControls, wireToolbar} from "./panel.js";
import {finalize, markBad, refresh, render, ui} from "./render.js";
import {setImageSize, view, wireView} from "./view.js";

let reRender = null;

// After a zoom, ask again for an image fine enough for the screen (cached: only re-encoded).
function onViewChange() {
  if (!ui.drag) drawHandles();
  clearTimeout(reRender);
  const need = Math.max(1, Math.floor(1 / (view.k * (window.devicePixelRatio || 1))));
  if (view.bitmap && need < view.scale) reRender = setTimeout(() => { if (!ui.drag) finalize({}); }, 250);
}

// The graph, its handles and a first final image: at start and after opening files.
// A graph a node refuses (its scene cannot be described) still gets its param panel, the
// node's error and its field marked, so it can be mended in the page.
async function load() {
  let failed = null;
  try {
    await refresh();
  } catch (err) {
    failed = err;
  }
  if (!ui.info) {           // not even the graph: nothing to show but the error
    showError(failed.message);
    return;
  }
  if (ui.scene.camera) setImageSize(ui.scene.camera.width, ui.scene.camera.height);
  // what the server proposes (the last name saved, the opened photo's, else the served file's):
  // a reload keeps it, so "save" does not write the user's graph over the served one
  if (!$("save-name").value) setSaveName(ui.info.save_as || ui.info.file.split(/[\\/]/).pop());
  buildPanel();
  syncControls();
  syncHeightTools();
  drawHandles();
  if (failed) {
    showError(failed.message);
    markBad(failed.data);
  } else {
    await render({}, "final");
  }
  document.body.dataset.synced = ui.shownSeq;
  document.body.dataset.ready = String(Number(document.body.dataset.ready || 0) + 1);
}

function main() {
  wireView();
  view.listeners.push(onViewChange);
  view.wheelHook = cutoutWheel;
  view.holdFit = () => !!ui.drag;      // re-fitted after the drag, when the scene comes (setImageSize)
  ui.onScene.push(() => {
    if (ui.scene.camera) setImageSize(ui.scene.camera.width, ui.scene.camera.height);
    syncControls();
    syncHeightTools();
    if (!ui.drag) drawHandles();   // never pull a handle from under the pointer
  });
  wireToolbar();
  wireHeightTools();
  wireHistory();
  wireFiles(load);
  load();
}

main();
