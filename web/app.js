// Umbra control panel: turns the form into an API.md request body, asks for
// the frame and then the light's depth map, and never has more than one
// request in flight (a change made meanwhile is sent when the answer comes).
"use strict";

const $ = (id) => document.getElementById(id);
const state = { inFlight: false, dirty: false, playing: false, lastTick: 0, frameUrl: null, depthUrl: null, errorSource: null };

function number(id) {
  const value = Number($(id).value);
  return Number.isFinite(value) ? value : 0;
}

// The request body for the current settings. Only fields that matter for
// the chosen settings are sent (the server reports unused ones).
function buildRequest() {
  const perspective = $("projection").value === "perspective";
  const fixed = $("fit").value === "fixed";
  const enabled = $("enabled").checked;
  const light = {
    position: [number("lx"), number("ly"), number("lz")],
    color: $("color").value,
    ambient: number("ambient"),
    projection: $("projection").value,
  };
  if (number("size") > 0) light.size = number("size");
  const shadow = { enabled };
  if (enabled) {
    if (!perspective && !fixed && $("cascades").value !== "auto") shadow.cascades = Number($("cascades").value);
    shadow.filter = $("filter").value;
    if (shadow.filter === "pcf" || (shadow.filter === "pcss" && !(number("size") > 0))) shadow.pcf_radius = Math.round(number("pcf_radius"));
    if (shadow.filter !== "pcss" && number("size") > 0) delete light.size;
    shadow.map_size = Number($("map_size").value);
    shadow.fit = $("fit").value;
    if (fixed) {
      shadow.near = number("near");
      shadow.far = number("far");
      if (!perspective) shadow.ortho_half_size = number("half");
    }
  }
  const model = chosenModel();
  return {
    width: 960,
    height: 540,
    ...(model ? modelView(model) : { scene: $("scene").value }),
    light,
    time: number("time"),
    shadow,
    output: $("view").value,
  };
}

// The error box says what failed last: a render or an upload. A frame that
// arrives clears only a render's error, so that a refused upload stays
// readable while frames keep coming (playing).
function showError(message, source = "render") {
  const box = $("error");
  box.textContent = message;
  box.hidden = false;
  state.errorSource = source;
}

function clearError(source = "render") {
  if (state.errorSource !== source) return;
  $("error").hidden = true;
  $("error").textContent = "";
  state.errorSource = null;
}

