// Umbra control panel: turns the form into an API.md request body, asks for
// the frame and then the light's depth map, and never has more than one
// request in flight (a change made meanwhile is sent when the answer comes).
"use strict";

const $ = (id) => document.getElementById(id);
const state = { inFlight: false, dirty: false, playing: false, lastTick: 0, frameUrl: null, depthUrl: null };

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
  return {
    width: 960,
    height: 540,
    scene: $("scene").value,
    light,
    time: number("time"),
    shadow,
    output: $("view").value,
  };
}

function showError(message) {
  const box = $("error");
  box.textContent = message;
  box.hidden = false;
}

function clearError() {
  $("error").hidden = true;
  $("error").textContent = "";
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
    params.set(e.name, e.type === "checkbox" ? (e.checked ? "1" : "0") : e.value);
  }
  const query = params.toString();
  history.replaceState(null, "", query ? `?${query}` : location.pathname);
}

// Applies the address's settings; a value a control cannot take is skipped
// (and reported), never half applied.
function loadFromUrl() {
  const params = new URLSearchParams(location.search);
  const skipped = [];
  for (const e of controls()) {
    if (!params.has(e.name)) continue;
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
  const known = new Set(controls().map((e) => e.name));
  for (const name of params.keys()) if (!known.has(name)) skipped.push(name);
  $("notice").textContent = skipped.length
    ? `Ignored from the address: ${skipped.join(", ")} (not a setting, or a value it cannot take).` : "";
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

$("controls").addEventListener("input", () => { syncFixedSettings(); requestFrame(); });
$("controls").addEventListener("submit", (e) => e.preventDefault());
$("play").addEventListener("click", togglePlay);
$("copy-curl").addEventListener("click", copyCurl);
loadFromUrl();
syncFixedSettings();
requestFrame();
