// pixgraph serve: the page's requests. Plain JS modules, no dependencies, nothing
// fetched from elsewhere; every request the page makes goes through `request` here.
//
//   app.js      requests to the server (this file)
//   render.js   the render queue: previews while dragging, a final when the pointer stops
//   view.js     the image in the window: fit, zoom and pan, image <-> screen pixels
//   handles.js  the handles over the image (cutout, horizon, wall, light), sized in screen pixels
//   panel.js    the toolbar and the param panel
//   heightedit.js  the cutout's pixel height by hand: contact points, tilt, lying down
//   history.js  undo and redo (the server keeps the history), the buttons and Ctrl+Z
//   horizon.js  "find horizon": two lines along parallel floor lines meet on the horizon
//   files.js    open or drop a photo and a cutout, save the graph with its files
//   main.js     start-up
"use strict";

export const $ = (id) => document.getElementById(id);

// The server's per-launch token, when it wrote one into the page, goes with every request.
const TOKEN = document.querySelector("meta[name=pixgraph-token]")?.content;

// The token leaves the address bar at once (browser history, screenshots, a Referer):
// the page keeps it here, and a reload is let in by the cookie the page's first
// answer set (docs/server.md, "Safety").
{
  const url = new URL(location.href);
  if (url.searchParams.has("token")) {
    url.searchParams.delete("token");
    history.replaceState(history.state, "", url.pathname + url.search + url.hash);
  }
}

// The one fetch of the page.
export function request(path, init = {}) {
  return fetch(path, TOKEN ? {...init, headers: {...(init.headers || {}), "X-Pixgraph-Token": TOKEN}} : init);
}

export async function api(method, path, body) {
  const r = await request(path, {method, headers: {"Content-Type": "application/json"},
                                 body: body === undefined ? undefined : JSON.stringify(body)});
  const data = await r.json();
  if (!r.ok) throw Object.assign(new Error(data.error || r.statusText), {status: r.status, data});
  return data;
}

// The name an upload is stored under: the server takes letters, digits and '._-', up
// to 100 characters and an image extension. A name that loses characters on the way
// (a photo named in another script: "写真.png" became "png", refused, and two such
// names became one file) is "NAME-HASH", HASH of the whole name; spaces become "_".
export function uploadName(name) {
  const image = name.match(/\.(png|jpe?g|tiff?|exr)$/i);
  const ext = image ? image[0].toLowerCase() : ".png";
  const stem = image ? name.slice(0, -image[0].length) : name;
  const plain = stem.replace(/ /g, "_");     // "my photo.png": my_photo.png, as before
  if (/^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$/.test(plain)) return plain + ext;
  let h = 0x811c9dc5;                        // FNV-1a of the name's UTF-16 code units
  for (let i = 0; i < name.length; i++) h = Math.imul(h ^ name.charCodeAt(i), 16777619) >>> 0;
  const kept = stem.replace(/[^A-Za-z0-9_.-]/g, "_").replace(/^[^A-Za-z0-9]+/, "").slice(0, 80);
  return `${kept || "upload"}-${h.toString(16).padStart(8, "0")}${ext}`;
}

// Store a file from this computer in the server's upload folder; returns its path there.
export async function upload(file) {
  const name = uploadName(file.name);
  const r = await request(`/api/uploads/${encodeURIComponent(name)}`, {method: "PUT", body: file});
  const data = await r.json().catch(() => ({error: r.statusText}));
  if (!r.ok) throw Object.assign(new Error(`${file.name}: ${data.error}`), {status: r.status, data});
  return data.path;
}

export function showError(msg) {
  const e = $("error");
  e.textContent = msg || "";
  e.hidden = !msg;
}