async function post(path, body) {
  let response;
  try {
    response = await fetch(path, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
  } catch (e) {
    throw new Error("The server is unreachable (" + e.message + "). Is umbra-server running?");
  }
  if (!response.ok) {
    let detail = response.status + " " + response.statusText;
    try {
      const json = await response.json();
      detail = json.field ? `${json.field}: ${json.error}` : json.error;
    } catch (_) { /* not JSON */ }
    throw new Error(`Server error (${response.status}): ${detail}`);
  }
  return {
    blob: await response.blob(),
    timing: response.headers.get("Server-Timing") || "",
    unused: response.headers.get("Umbra-Unused-Fields"),
    views: response.headers.get("Umbra-Shadow-Views"),
  };
}

function parseTiming(header) {
  const parts = {};
  for (const entry of header.split(",")) {
    const match = entry.trim().match(/^([\w-]+);dur=([\d.]+)/);
    if (match) parts[match[1]] = Number(match[2]);
  }
  return parts;
}

function replaceImage(img, blob, key) {
  const url = URL.createObjectURL(blob);
  if (state[key]) URL.revokeObjectURL(state[key]);
  state[key] = url;
  img.src = url;
}

// Requests one frame (then the depth map). Called on every change and, while
// playing, again whenever the previous frame has arrived.
async function requestFrame() {
  if (state.inFlight) {
    state.dirty = true;
    return;
  }
  state.inFlight = true;
  state.dirty = false;
  const started = performance.now();
  if (state.playing) {
    const now = performance.now();
    if (state.lastTick) $("time").value = (number("time") + (now - state.lastTick) / 1000).toFixed(3);
    state.lastTick = now;
  }
  const body = buildRequest();
  saveToUrl();
  try {
    const frame = await post("/api/render", body);
    replaceImage($("frame"), frame.blob, "frameUrl");
    const depth = await post("/api/depth", { ...body, output: "depth" });
    replaceImage($("depth"), depth.blob, "depthUrl");
    const t = parseTiming(frame.timing);
    const ms = performance.now() - started;
    const fps = state.playing ? ` · ${(1000 / ms).toFixed(1)} frames/s` : "";
    $("timing").textContent =
      `server: shadow ${fmt(t.shadow)} · main ${fmt(t.main)} · readback ${fmt(t.readback)} · encode ${fmt(t.encode)} ms` +
      ` · round trip ${ms.toFixed(0)} ms${fps}` + (frame.views ? ` · light views: ${frame.views}` : "") +
      (frame.unused ? ` · unused: ${frame.unused}` : "");
    $("frame-info").textContent = `(${body.output}, t = ${body.time.toFixed(2)} s)`;
    clearError();
  } catch (e) {
    showError(e.message);
    if (state.playing) togglePlay();
  } finally {
    state.inFlight = false;
  }
  if (state.dirty || state.playing) requestFrame();
}

function fmt(v) {
  return v === undefined ? "–" : v.toFixed(1);
}

function togglePlay() {
  state.playing = !state.playing;
  state.lastTick = 0;
  $("play").textContent = state.playing ? "Pause" : "Play";
  $("play").setAttribute("aria-pressed", String(state.playing));
  if (state.playing) requestFrame();
}

function syncFixedSettings() {
  const fixed = $("fit").value === "fixed";
  const perspective = $("projection").value === "perspective";
  $("fixed-settings").setAttribute("aria-disabled", String(!fixed));
  for (const id of ["near", "far", "half"]) $(id).disabled = !fixed;
  $("half").disabled = !fixed || perspective;
  $("cascades").disabled = fixed || perspective;
}

// --- Settings in the address bar ---------------------------------------------
// Every control whose value differs from the page's default is a query
// parameter named after the control, so the address is a link to this view.

function controls() {
  return Array.from($("controls").elements).filter((e) => e.name);
}

// A select's default is its option marked selected in the page, else its
// first option (which the browser selects without marking it).
function isDefault(e) {
  if (e.type === "checkbox") return e.checked === e.defaultChecked;
  if (e.tagName === "SELECT") return e.selectedIndex === Math.max(0, Array.from(e.options).findIndex((o) => o.defaultSelected));
  return e.value === e.defaultValue;
}

function saveToUrl() {
  const params = new URLSearchParams();
  for (const e of controls()) {
    if (isDefault(e)) continue;
    const value = e.type === "checkbox" ? (e.checked ? "1" : "0") : e.value;
    // A model is chosen in the scene list but named by its own parameter.
    if (e.id === "scene" && value.startsWith(MODEL_PREFIX)) params.set("model", value.slice(MODEL_PREFIX.length));
    else params.set(e.name, value);
  }
  const query = params.toString();
  history.replaceState(null, "", query ? `?${query}` : location.pathname);
}

// Applies the address's settings; a value a control cannot take is skipped
// (and reported), never half applied.
function loadFromUrl() {
  const params = new URLSearchParams(location.search);
  const skipped = [];
  const model = params.get("model");
  if (model) {
    // A model the server does not list is chosen all the same: the render
    // then shows the server's own message (upload it first), not a blank.
    $("scene").value = modelChoice(model) || addUnlistedModel(model);
    if (params.has("scene")) skipped.push("scene");
  } else if (model !== null) {
    skipped.push("model");
  }
  for (const e of controls()) {
    if (!params.has(e.name) || (e.id === "scene" && model)) continue;
    const value = params.get(e.name);
    if (e.type === "checkbox") {
      if (value === "1" || value === "0") e.checked = value === "1";
      else skipped.push(e.name);
    } else if (e.tagName === "SELECT") {
      if (Array.from(e.options).some((o) => o.value === value)) e.value = value;
      else skipped.push(e.name);
    } else if (e.type === "number" || e.type === "range") {
      if (value.trim() !== "" && Number.isFinite(Number(value))) e.value = value;
      else skipped.push(e.name);
    } else if (e.type === "color") {
      if (/^#[0-9a-fA-F]{6}$/.test(value)) e.value = value.toLowerCase();
      else skipped.push(e.name);
    }
  }
  const known = new Set(controls().map((e) => e.name).concat("model"));
  for (const name of params.keys()) if (!known.has(name)) skipped.push(name);
  $("notice").textContent = skipped.length
    ? `Ignored from the address: ${skipped.join(", ")} (not a setting, or a value it cannot take).` : "";
}

// --- Scenes and models ----------------------------------------------------------
// The scene list holds the server's built-in scenes and, in a "Models"
// group, every model it holds (uploads, --models files, built-in models).
// A model option's value is MODEL_PREFIX + its name, or its id if it has
// none; choosing one renders it on a floor (modelView).

const MODEL_PREFIX = "model:";
const models = new Map();  // option value -> the model as GET /api/models lists it, plus its key
const upload = { busy: null };  // the file name being uploaded, if any

// The largest side of a model as placed: about the built-in teapot's (3.2).
// Scaling every model to it keeps the light controls meaningful for any
// model: a point light at (-2, 4, -1), the fixed frustum's near, far and
// half-size are in the same units as for the built-in scenes.
const MODEL_SIZE = 3;
const FLOOR_SIZE = 4 * MODEL_SIZE;  // wide enough to catch the shadow of a tall model under a low light
const CAMERA_DIRECTION = normalize([0.45, 0.55, 1.0]);  // the server's own for a custom scene

function normalize(v) {
  const length = Math.hypot(...v);
  return v.map((x) => x / length);
}

// Six significant digits: a readable request (and curl command), and far
// finer than a pixel.
function round(x) {
  return Number(x.toPrecision(6));
}

async function getJson(path) {
  try {
    const response = await fetch(path);
    return response.ok ? await response.json() : null;
  } catch (_) {
    return null;
  }
}

// Without the lists (an older or unreachable server) the page's own two
// scenes stay, and the first frame reports what is wrong.
async function loadChoices() {
  const [scenes, held] = await Promise.all([getJson("/api/scenes"), getJson("/api/models")]);
  if (scenes && Array.isArray(scenes.scenes) && scenes.scenes.length) fillScenes(scenes.scenes);
  if (held && Array.isArray(held.models)) for (const model of held.models) addModel(model);
}

// Replaces the scene options (not the models); the first is the default.
function fillScenes(scenes) {
  const select = $("scene");
  for (const option of Array.from(select.options)) if (!option.value.startsWith(MODEL_PREFIX)) option.remove();
  scenes.forEach((scene, i) => {
    const option = new Option(scene.name, scene.name, i === 0, i === 0);
    option.title = scene.description || "";
    select.insertBefore(option, select.querySelector("optgroup"));
  });
}

function modelGroup() {
  let group = $("scene").querySelector("optgroup");
  if (!group) {
    group = document.createElement("optgroup");
    group.label = "Models";
    $("scene").append(group);
  }
  return group;
}

function modelOption(value) {
  return Array.from($("scene").options).find((o) => o.value === value) || modelGroup().appendChild(new Option("", value));
}

// Adds (or updates) a held model's option and returns its value.
function addModel(model, fileName) {
  const key = model.name || model.id;
  const value = MODEL_PREFIX + key;
  models.set(value, { ...model, key });
  const shown = model.name || fileName || rememberedFileNames()[model.id] || `${model.id.slice(0, 19)}…`;
  const option = modelOption(value);
  option.textContent = `model: ${shown} (${model.triangles.toLocaleString("en")} triangles)`;
  option.title = `${model.id}, ${model.closed ? "closed" : "open"}`;
  return value;
}

function addUnlistedModel(key) {
  const value = MODEL_PREFIX + key;
  modelOption(value).textContent = `model: ${key} (not listed by the server)`;
  return value;
}

// The option for a model named by its name or its id, if listed.
function modelChoice(key) {
  for (const [value, model] of models) if (model.key === key || model.id === key) return value;
  return null;
}

function chosenModel() {
  const value = $("scene").value;
  if (!value.startsWith(MODEL_PREFIX)) return null;
  return models.get(value) || { key: value.slice(MODEL_PREFIX.length) };
}

// The scene and camera for a model: scaled to MODEL_SIZE, standing centred
// on a floor at y = 0, the camera framing the model (the server's default
// camera frames the whole floor, which leaves the model small).
function modelView(model) {
  if (!model.bounds) return { scene: { objects: [{ type: "mesh", model: model.key }] } };  // not listed: the server says why
  const { min, max } = model.bounds;
  const extent = [0, 1, 2].map((i) => max[i] - min[i]);
  const largest = Math.max(...extent);
  const scale = largest > 0 ? Math.min(Math.max(MODEL_SIZE / largest, 1e-6), 1e6) : 1;
  const position = [-0.5 * (min[0] + max[0]) * scale, -min[1] * scale, -0.5 * (min[2] + max[2]) * scale];
  const target = [0, 0.5 * extent[1] * scale, 0];
  const distance = 3.2 * Math.max(0.5 * Math.hypot(...extent) * scale, 0.5);
  return {
    scene: {
      objects: [
        { type: "plane", center: [0, 0, 0], size: [FLOOR_SIZE, FLOOR_SIZE] },
        { type: "mesh", model: model.key, position: position.map(round), scale: round(scale) },
      ],
    },
    camera: { position: target.map((t, i) => round(t + CAMERA_DIRECTION[i] * distance)), target: target.map(round) },
  };
}

// Uploads have no name on the server: this browser remembers the file
// each came from, to show it again after a reload.
const FILE_NAMES_KEY = "umbra.modelFileNames";

function rememberedFileNames() {
  try {
    return JSON.parse(localStorage.getItem(FILE_NAMES_KEY)) || {};
  } catch (_) {
    return {};
  }
}

function rememberFileName(id, fileName) {
  try {
    localStorage.setItem(FILE_NAMES_KEY, JSON.stringify({ ...rememberedFileNames(), [id]: fileName }));
  } catch (_) { /* storage off: the list shows the id */ }
}

function contentTypeFor(fileName) {
  return /\.gltf$/i.test(fileName) ? "model/gltf+json" : "model/gltf-binary";
}

// POST /api/models through XMLHttpRequest: fetch cannot report how much
// of a large body has been sent.
function sendModel(file, onProgress) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", "/api/models");
    xhr.setRequestHeader("Content-Type", contentTypeFor(file.name));
    xhr.upload.addEventListener("progress", (e) => { if (e.lengthComputable) onProgress(e.loaded / e.total); });
    xhr.addEventListener("load", () => {
      let json = null;
      try {
        json = JSON.parse(xhr.responseText);
      } catch (_) { /* not JSON */ }
      resolve({ status: xhr.status, statusText: xhr.statusText, json });
    });
    xhr.addEventListener("error", () =>
      reject(new Error(`${file.name} was not uploaded: the connection failed or the server closed it. Is umbra-server running?`)));
    xhr.send(file);
  });
}

