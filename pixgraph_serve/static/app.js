// pixgraph serve: the page. Plain JS, no dependencies, nothing fetched from elsewhere.
//
// Every edit is sent as one POST /api/render {edits, mode, client, seq}: while a
// handle or slider moves, "preview" renders (hard shadow, half resolution) go out
// one at a time, the newest edit waiting in `pending`; when the pointer stops a
// "final" render follows at once. The server drops or cancels renders superseded
// by a newer seq (409), and the page never shows an image older than the one shown.
"use strict";

// The server's per-launch token (written into the page it serves) goes with every request.
function withToken(fetch, token) {
  return token ? (url, opts = {}) => fetch(url, {...opts, headers: {...opts.headers, "X-Pixgraph-Token": token}}) : fetch;
}
window.fetch = withToken(window.fetch.bind(window), document.querySelector("meta[name=pixgraph-token]")?.content);

window.pixgraphShown = [];

const SVG = "http://www.w3.org/2000/svg";
const $ = (id) => document.getElementById(id);
const ui = {
  client: Math.random().toString(36).slice(2), seq: 0, shownSeq: 0,
  inflight: false, pending: null, info: null, scene: null, W: 512, H: 512,
  drag: null, renders: 0,
};

async function api(method, path, body) {
  const r = await fetch(path, {method, headers: {"Content-Type": "application/json"},
                               body: body === undefined ? undefined : JSON.stringify(body)});
  const data = await r.json();
  if (!r.ok) throw Object.assign(new Error(data.error || r.statusText), {status: r.status, data});
  return data;
}

function showError(msg) {
  const e = $("error");
  e.textContent = msg || "";
  e.hidden = !msg;
}

// -- rendering -------------------------------------------------------------------

async function render(edits, mode) {
  const seq = ++ui.seq;
  const t0 = performance.now();
  let r;
  try {
    r = await fetch("/api/render", {method: "POST", headers: {"Content-Type": "application/json"},
      body: JSON.stringify({...edits, mode, output: "final", client: ui.client, seq})});
  } catch (err) {
    showError(`server unreachable: ${err.message}`);
    return false;
  }
  if (r.status === 409) return false;          // superseded by a newer render: dropped
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
  const ctx = $("view").getContext("2d");
  ctx.imageSmoothingEnabled = true;
  ctx.drawImage(bmp, 0, 0, ui.W, ui.H);
  ui.renders++;
  const ms = (performance.now() - t0).toFixed(0);
  $("status").textContent = `${mode} ${bmp.width}x${bmp.height} in ${ms} ms; ran: ${r.headers.get("X-Pixgraph-Ran") || "nothing (cached)"}`;
  window.pixgraphShown.push({seq, mode, ms: Number(ms)});   // what was displayed, for tests and timing
  showError("");
  markBad(null);
  return true;
}

// Previews one at a time, the newest edit waiting; a final render goes out at once.
function preview(edits) {
  ui.pending = {...(ui.pending || {}), ...edits, params: {...((ui.pending || {}).params || {}), ...(edits.params || {})}};
  if (ui.inflight) return;
  const next = ui.pending;
  ui.pending = null;
  ui.inflight = true;
  render(next, "preview").finally(() => {
    ui.inflight = false;
    if (ui.pending && ui.drag) preview({});
  });
}

async function finalize(edits) {
  ui.pending = null;
  const ok = await render(edits, "final");
  if (ok) await refresh();
}

async function refresh() {
  [ui.info, ui.scene] = await Promise.all([api("GET", "/api/graph"), api("GET", "/api/scene")]);
  syncControls();
  if (!ui.drag) drawHandles();   // never pull a handle from under the pointer
  document.body.dataset.synced = ui.shownSeq;
}

// -- handles -----------------------------------------------------------------------

function svgEl(tag, attrs, parent) {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  (parent || $("handles")).appendChild(el);
  return el;
}

