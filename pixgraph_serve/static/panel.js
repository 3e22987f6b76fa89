// The toolbar (shadow method, light sliders, flip) and the param panel: every
// node, its inputs and a field for every param, from the node declarations.
"use strict";

import {$, upload, showError} from "./app.js";
import {flipCutout} from "./handles.js";
import {applyFinder, toggleFinder} from "./horizon.js";
import {finalize, preview, ui} from "./render.js";

export function syncControls() {
  if (ui.info && panelKey() !== builtFor) buildPanel(false);   // a node switched type (or an undo did)
  const s = ui.scene || {};
  const light = s.light;
  for (const id of ["elevation", "softness"]) $(id).disabled = !light;
  if (light) {
    // the slider's ends: the elevation param's declared range (in the shadow_tip placement
    // what the tip can give), so the slider reaches what the panel's field takes; set
    // before the value, which a range input clamps to its ends
    const [lo, hi] = light.elevation_range || [];
    if (lo != null) $("elevation").min = lo;
    if (hi != null) $("elevation").max = hi;
    if (!(ui.drag && ui.drag.el === $("elevation"))) $("elevation").value = light.elevation_deg ?? light.elevation;
    $("elevation-value").textContent = Number($("elevation").value).toFixed(1);
    $("softness").value = light.radius;
    $("softness-value").textContent = Number(light.radius).toFixed(2);
  }
  const shadowType = s.shadow && s.shadow.type;
  for (const r of document.querySelectorAll("input[name=method]")) {
    r.checked = r.value === shadowType;
    r.disabled = !shadowType;
  }
  $("flip").disabled = !s.place;
  $("find-horizon").disabled = !s.camera;
  for (const node of ui.info.nodes) {
    for (const [name, value] of Object.entries(node.values)) {
      const el = document.querySelector(`[data-param="${node.id}.${name}"]`);
      if (el && document.activeElement !== el) setField(el, value);
    }
  }
  // the light's azimuth and elevation as the light has them (the slider's value too): in
  // the shadow_tip placement the tip places the light, and a graph may carry params it ignores
  for (const [key, value] of Object.entries((light && light.angles) || {})) {
    const el = document.querySelector(`[data-param="${key}"]`);
    if (el && document.activeElement !== el) setField(el, value);
  }
}

function setField(el, value) {
  if (el.type === "checkbox") el.checked = !!value;
  else el.value = Array.isArray(value) ? value.join(", ") : value;
}

function readField(el, p) {
  const raw = el.type === "checkbox" ? el.checked : el.value.trim();
  if (p.kind === "bool") return raw;
  if (p.kind === "int" || p.kind === "float") return raw === "" || isNaN(Number(raw)) ? raw : Number(raw);
  if (p.kind === "floats") return raw === "" ? [] : raw.split(/[\s,]+/).map((x) => (isNaN(Number(x)) ? x : Number(x)));
  return raw;
}

// The nodes whose boxes start open: the light, the shadow, and the source of the
// cutout's height that the page's hand edit edits (its params, e.g. a predictor's
// method, beside the edit's handles).
function openAtStart() {
  const scene = ui.scene || {};
  const roles = scene.roles || {};
  return new Set([roles.light, roles.shadow, ...((scene.height_edit || {}).sources || [])]);
}

// The nodes and their types the panel shows: another graph (an undo, a type switch) rebuilds it.
let builtFor = null;
const panelKey = () => JSON.stringify(ui.info.nodes.map((n) => [n.id, n.type]));