function mebibytes(bytes) {
  return bytes < 1 << 20 ? `${Math.ceil(bytes / 1024)} KiB` : `${(bytes / (1 << 20)).toFixed(1)} MiB`;
}

// Uploads one file and, once the server holds it, chooses it. One upload
// at a time: the server loads at most two, and one shows progress clearly.
async function uploadModel(file) {
  const status = $("model-status");
  if (upload.busy) {
    status.textContent = `Still uploading ${upload.busy}; try ${file.name} when it is done.`;
    return;
  }
  upload.busy = file.name;
  clearError("upload");
  status.textContent = `Uploading ${file.name} (${mebibytes(file.size)})…`;
  try {
    const answer = await sendModel(file, (sent) => {
      status.textContent = sent < 1 ? `Uploading ${file.name}: ${Math.floor(100 * sent)} %` : `Loading ${file.name} on the server…`;
    });
    const model = answer.json;
    if ((answer.status !== 200 && answer.status !== 201) || !model || !model.id) {
      const detail = model && model.error ? model.error : `${answer.status} ${answer.statusText}`;
      throw new Error(`${file.name} was not loaded (${answer.status}): ${detail}`);
    }
    rememberFileName(model.id, file.name);
    $("scene").value = addModel(model, file.name);
    status.textContent = `${file.name}: ${model.triangles.toLocaleString("en")} triangles, ` +
      (model.closed ? "closed" : "open (drawn two-sided in the shadow pass)") + (answer.status === 200 ? ", already held." : ".");
    requestFrame();
  } catch (e) {
    status.textContent = `${file.name}: not loaded.`;
    showError(e.message, "upload");
  } finally {
    upload.busy = null;
    $("model-file").value = "";  // the same file can be chosen again
  }
}