function toImage(ev) {
  const box = $("handles").getBoundingClientRect();
  return [(ev.clientX - box.left) * ui.W / box.width, (ev.clientY - box.top) * ui.H / box.height];
}

// A draggable handle: `edit([u, v])` returns the edits for the pointer at (u, v).
function handle(cls, id, u, v, edit, shape = "circle") {
  const attrs = {class: `handle ${cls}`, id};
  const el = shape === "circle" ? svgEl("circle", {...attrs, cx: u, cy: v, r: 7})
    : svgEl("rect", {...attrs, x: u - 6, y: v - 6, width: 12, height: 12});
  el.addEventListener("pointerdown", (ev) => {
    ev.preventDefault();
    el.setPointerCapture(ev.pointerId);
    ui.drag = {el, edit, last: null};
  });
  el.addEventListener("pointermove", (ev) => {
    if (!ui.drag || ui.drag.el !== el) return;
    const [x, y] = toImage(ev);
    if (shape === "circle") { el.setAttribute("cx", x); el.setAttribute("cy", y); }
    else { el.setAttribute("x", x - 6); el.setAttribute("y", y - 6); }
    ui.drag.last = edit([x, y]);
    preview(ui.drag.last);
  });
  const end = () => {
    if (!ui.drag || ui.drag.el !== el) return;
    const last = ui.drag.last;
    ui.drag = null;
    if (last) finalize(last);
  };
  el.addEventListener("pointerup", end);
  el.addEventListener("pointercancel", end);
  return el;
}

function drawHandles() {
  const svg = $("handles");
  svg.replaceChildren();
  svg.setAttribute("viewBox", `0 0 ${ui.W} ${ui.H}`);
  const s = ui.scene || {};
  const {camera: cam, background: bg, light, roles} = s;
  if (cam && roles.camera) {
    const y = cam.horizon;
    svgEl("line", {class: "guide horizon", x1: 0, y1: y, x2: ui.W, y2: y});
    handle("horizon", "horizon-handle", 14, y, ([, v]) => ({params: {[`${roles.camera}.horizon`]: round(v)}}), "rect");
  }
  if (bg && roles.background) {
    const id = roles.background;
    if (bg.kind === "wall_corner" || bg.kind === "two_corners") {
      // the slope handles sit on the wall-floor line, 8 px inside the image's edges
      const [cu, cv] = bg.corner;
      const rx = bg.kind === "two_corners" ? bg.corner2 : bg.corner;
      const lu = 8, ru = ui.W - 8;
      const lv = cv + bg.left_slope * (lu - cu), rv = rx[1] + bg.right_slope * (ru - rx[0]);
      const ends = [[0, cv + bg.left_slope * (0 - cu)], [ui.W, rx[1] + bg.right_slope * (ui.W - rx[0])]];
      const pts = bg.kind === "two_corners" ? [ends[0], bg.corner, bg.corner2, ends[1]] : [ends[0], bg.corner, ends[1]];
      svgEl("polyline", {class: "guide wall", points: pts.map((p) => p.join(",")).join(" ")});
      handle("wall", "corner-handle", cu, cv, ([u, v]) => ({params: {[`${id}.corner`]: [round(u), round(v)]}}), "rect");
      handle("wall", "left-wall-handle", lu, lv, ([, v]) => ({params: {[`${id}.left_slope`]: round((v - cv) / (lu - cu), 4)}}));
      handle("wall", "right-wall-handle", ru, rv, ([, v]) => ({params: {[`${id}.right_slope`]: round((v - rx[1]) / (ru - rx[0]), 4)}}));
    } else if (bg.kind === "back_wall") {
      const v0 = bg.junction_row, sl = bg.junction_slope;
      svgEl("line", {class: "guide wall", x1: 0, y1: v0 - sl * ui.W / 2, x2: ui.W, y2: v0 + sl * ui.W / 2});
      handle("wall", "wall-handle", ui.W / 2, v0, ([, v]) => ({params: {[`${id}.junction_row`]: round(v)}}), "rect");
    }
  }
  if (light && light.tip_uv) {
    const [tu, tv] = light.tip_uv;
    if (light.top_uvh) svgEl("line", {class: "guide light", x1: light.top_uvh[0], y1: light.top_uvh[1], x2: tu, y2: tv});
    handle("light", "light-handle", tu, tv, ([u, v]) => ({light_tip: [round(u), round(v)]}));
  }
}