// fresh: a graph loaded (the boxes of openAtStart open), else rebuilt after a type switch or
// an undo: the boxes the user opened stay open while the graph has the same nodes
export function buildPanel(fresh = true) {
  const root = $("nodes");
  const boxes = [...root.querySelectorAll("details.node")];
  const same = boxes.map((d) => d.dataset.node).join("\n") === ui.info.nodes.map((n) => n.id).join("\n");
  const open = fresh || !same ? openAtStart() : new Set(boxes.filter((d) => d.open).map((d) => d.dataset.node));
  root.replaceChildren();
  builtFor = panelKey();
  for (const node of ui.info.nodes) {
    const spec = ui.info.types[node.type];
    const box = document.createElement("details");
    box.className = "node";
    box.dataset.node = node.id;
    box.open = open.has(node.id);
    const sum = document.createElement("summary");
    sum.innerHTML = `<b></b><span class="type"></span>`;
    sum.querySelector("b").textContent = node.id;
    sum.querySelector(".type").textContent = node.type;
    sum.title = spec.summary;
    box.appendChild(sum);
    const ins = Object.entries(node.inputs);
    if (ins.length) {
      const d = document.createElement("div");
      d.className = "inputs";
      d.textContent = "\u2190 " + ins.map(([k, v]) => `${k}: ${v}`).join(", ");
      box.appendChild(d);
    }
    for (const p of spec.params) {
      const row = document.createElement("label");
      row.className = "param";
      row.title = p.doc + (p.unit ? ` [${p.unit}]` : "");
      const name = document.createElement("span");
      name.textContent = p.name + (p.unit ? ` (${p.unit})` : "");
      let el;
      if (p.choices) {
        el = document.createElement("select");
        for (const c of p.choices) el.add(new Option(c, c));
      } else {
        el = document.createElement("input");
        el.type = p.kind === "bool" ? "checkbox" : "text";
        if (p.kind === "int" || p.kind === "float") el.inputMode = "decimal";
      }
      el.dataset.param = `${node.id}.${p.name}`;
      setField(el, node.values[p.name]);
      el.addEventListener("change", () => finalize({params: {[`${node.id}.${p.name}`]: readField(el, p)}}));
      row.append(name, el);
      if (p.kind === "path" && !p.writes) row.append(uploadButton(`${node.id}.${p.name}`));
      box.appendChild(row);
    }
    root.appendChild(box);
  }
}

// An image from this computer for one path param: stored by the server in its
// upload folder (an allowed root), then set as the param's path.
function uploadButton(param) {
  const pick = document.createElement("input");
  pick.type = "file";
  pick.accept = ".png,.jpg,.jpeg,.tif,.tiff,.exr";
  pick.title = "upload an image for this param";
  pick.addEventListener("change", async () => {
    const file = pick.files[0];
    if (!file) return;
    try {
      await finalize({params: {[param]: await upload(file)}});
    } catch (err) { showError(err.message); }
    pick.value = "";
  });
  return pick;
}

export function wireToolbar() {
  const sliderDrag = (id, edits) => {
    const el = $(id);
    el.addEventListener("pointerdown", () => { ui.drag = {el}; });
    // released without a new value there is no 'change': the drag ends here too
    const release = () => { if (ui.drag && ui.drag.el === el) ui.drag = null; };
    el.addEventListener("pointerup", release);
    el.addEventListener("pointercancel", release);
    el.addEventListener("input", () => {
      $(`${id}-value`).textContent = Number(el.value).toFixed(id === "elevation" ? 1 : 2);
      ui.drag = ui.drag || {el};
      preview(edits(Number(el.value)));
    });
    el.addEventListener("change", () => { ui.drag = null; finalize(edits(Number(el.value))); });
  };
  sliderDrag("elevation", (v) => ({light_elevation: v}));
  sliderDrag("softness", (v) => ({params: {[`${ui.scene.roles.light}.radius`]: v}}));
  for (const r of document.querySelectorAll("input[name=method]")) {
    r.addEventListener("change", () => finalize({types: {[ui.scene.roles.shadow]: r.value}}));
  }
  $("flip").addEventListener("click", flipCutout);
  $("find-horizon").addEventListener("click", toggleFinder);
  $("horizon-apply").addEventListener("click", applyFinder);
}