// A file dropped anywhere on the page is uploaded; without this the
// browser would open it in place of the panel.
function hasFiles(e) {
  return e.dataTransfer && Array.from(e.dataTransfer.types).includes("Files");
}

function dragOver(e) {
  if (!hasFiles(e)) return;
  e.preventDefault();
  e.dataTransfer.dropEffect = "copy";
  document.body.classList.add("dropping");
}

function drop(e) {
  if (!hasFiles(e)) return;
  e.preventDefault();
  document.body.classList.remove("dropping");
  const file = e.dataTransfer.files[0];
  if (file) uploadModel(file);
}

// --- Copy as curl --------------------------------------------------------------

function curlCommand(body) {
  const json = JSON.stringify(body).replace(/'/g, "'\\''");
  const file = body.output === "color" ? "frame.png" : `${body.output}.png`;
  return `curl -X POST '${location.origin}/api/render' -H 'Content-Type: application/json' -d '${json}' -o ${file}`;
}

async function copyCurl() {
  const command = curlCommand(buildRequest());
  $("curl").textContent = command;
  $("curl").hidden = false;
  try {
    await navigator.clipboard.writeText(command);
    $("copy-status").textContent = "Copied to the clipboard.";
  } catch (_) {
    $("copy-status").textContent = "The clipboard is not available here: select the command below and copy it.";
  }
}

// The controls come from the server's lists, and the address names a
// choice among them: fill the lists before reading the address.
async function start() {
  await loadChoices();
  loadFromUrl();
  syncFixedSettings();
  requestFrame();
}

$("controls").addEventListener("input", (e) => {
  if (e.target.id === "model-file") return;  // its "change" uploads; the frame follows the answer
  clearError("upload");
  syncFixedSettings();
  requestFrame();
});
$("controls").addEventListener("submit", (e) => e.preventDefault());
$("play").addEventListener("click", togglePlay);
$("copy-curl").addEventListener("click", copyCurl);
$("model-file").addEventListener("change", () => {
  const file = $("model-file").files[0];
  if (file) uploadModel(file);
});
document.addEventListener("dragover", dragOver);
document.addEventListener("dragleave", (e) => { if (e.relatedTarget === null) document.body.classList.remove("dropping"); });
document.addEventListener("drop", drop);
start();