function round(x, digits = 1) {
  const k = 10 ** digits;
  return Math.round(x * k) / k;
}

// -- toolbar and param panel --------------------------------------------------------

function syncControls() {
  const s = ui.scene || {};
  const light = s.light;
  for (const id of ["elevation", "softness"]) $(id).disabled = !light;
  if (light) {
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
  for (const node of ui.info.nodes) {
    for (const [name, value] of Object.entries(node.values)) {
      const el = document.querySelector(`[data-param="${node.id}.${name}"]`);
      if (el && document.activeElement !== el) setField(el, value);
    }
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

function markBad(data) {
  for (const el of document.querySelectorAll(".param .bad")) el.classList.remove("bad");
  if (data && data.node && data.field && data.field.startsWith("params.")) {
    const el = document.querySelector(`[data-param="${data.node}.${data.field.slice(7)}"]`);
    if (el) el.classList.add("bad");
  }
}

function buildPanel() {
  const root = $("nodes");
  root.replaceChildren();
  for (const node of ui.info.nodes) {
    const spec = ui.info.types[node.type];
    const box = document.createElement("details");
    box.className = "node";
    const roles = (ui.scene && ui.scene.roles) || {};
    box.open = node.id === roles.light || node.id === roles.shadow;
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

// An image from this computer: stored by the server in its upload folder (an allowed
// root), then set as the param's path.
function uploadButton(param) {
  const pick = document.createElement("input");
  pick.type = "file";
  pick.accept = ".png,.jpg,.jpeg,.tif,.tiff,.exr";
  pick.title = "upload an image for this param";
  pick.addEventListener("change", async () => {
    const file = pick.files[0];
    if (!file) return;
    const name = file.name.replace(/[^A-Za-z0-9_.-]/g, "_").replace(/^[^A-Za-z0-9]+/, "") || "upload.png";
    try {
      const r = await fetch(`/api/uploads/${encodeURIComponent(name)}`, {method: "PUT", body: file});
      const data = await r.json();
      if (!r.ok) throw new Error(data.error);
      await finalize({params: {[param]: data.path}});
    } catch (err) { showError(err.message); }
    pick.value = "";
  });
  return pick;
}

function wireToolbar() {
  const sliderDrag = (id, edits) => {
    const el = $(id);
    el.addEventListener("pointerdown", () => { ui.drag = {el}; });
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
  $("save").addEventListener("click", async () => {
    try {
      const res = await api("POST", "/api/save", {});
      $("status").textContent = `saved ${res.path}`;
      showError("");
    } catch (err) { showError(err.message); }
  });
}

async function main() {
  try {
    [ui.info, ui.scene] = await Promise.all([api("GET", "/api/graph"), api("GET", "/api/scene")]);
  } catch (err) {
    showError(err.message);
    return;
  }
  if (ui.scene.camera) { ui.W = ui.scene.camera.width; ui.H = ui.scene.camera.height; }
  const k = Math.min(1, 640 / Math.max(ui.W, ui.H));
  for (const el of [$("view"), $("handles"), $("stage")]) {
    el.style.width = `${ui.W * k}px`;
    el.style.height = `${ui.H * k}px`;
  }
  $("view").width = ui.W;
  $("view").height = ui.H;
  buildPanel();
  wireToolbar();
  syncControls();
  drawHandles();
  await render({}, "final");
  document.body.dataset.synced = ui.shownSeq;
  document.body.dataset.ready = "1";
}

main();
