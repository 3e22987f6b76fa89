// Your own files: open (or drop) a photo and a cutout (RGBA, or RGB with a mask
// file). Each goes to the server's upload folder (PUT /api/uploads/NAME), then
// POST /api/open builds the own-photo graph around them from the node pack's
// template. "save" writes the graph with the files it reads copied beside it
// (POST /api/save_files).
"use strict";

import {$, api, upload, showError} from "./app.js";
import {ui} from "./render.js";

const ROLES = ["photo", "cutout", "mask"];
const chosen = {photo: null, cutout: null, mask: null};

function setChosen(role, file) {
  chosen[role] = file;
  $(`open-${role}-name`).textContent = file ? file.name : "";
  $("open-go").disabled = !(chosen.photo && chosen.cutout);
}

async function pixels(file) {
  try {
    const b = await createImageBitmap(file);
    const n = b.width * b.height;
    b.close();
    return n;
  } catch (err) {
    return 0;   // a format the browser does not decode (EXR, TIFF): the server reads it
  }
}

// Files dropped together: a name with mask, matte or alpha is the mask; of the
// others the larger image is the photo, the smaller the cutout.
async function assign(files) {
  const rest = [];
  for (const f of files) {
    if (/mask|matte|alpha/i.test(f.name)) setChosen("mask", f);
    else rest.push(f);
  }
  if (rest.length === 1) {
    setChosen(chosen.photo ? "cutout" : "photo", rest[0]);
  } else if (rest.length >= 2) {
    const sized = await Promise.all(rest.slice(0, 2).map(async (f) => [await pixels(f), f]));
    sized.sort((a, b) => b[0] - a[0]);
    setChosen("photo", sized[0][1]);
    setChosen("cutout", sized[1][1]);
  }
}

export async function openChosen(reload) {
  const paths = {};
  let opened;
  try {
    $("status").textContent = "uploading\u2026";
    for (const role of ROLES) if (chosen[role]) paths[role] = await upload(chosen[role]);
    $("status").textContent = "building the graph\u2026";
    opened = await api("POST", "/api/open", paths);
  } catch (err) {
    showError(err.message);
    return false;
  }
  setSaveName(opened.save_as);   // the server's proposal, the same after a reload
  $("open-form").hidden = true;
  await reload();
  return true;
}

/** Put ``name`` in the save box; a name longer than the box shows whole on hover (its
 * title) and, while the box is not being typed in, with its end in view (the file name;
 * a browser shows a text box's start, and goes back to it when the box loses the focus):
 * the box keeps its width, which the toolbar's two rows were laid out for. */
export function setSaveName(name) {
  $("save-name").value = name;
  titleSaveName();
  showNameEnd();
}

function titleSaveName() {
  const box = $("save-name");
  box.title = `${box.value}: file name, in the served graph's folder`;
}

function showNameEnd() {
  const box = $("save-name");
  if (document.activeElement !== box) box.scrollLeft = box.scrollWidth;
}

export function wireFiles(reload) {
  $("save-name").addEventListener("input", titleSaveName);
  // after the browser's own return to the start, which follows the blur event
  $("save-name").addEventListener("blur", () => requestAnimationFrame(showNameEnd));
  $("open").addEventListener("click", () => { $("open-form").hidden = !$("open-form").hidden; });
  for (const role of ROLES) {
    const input = $(`open-${role}`);
    input.addEventListener("change", () => setChosen(role, input.files[0] || null));
    const zone = input.closest("label");
    zone.addEventListener("dragover", (ev) => { ev.preventDefault(); zone.classList.add("over"); });
    zone.addEventListener("dragleave", () => zone.classList.remove("over"));
    zone.addEventListener("drop", (ev) => {
      ev.preventDefault();
      ev.stopPropagation();
      zone.classList.remove("over");
      if (ev.dataTransfer.files.length) setChosen(role, ev.dataTransfer.files[0]);
    });
  }
  $("open-go").addEventListener("click", (ev) => { ev.preventDefault(); openChosen(reload); });
  // files dropped on the image: sorted into photo, cutout and mask; opened when both are there
  const stage = $("stage");
  stage.addEventListener("dragover", (ev) => { ev.preventDefault(); stage.classList.add("over"); });
  stage.addEventListener("dragleave", () => stage.classList.remove("over"));
  stage.addEventListener("drop", async (ev) => {
    ev.preventDefault();
    stage.classList.remove("over");
    await assign([...ev.dataTransfer.files]);
    if (chosen.photo && chosen.cutout) await openChosen(reload);
    else $("open-form").hidden = false;
  });
  $("save").addEventListener("click", async () => {
    try {
      const name = $("save-name").value.trim();
      const res = await api("POST", "/api/save_files", name ? {path: name} : {});
      ui.savedSeq = ui.seq;        // renders asked before the save leave this line (render.js)
      $("status").textContent = `saved ${res.path}` + (res.copied.length ? ` with ${res.copied.join(", ")}` : "");
      showError("");
      ui.saved = res;
    } catch (err) { showError(err.message); }
  });
}
