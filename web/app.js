// Umbra control panel: turns the form into an API.md request body, asks for
// the frame and then the light's depth map, and never has more than one
// request in flight (a change made meanwhile is sent when the answer comes).
"use strict";

const $ = (id) => document.getElementById(id);
const state = {
  inFlight: false, dirty: false, playing: false, lastTick: 0, frameUrl: null, depthUrl: null, errorSource: null,
  camera: null,  // the camera as moved ({position, target}); null: the scene's own
  frameOutput: "color",  // the output the frame shown is
  lastDepth: 0,  // when the depth map last arrived (performance.now())
  depthStale: false,  // whether the depth map shown is older than the frame
  custom: null,  // the scene editor's request fragment being rendered; null: the form's scene
  lightAtZero: null,  // the light's position at time 0, unrounded: what the request sends (see "The light")
};
const DEPTH_INTERVAL_PLAYING_MS = 1000;

function number(id) {
  const value = Number($(id).value);
  return Number.isFinite(value) ? value : 0;
}

// The request body for the current settings. Only fields that matter for
// the chosen settings are sent (the server reports unused ones).
function buildRequest() {
  const sun = sunMode();
  const perspective = !sun && $("projection").value === "perspective";
  const fixed = $("fit").value === "fixed";
  const enabled = $("enabled").checked;
  const light = {
    position: lightAtZero().map(round),
    color: $("color").value,
    ambient: number("ambient"),
    projection: $("projection").value,
  };
  if (number("size") > 0) light.size = number("size");
  // The API's defaults are left out, so that a request stays as short as
  // the settings allow.
  const target = ["ltx", "lty", "ltz"].map(number);
  if (target.some((x) => x !== 0)) light.target = target;
  if (number("orbit") !== apiDefault("Light", "orbit_deg_per_s")) light.orbit_deg_per_s = number("orbit");
  if (sun) {
    // The sun places the light: no position (its default distance serves
    // fit "fixed"), target, projection or orbit speed to send.
    for (const key of ["position", "target", "projection", "orbit_deg_per_s"]) delete light[key];
    light.sun = sunClock();
  }
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
  const view = model ? modelView(model) : { scene: $("scene").value };
  // A built-in scene's own camera is left to the server (a shorter request,
  // the same frame); a model's framing camera is always sent.
  if (state.camera) view.camera = { position: state.camera.position, target: state.camera.target };
  const [width, height] = $("resolution").value.split("x").map(Number);
  const body = {
    width,
    height,
    ...view,
    light,
    time: number("time"),
    shadow,
    output: $("view").value,
  };
  return state.custom ? withFragment(body, state.custom) : body;
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

// --- Access token ------------------------------------------------------------------
// A server run with --tokens answers 401 without a token: the panel asks for
// one, keeps it for this tab only (sessionStorage: gone when the tab
// closes) and sends it as "Authorization: Bearer" on every call it makes.

const TOKEN_KEY = "umbra.token";
const auth = { asking: null, memory: "" };  // the question being asked; the token if storage is off

function savedToken() {
  try {
    return sessionStorage.getItem(TOKEN_KEY) || "";
  } catch (_) {
    return auth.memory;
  }
}

function saveToken(token) {
  auth.memory = token;
  try {
    sessionStorage.setItem(TOKEN_KEY, token);
  } catch (_) { /* storage off: kept in memory until the page is left */ }
}

function withToken(headers = {}) {
  const token = savedToken();
  return token ? { ...headers, Authorization: `Bearer ${token}` } : headers;
}

// Shows the token field; resolves once a token is entered. Calls refused
// at once (the lists, a frame) share the one question.
function askForToken(rejected) {
  if (!auth.asking) {
    auth.asking = new Promise((resolve) => {
      $("auth-reason").textContent = rejected
        ? "The server did not accept that token (401): enter another."
        : "This server needs an access token (401).";
      $("auth").hidden = false;
      $("token").value = "";
      $("token").focus();
      $("auth").onsubmit = (e) => {
        e.preventDefault();
        const token = $("token").value.trim();
        if (!token) return;
        saveToken(token);
        $("auth").hidden = true;
        auth.asking = null;
        resolve();
      };
    });
  }
  return auth.asking;
}

// After a 401 to a call sent with `sent`: asks for a token, unless another
// call has brought a new one meanwhile (then that one is tried).
async function tokenAfter401(sent) {
  if (savedToken() === sent) await askForToken(sent !== "");
}

// fetch with the token, asking for one (and trying again) on 401.
async function apiFetch(path, init = {}) {
  for (;;) {
    const sent = savedToken();
    const response = await fetch(path, { ...init, headers: withToken(init.headers) });
    if (response.status !== 401) return response;
    await tokenAfter401(sent);
  }
}

async function post(path, body) {
  let response;
  try {
    response = await apiFetch(path, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
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
    sun: response.headers.get("Umbra-Sun"),
    views: response.headers.get("Umbra-Shadow-Views"),
    figures: response.headers.get("Umbra-Shadow-Error"),
    certified: response.headers.get("Umbra-Certified"),
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
  // In the Sun hours mode no frame is shown: the change is rendered once
  // the panel is back to frames.
  if (sunHoursMode()) {
    state.frameOwed = true;
    if (state.playing) togglePlay();
    saveToUrl();
    return;
  }
  state.frameOwed = false;
  if (fieldsHeld()) {
    state.lastTick = 0;  // playing resumes from here once the field is fixed
    return;
  }
  if (state.inFlight) {
    state.dirty = true;
    return;
  }
  state.inFlight = true;
  state.dirty = false;
  const started = performance.now();
  if (state.playing) {
    const now = performance.now();
    if (state.lastTick) {
      // A sun's Play runs the clock faster than real time: a day in tens of seconds.
      const rate = sunMode() ? number("sun_speed") : 1;
      $("time").value = (number("time") + rate * (now - state.lastTick) / 1000).toFixed(3);
      showLightAtTime();
    }
    state.lastTick = now;
  }
  const body = buildRequest();
  showLightNow(body.light, body.time);
  saveToUrl();
  try {
    const frame = await post("/api/render", body);
    replaceImage($("frame"), frame.blob, "frameUrl");
    showOutput(body.output, frame.figures);
    showSunNow(body, frame.sun);
    // While a newer change waits (a drag), the next frame comes first: the
    // depth map follows once the changes stop.
    // While playing, it is drawn at most once a second: it costs a second
    // render, which would halve the frame rate.
    const depthDue = !state.playing || performance.now() - state.lastDepth >= DEPTH_INTERVAL_PLAYING_MS;
    if (!state.dirty && depthDue) {
      const depth = await post("/api/depth", { ...body, output: "depth" });
      replaceImage($("depth"), depth.blob, "depthUrl");
      showDepthTiles(depth.views);
      state.lastDepth = performance.now();
    }
    state.depthStale = state.dirty || !depthDue;
    const t = parseTiming(frame.timing);
    const ms = performance.now() - started;
    const fps = state.playing ? ` · ${(1000 / ms).toFixed(1)} frames/s` : "";
    $("timing").textContent =
      `server: shadow ${fmt(t.shadow)} · main ${fmt(t.main)} · readback ${fmt(t.readback)} · encode ${fmt(t.encode)}` +
      (t.settle !== undefined ? ` · settle ${fmt(t.settle)}` : "") + " ms" +
      ` · round trip ${ms.toFixed(0)} ms${fps}` + (frame.views ? ` · light views: ${frame.views}` : "") +
      (frame.certified ? ` · ${certifiedText(frame.certified)}` : "") +
      (frame.unused ? ` · unused: ${frame.unused}` : "");
    $("frame-info").textContent = `(${body.output}, t = ${body.time.toFixed(2)} s)`;
    clearError();
  } catch (e) {
    showError(e.message);
    if (state.custom) $("scene-json-status").textContent = `The editor's scene was not rendered: ${e.message}`;
    if (state.playing) togglePlay();
  } finally {
    state.inFlight = false;
  }
  if (state.dirty || state.playing) requestFrame();
}

function fmt(v) {
  return v === undefined ? "–" : v.toFixed(1);
}

// Filter "exact": "uncertain=0.2288%, ray_cast=1186, pixels=518400, path=maps" ->
// "certified: 0.2288 % of pixels ray cast (1,186 of 518,400), by the maps".
const CERTIFIED_PATHS = { maps: "by the maps", proofs: "without maps", "ray-cast": "all ray cast" };
function certifiedText(header) {
  const f = parseFigures(header);
  if (!("uncertain" in f)) return `certified: ${header}`;
  const count = (key) => (/^\d+$/.test(f[key] || "") ? Number(f[key]).toLocaleString("en") : "?");
  const path = f.path in CERTIFIED_PATHS ? `, ${CERTIFIED_PATHS[f.path]}` : "";
  return `certified: ${f.uncertain.replace("%", " %")} of pixels ray cast (${count("ray_cast")} of ${count("pixels")})${path}`;
}

function togglePlay() {
  state.playing = !state.playing;
  state.lastTick = 0;
  $("play").textContent = state.playing ? "Pause" : "Play";
  $("play").setAttribute("aria-pressed", String(state.playing));
  if (state.playing) requestFrame();
  // Paused, the depth map catches up with the last frame.
  else if (state.depthStale) requestFrame();
}

function syncFixedSettings() {
  syncLightMode();
  const fixed = $("fit").value === "fixed";
  const perspective = !sunMode() && $("projection").value === "perspective";
  $("fixed-settings").setAttribute("aria-disabled", String(!fixed));
  for (const id of ["near", "far", "half"]) $(id).disabled = !fixed;
  $("half").disabled = !fixed || perspective;
  $("cascades").disabled = fixed || perspective;
}

// --- The error view ---------------------------------------------------------------
// The error PNG is |v - v_exact| in red (false shadow) or blue (false
// light): most errors are a few levels out of 255, black to the eye. The
// panel shows it amplified by the chosen gain on a canvas (the <img> keeps
// the PNG as sent, for "Copy as curl"), with the server's figures beside it.

const FIGURES = [
  ["mae", "MAE"],
  ["wrong", "wrong (> 0.5)"],
  ["false_shadow", "false shadow"],
  ["false_light", "false light"],
  ["artifacts", "artifacts (> 0.1)"],
  ["pixels", "pixels measured"],
  ["interior_pixels", "interior pixels"],
];

// "mae=0.00015, wrong=0.0027%, ..." -> { mae: "0.00015", wrong: "0.0027%", ... }
function parseFigures(header) {
  const figures = {};
  for (const entry of (header || "").split(",")) {
    const match = entry.trim().match(/^(\w+)=(.+)$/);
    if (match) figures[match[1]] = match[2];
  }
  return figures;
}

function showFigures(header) {
  const figures = parseFigures(header);
  const list = $("error-figures");
  list.replaceChildren();
  for (const [key, name] of FIGURES) {
    if (!(key in figures)) continue;
    const value = /^\d+$/.test(figures[key]) ? Number(figures[key]).toLocaleString("en") : figures[key].replace("%", " %");
    list.append(Object.assign(document.createElement("dt"), { textContent: name }),
                Object.assign(document.createElement("dd"), { textContent: value, id: `figure-${key}` }));
  }
  if (!list.children.length) list.append(Object.assign(document.createElement("dd"), { textContent: "The server sent no figures." }));
}

// Shows the frame as sent, or for "error" the amplified heatmap and its
// figures.
function showOutput(output, figures) {
  const error = output === "error";
  state.frameOutput = output;
  $("frame").hidden = error;
  $("heatmap").hidden = !error;
  $("error-panel").hidden = !error;
  if (!error) return;
  showFigures(figures);
  $("frame").decode().then(drawHeatmap, () => {});
}

function drawHeatmap() {
  if (state.frameOutput !== "error") return;
  const image = $("frame");
  const canvas = $("heatmap");
  const gain = Number($("gain").value);
  canvas.width = image.naturalWidth;
  canvas.height = image.naturalHeight;
  const context = canvas.getContext("2d", { willReadFrequently: true });
  context.drawImage(image, 0, 0);
  if (gain !== 1) {
    const pixels = context.getImageData(0, 0, canvas.width, canvas.height);
    const data = pixels.data;
    for (let i = 0; i < data.length; i += 4) {
      data[i] = Math.min(255, data[i] * gain);
      data[i + 1] = Math.min(255, data[i + 1] * gain);
      data[i + 2] = Math.min(255, data[i + 2] * gain);
    }
    context.putImageData(pixels, 0, 0);
  }
  drawLegend(gain);
}

// Two ramps, black to red and black to blue, over the error that the gain
// brings to full brightness.
function drawLegend(gain) {
  const canvas = $("legend-bar");
  const context = canvas.getContext("2d");
  const half = canvas.height / 2;
  for (const [row, colour] of [[0, "#ff0000"], [half, "#0000ff"]]) {
    const ramp = context.createLinearGradient(0, 0, canvas.width, 0);
    ramp.addColorStop(0, "#000000");
    ramp.addColorStop(1, colour);
    context.fillStyle = ramp;
    context.fillRect(0, row, canvas.width, half);
  }
  const full = 1 / gain;
  $("legend").textContent = `Gain ×${gain}: brightness = ${gain} × |v − v_exact|, full at ${full.toPrecision(2)} or more. ` +
    "Red: shadowed where exactly lit (false shadow); blue: lit where exactly shadowed (false light); black: no error.";
}

// --- The depth map ---------------------------------------------------------------
// The depth PNG tiles the light's views in a square grid (the server's
// depth_preview.frag), laid out as its Umbra-Shadow-Views header says:
// grid=G tiles a side, view 0 top left, row by row, and for a cube the face
// each view is (faces=+X,-X,...); cells past the last view are grey (0.5).
// Each view's depth spans only part of 0..1, so the panel shows every view
// on its own canvas, stretched from its nearest texel (black) to its
// farthest drawn one (white); texels where nothing was drawn hold the far
// plane (255) and are shown in FAR_COLOUR. The <img> keeps the PNG as sent.

const FAR_COLOUR = [29, 43, 69];
const DEPTH_WORK_SIZE = 2048;  // larger maps are read scaled down (nearest texel), to bound the memory

// "cube; views=6; size=2048; grid=3; faces=+X,-X,+Y,-Y,+Z,-Z" ->
// { layout: "cube", views: 6, grid: 3, faces: ["+X", ...] }; an unknown or
// missing header: one view in one tile.
function parseViews(header) {
  const layout = ((header || "").split(";")[0] || "").trim() || "single";
  const match = (header || "").match(/views=(\d+)/);
  const views = match ? Math.max(1, Number(match[1])) : 1;
  const gridMatch = (header || "").match(/grid=(\d+)/);
  const grid = gridMatch ? Math.max(1, Number(gridMatch[1])) : 1;
  const facesMatch = (header || "").match(/faces=([^;\s]+)/);
  const faces = facesMatch ? facesMatch[1].split(",").map((f) => f.replace("-", "−")) : [];
  return { layout, views, grid, faces };
}

function viewLabel(layout, i, views, faces) {
  if (layout === "cube" && faces[i]) return `cube face ${faces[i]}`;
  if (layout === "cascades") return `cascade ${i}`;
  return views === 1 ? "the light's view" : `view ${i}`;
}

function showDepthTiles(header) {
  const { layout, views, grid, faces } = parseViews(header);
  const image = $("depth");
  const src = image.src;
  // A newer map may replace this one before it is decoded: draw each with its own layout.
  image.decode().then(() => { if (image.src === src) drawDepthTiles(image, layout, views, grid, faces); }, () => {});
}

function drawDepthTiles(image, layout, views, grid, faces) {
  const size = Math.min(image.naturalWidth, DEPTH_WORK_SIZE);
  if (!size) return;
  const work = Object.assign(document.createElement("canvas"), { width: size, height: size });
  const context = work.getContext("2d", { willReadFrequently: true });
  context.imageSmoothingEnabled = false;  // no texel mixed with a neighbour tile's
  context.drawImage(image, 0, 0, size, size);
  const data = context.getImageData(0, 0, size, size).data;
  const container = $("depth-tiles");
  container.style.setProperty("--depth-columns", String(Math.min(grid, views)));
  container.dataset.layout = layout;
  const tiles = [];
  for (let i = 0; i < views; i += 1) {
    const column = i % grid, row = Math.floor(i / grid);
    const x0 = Math.round((column * size) / grid), x1 = Math.round(((column + 1) * size) / grid);
    const y0 = Math.round((row * size) / grid), y1 = Math.round(((row + 1) * size) / grid);
    tiles.push(stretchedTile(data, size, x0, y0, x1 - x0, y1 - y0, viewLabel(layout, i, views, faces)));
  }
  container.replaceChildren(...tiles);
}

// One view's tile: its grey levels stretched to its own min..max, the far
// plane (255) left out of both and drawn in FAR_COLOUR.
function stretchedTile(data, size, x0, y0, width, height, label) {
  // One texel in from the edges: a scaled-down map's nearest texel there may be the next tile's.
  let min = 255, max = 0;
  for (let y = y0 + 1; y < y0 + height - 1; y += 1) {
    for (let x = x0 + 1; x < x0 + width - 1; x += 1) {
      const v = data[4 * (y * size + x)];
      if (v === 255) continue;
      if (v < min) min = v;
      if (v > max) max = v;
    }
  }
  const empty = min > max;
  const canvas = Object.assign(document.createElement("canvas"), { width, height });
  const context = canvas.getContext("2d");
  const out = context.createImageData(width, height);
  const range = max - min;
  for (let y = 0; y < height; y += 1) {
    for (let x = 0; x < width; x += 1) {
      const v = data[4 * ((y0 + y) * size + x0 + x)];
      const o = 4 * (y * width + x);
      if (v === 255 || empty) {
        [out.data[o], out.data[o + 1], out.data[o + 2]] = FAR_COLOUR;
      } else {
        const grey = range > 0 ? Math.round((255 * (clamp(v, min, max) - min)) / range) : 128;
        out.data[o] = out.data[o + 1] = out.data[o + 2] = grey;
      }
      out.data[o + 3] = 255;
    }
  }
  context.putImageData(out, 0, 0);
  const text = empty ? `${label} (empty)` : label;
  canvas.setAttribute("role", "img");
  canvas.setAttribute("aria-label", `${text}: grey levels ${min}…${max} of 255 stretched to black…white`);
  const figure = document.createElement("figure");
  figure.className = "depth-tile";
  figure.dataset.rawMin = empty ? "" : String(min);
  figure.dataset.rawMax = empty ? "" : String(max);
  figure.append(canvas, Object.assign(document.createElement("figcaption"), { textContent: text }));
  return figure;
}

// --- The light ------------------------------------------------------------------
// The API's light.position is where the light is at time 0; the server
// turns it about the vertical axis through light.target by
// time x orbit_deg_per_s degrees, counter-clockwise seen from above.
// The position fields show where the light is at the time shown, so they
// follow it while playing and a typed (or Alt-dragged) position is where the
// light is in the frame. One rule links what is shown and what is sent:
//   shown = turned(sent, +time x speed),  sent = turned(shown, -time x speed).
// state.lightAtZero keeps the sent position unrounded, so that the fields'
// six significant digits do not drift over a long play. The address keeps
// the fields and the time (reloading shows the same light); the request and
// "Copy as curl" send the position at time 0.

const LIGHT_FIELDS = ["lx", "ly", "lz"];
const LIGHT_TARGET_FIELDS = ["ltx", "lty", "ltz"];

function lightTarget() {
  return LIGHT_TARGET_FIELDS.map(number);
}

// Degrees the light has turned at the time shown.
function lightTurn() {
  return (number("time") * number("orbit")) % 360;
}

// As the server's orbit_light_position.
function orbitPosition(position, target, degrees) {
  const angle = (degrees % 360) * Math.PI / 180;
  const [x, y, z] = sub(position, target);
  return add(target, [x * Math.cos(angle) + z * Math.sin(angle), y, -x * Math.sin(angle) + z * Math.cos(angle)]);
}

function lightFieldsValid() {
  return [...LIGHT_FIELDS, ...LIGHT_TARGET_FIELDS, "orbit", "time"].every((id) => !fieldProblem($(id)));
}

// The position the request sends, taken from the fields when they changed.
function lightAtZero() {
  if (!state.lightAtZero) state.lightAtZero = orbitPosition(LIGHT_FIELDS.map(number), lightTarget(), -lightTurn());
  return state.lightAtZero;
}

// The position, target or speed was edited: the light stays where the
// fields show it, and its position at time 0 follows.
function lightFieldsEdited() {
  if (!lightFieldsValid()) return;
  state.lightAtZero = null;
  lightAtZero();  // now, at the time shown: a later change of time turns this position
}

// The time changed (typed, or Play): the fields follow the light.
// (In sun mode too, where the fields are hidden: switched back to the
// orbit, they show where the orbiting light is at the time shown.)
function showLightAtTime() {
  if (!lightFieldsValid()) return;
  const now = orbitPosition(lightAtZero(), lightTarget(), lightTurn());
  LIGHT_FIELDS.forEach((id, i) => { $(id).value = String(round(now[i])); });
}

// Under the fields: what the request sends, where that differs from them.
function showLightNow(light, time) {
  // The scene editor can send anything: the server judges it, this line only follows a valid light.
  const triple = (v) => Array.isArray(v) && v.length === 3 && v.every(Number.isFinite);
  if (!light || !triple(light.position) || !Number.isFinite(time)) {
    $("light-now").textContent = "";
    return;
  }
  const shown = LIGHT_FIELDS.map(number);
  const same = light.position.every((x, i) => Math.abs(x - shown[i]) < 1e-9);
  $("light-now").textContent = same ? "" :
    `Shown at t = ${time.toFixed(2)} s; sent as position (${light.position.map((x) => x.toFixed(3)).join(", ")}) at time 0.`;
}

// --- The sun -----------------------------------------------------------------------
// "Placed by the sun" sends light.sun: the place, and the date and time
// (UTC) at time 0; `time` then advances that clock, and Play runs it at
// "Play speed" clock seconds per real second. The server answers with
// Umbra-Sun, the sun's azimuth and elevation, shown under the fields.

function sunMode() {
  return $("light_mode").value === "sun";
}

function sunClock() {
  // RFC 3339 needs the seconds, which a time field of step 60 leaves out.
  const time = $("sun_time").value.length === 5 ? `${$("sun_time").value}:00` : $("sun_time").value;
  const clock = { latitude: number("sun_lat"), longitude: number("sun_lon"), utc: `${$("sun_date").value}T${time}Z` };
  if (number("sun_north") !== 0) clock.north_deg = number("sun_north");
  return clock;
}

// Orbit settings or sun settings: the other kind is hidden and disabled,
// so it is neither checked nor sent.
function syncLightMode() {
  const sun = sunMode();
  $("sun-settings").hidden = !sun;
  $("orbit-settings").hidden = sun;
  for (const e of $("sun-settings").querySelectorAll("input, select")) e.disabled = !sun;
  for (const e of $("orbit-settings").querySelectorAll("input")) e.disabled = sun;
  $("projection").disabled = sun;  // a sun is a directional light
  if (!sun) $("sun-now").textContent = "";
  syncSunCity();
}

// The place list shows the city whose coordinates the fields hold, if any.
function syncSunCity() {
  const here = `${number("sun_lat")},${number("sun_lon")}`;
  const match = Array.from($("sun_city").options).find((o) => o.value === here);
  $("sun_city").value = match ? match.value : "";
}

function chooseSunCity() {
  if (!$("sun_city").value) return;
  const [latitude, longitude] = $("sun_city").value.split(",");
  $("sun_lat").value = latitude;
  $("sun_lon").value = longitude;
  for (const id of ["sun_lat", "sun_lon"]) markField($(id), "");
  requestFrame();
}

// "Umbra-Sun: azimuth_deg=210.5597; elevation_deg=12.0704" under the fields,
// with the clock it was read at (utc + time).
function showSunNow(body, header) {
  const sun = body.light && body.light.sun;
  const match = (header || "").match(/azimuth_deg=(-?[\d.]+); elevation_deg=(-?[\d.]+)/);
  if (!sun || !match) {
    $("sun-now").textContent = "";
    return;
  }
  const clock = new Date(Date.parse(sun.utc) + 1000 * body.time);
  const when = Number.isNaN(clock.getTime()) ? sun.utc : clock.toISOString().replace("T", " ").replace(/:\d\d\.\d+Z$/, " UTC");
  const [azimuth, elevation] = [Number(match[1]), Number(match[2])];
  $("sun-now").textContent = `${when}: sun at azimuth ${azimuth.toFixed(2)}°, elevation ${elevation.toFixed(2)}°` +
    (elevation <= 0 ? " — below the horizon: ambient light only." : ".");
  $("sun-now").dataset.azimuth = match[1];
  $("sun-now").dataset.elevation = match[2];
}

// Alt-drag on the frame moves the light about its target as the camera
// orbits its own: across turns it about the vertical axis, up raises it.
function moveLight(dx, dy, height) {
  if (sunMode() || !lightFieldsValid()) return;  // the sun is moved by the clock
  const moved = orbit({ position: LIGHT_FIELDS.map(number), target: lightTarget() }, dx, -dy, height).position;
  LIGHT_FIELDS.forEach((id, i) => { $(id).value = String(round(moved[i])); });
  lightFieldsEdited();
  requestFrame();
}

// --- Camera ---------------------------------------------------------------------
// The camera orbits, dollies and pans about its target as three.js's
// OrbitControls do: left-drag orbits, the wheel (or a pinch) dollies, right-
// or shift-drag (or two fingers) pans. Every move only changes state.camera
// and asks for a frame; requestFrame sends the newest camera when the frame
// in flight arrives, so dragging runs at the panel's frame rate.

const CAMERA_FIELDS = { position: ["cx", "cy", "cz"], target: ["ctx", "cty", "ctz"] };
const POLAR_MARGIN = 0.01;  // radians kept from the poles: straight up or down, "up" would be undefined
const sceneCameras = new Map();  // built-in scene name -> its camera, from GET /api/scenes
const sceneObjects = new Map();  // built-in scene name -> its objects, from GET /api/scenes

const sub = (a, b) => a.map((x, i) => x - b[i]);
const add = (a, b) => a.map((x, i) => x + b[i]);
const scale = (a, k) => a.map((x) => x * k);
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const clamp = (x, lo, hi) => Math.min(Math.max(x, lo), hi);

// The chosen scene's own camera, or null where the panel does not know it
// (a model the server does not list, a server without /api/scenes).
function defaultCamera() {
  const custom = customCamera();
  if (custom) return custom;
  const model = chosenModel();
  if (model) return modelView(model).camera || null;
  return sceneCameras.get($("scene").value) || null;
}

function currentCamera() {
  return state.camera || defaultCamera();
}

function sameCamera(a, b) {
  return !!a && !!b && ["position", "target"].every((k) => a[k].every((x, i) => x === b[k][i]));
}

// Every camera the panel sends is rounded as the address bar writes it,
// so a link reproduces the very request (and frame).
function roundedCamera(camera) {
  return { position: camera.position.map(round), target: camera.target.map(round) };
}

// Takes a moved camera: kept (and sent) unless it is the scene's own.
function setCamera(camera) {
  const rounded = camera && roundedCamera(camera);
  state.camera = rounded && !sameCamera(rounded, defaultCamera()) ? rounded : null;
  showCamera();
  requestFrame();
}

// The fields show the camera in use; blank where it is not known.
function showCamera() {
  const camera = currentCamera();
  for (const key of ["position", "target"]) {
    CAMERA_FIELDS[key].forEach((id, i) => {
      $(id).value = camera ? String(camera[key][i]) : "";
      markField($(id), "");
    });
  }
}

// The camera the fields hold, or null (each bad field marked) where one
// cannot be sent.
function cameraFromFields() {
  let good = true;
  for (const id of [...CAMERA_FIELDS.position, ...CAMERA_FIELDS.target]) {
    const problem = fieldProblem($(id));
    markField($(id), problem);
    if (problem) good = false;
  }
  if (!good) return null;
  const camera = {
    position: CAMERA_FIELDS.position.map((id) => Number($(id).value)),
    target: CAMERA_FIELDS.target.map((id) => Number($(id).value)),
  };
  if (sameCamera({ position: camera.position, target: camera.position }, { position: camera.target, target: camera.target })) {
    markField($("cz"), "the position equals the target: the camera would look nowhere");
    return null;
  }
  return camera;
}

// Spherical coordinates about the target: theta about +Y from +Z, phi
// from +Y.
function spherical(camera) {
  const offset = sub(camera.position, camera.target);
  const radius = Math.hypot(...offset);
  return { radius, theta: Math.atan2(offset[0], offset[2]), phi: Math.acos(clamp(offset[1] / radius, -1, 1)) };
}

function fromSpherical(target, { radius, theta, phi }) {
  return add(target, [radius * Math.sin(phi) * Math.sin(theta), radius * Math.cos(phi), radius * Math.sin(phi) * Math.cos(theta)]);
}

// A drag across the frame's full height turns the camera a full circle
// (OrbitControls' rate); the polar angle stops short of the poles.
function orbit(camera, dx, dy, height) {
  const s = spherical(camera);
  s.theta -= (2 * Math.PI * dx) / height;
  s.phi = clamp(s.phi - (2 * Math.PI * dy) / height, POLAR_MARGIN, Math.PI - POLAR_MARGIN);
  return { position: fromSpherical(camera.target, s), target: camera.target };
}

// Scales the distance to the target by factor (> 1: away), kept where
// the server takes it (coordinates within 10^6, never on the target).
function dolly(camera, factor) {
  const s = spherical(camera);
  s.radius = clamp(s.radius * factor, 1e-3, 1e5);
  return { position: fromSpherical(camera.target, s), target: camera.target };
}

// Moves position and target together in the view plane so that the scene
// follows the pointer at the target's distance.
function pan(camera, dx, dy, height) {
  const offset = sub(camera.position, camera.target);
  const distance = Math.hypot(...offset);
  const perPixel = (2 * distance * Math.tan((apiDefault("Camera", "fov_y_deg") * Math.PI) / 360)) / height;
  const forward = scale(offset, -1 / distance);
  let right = cross(forward, [0, 1, 0]);
  right = scale(right, 1 / (Math.hypot(...right) || 1));
  const up = cross(right, forward);
  const move = add(scale(right, -dx * perPixel), scale(up, dy * perPixel));
  return { position: add(camera.position, move), target: add(camera.target, move) };
}

// Pointer Events cover mouse, pen and touch alike. One pointer orbits (or
// pans, with the right button or Shift); two pinch to dolly and move
// together to pan.
const drag = { pointers: new Map(), pan: false, light: false };

function pointerDown(e) {
  if (!currentCamera() || (e.pointerType === "mouse" && e.button !== 0 && e.button !== 2)) return;
  e.preventDefault();
  try {
    $("viewport").setPointerCapture(e.pointerId);  // the drag goes on outside the frame
  } catch (_) { /* a synthetic pointer: nothing to capture */ }
  drag.pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
  drag.pan = e.button === 2 || e.shiftKey || e.ctrlKey || e.metaKey;
  drag.light = e.altKey && e.button === 0;
}

// The centre of the two touch points and their spread.
function pinch() {
  const [a, b] = Array.from(drag.pointers.values());
  return { x: (a.x + b.x) / 2, y: (a.y + b.y) / 2, spread: Math.hypot(a.x - b.x, a.y - b.y) || 1 };
}

function pointerMove(e) {
  const last = drag.pointers.get(e.pointerId);
  if (!last) return;
  const height = $("viewport").clientHeight || 1;
  let camera = currentCamera();
  if (drag.pointers.size === 1) {
    const dx = e.clientX - last.x, dy = e.clientY - last.y;
    drag.pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    if (drag.light) return moveLight(dx, dy, height);
    camera = drag.pan ? pan(camera, dx, dy, height) : orbit(camera, dx, dy, height);
  } else if (drag.pointers.size === 2) {
    const before = pinch();
    drag.pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    const after = pinch();
    camera = pan(dolly(camera, before.spread / after.spread), after.x - before.x, after.y - before.y, height);
  } else {
    return;
  }
  setCamera(camera);
}

function pointerUp(e) {
  drag.pointers.delete(e.pointerId);
}

// A wheel notch (100 px) dollies by 5 %, as OrbitControls does; lines and
// pages are made pixels first.
function wheel(e) {
  const camera = currentCamera();
  if (!camera) return;
  e.preventDefault();
  const pixels = e.deltaY * (e.deltaMode === 1 ? 40 : e.deltaMode === 2 ? 800 : 1);
  setCamera(dolly(camera, Math.pow(1 / 0.95, clamp(pixels / 100, -10, 10))));
}

function cameraToUrl(query) {
  if (!state.camera) return query;
  // Commas written as they are: URLSearchParams would escape them.
  const camera = `camera=${state.camera.position.join(",")}&camera_target=${state.camera.target.join(",")}`;
  return query ? `${query}&${camera}` : camera;
}

// The address's camera, or null (and its names in skipped) where it is not
// three finite numbers each.
function cameraFromUrl(params, skipped) {
  if (!params.has("camera") && !params.has("camera_target")) return null;
  const triple = (name) => {
    const values = (params.get(name) || "").split(",").map((v) => (v.trim() === "" ? NaN : Number(v)));
    return values.length === 3 && values.every(Number.isFinite) ? values : null;
  };
  const fallback = defaultCamera();
  const position = params.has("camera") ? triple("camera") : fallback && fallback.position;
  const target = params.has("camera_target") ? triple("camera_target") : fallback && fallback.target;
  if (!position || !target || position.every((x, i) => x === target[i])) {
    skipped.push(...["camera", "camera_target"].filter((name) => params.has(name)));
    return null;
  }
  return { position, target };
}

// --- Fields whose value cannot be sent --------------------------------------------
// A number field the browser cannot read ("1e"), an empty one or one out of
// its range is marked, with its message beside it, and nothing is sent
// until it is fixed: sending 0 in its place would move the light to the
// horizon without a word.

function fieldProblem(input) {
  if (input.disabled) return "";
  if (input.type === "date" || input.type === "time") {
    if (input.validity.badInput || input.value === "") return `a ${input.type} is needed`;
    if (input.validity.rangeUnderflow || input.validity.rangeOverflow) return `from ${input.min} to ${input.max}`;
    return "";
  }
  if (input.validity.badInput) return "not a number";
  if (input.value.trim() === "") return "a number is needed";
  const value = Number(input.value);
  if (!Number.isFinite(value)) return "not a number";
  if (input.min !== "" && value < Number(input.min)) return `at least ${input.min}`;
  if (input.max !== "" && value > Number(input.max)) return `at most ${input.max}`;
  if ("integer" in input.dataset && !Number.isInteger(value)) return "a whole number";
  return "";
}

// "Light position y": the field's label with its group's.
function fieldName(input) {
  const group = input.closest("[role=group]");
  const label = input.labels && input.labels[0] ? input.labels[0].textContent.trim() : input.id;
  return group ? `${group.getAttribute("aria-label")} ${label}` : label;
}

// `name` is how the message names the field (default: its group and label).
function markField(input, problem, name = fieldName(input)) {
  let message = document.getElementById(`${input.id}-problem`);
  if (!problem) {
    input.removeAttribute("aria-invalid");
    input.removeAttribute("aria-describedby");
    if (message) message.remove();
    return;
  }
  if (!message) {
    message = document.createElement("p");
    message.id = `${input.id}-problem`;
    message.className = "field-problem";
    (input.closest(".triple, .row") || input).after(message);
  }
  input.setAttribute("aria-invalid", "true");
  input.setAttribute("aria-describedby", message.id);
  message.textContent = `${name}: ${problem}. Nothing is sent until it is fixed.`;
}

// Marks every field that cannot be sent and says so under the frame; true
// if there is one. The camera's fields are judged as they are typed in
// (cameraFromFields): they hold no setting of their own.
function fieldsHeld() {
  const bad = [];
  for (const input of $("controls").querySelectorAll("input[type=number], input[type=date], input[type=time]")) {
    if (isSunHoursField(input)) continue;  // the analysis's own: judged when it is run
    if (!isCameraField(input)) markField(input, fieldProblem(input));
    if (input.getAttribute("aria-invalid") === "true") bad.push(fieldName(input));
  }
  $("held").hidden = bad.length === 0;
  $("held").textContent = bad.length ? `Not sent: ${bad.join(", ")} cannot be sent as it is (marked above).` : "";
  return bad.length > 0;
}

// A light's size softens shadows with the PCSS filter only (the server
// refuses a size with "pcf", "hard" or "exact"): setting a size chooses PCSS, and
// choosing another filter afterwards says that the size is not used.
function syncSizeNote(changed) {
  const soft = number("size") > 0 && $("enabled").checked;
  if (changed === "size" && soft && $("filter").value !== "pcss") {
    $("filter").value = "pcss";
    $("size-note").textContent = "Filter set to PCSS: only PCSS softens shadows by the light's size.";
  } else if (soft && $("filter").value !== "pcss") {
    $("size-note").textContent = `Size not used: the ${$("filter").selectedOptions[0].textContent} filter draws hard-edged ` +
      "shadows; choose PCSS for soft ones.";
  } else if (changed !== "size" || !soft) {
    $("size-note").textContent = "";
  }
}

// --- Settings in the address bar ---------------------------------------------
// Every control whose value differs from the page's default is a query
// parameter named after the control, so the address is a link to this view.
// lx, ly and lz hold the light's position at time 0, as the API's
// light.position does (the fields show it turned to the time shown).

function controls() {
  return Array.from($("controls").elements).filter((e) => e.name);
}

// A select's default is its option marked selected in the page, else its
// first option (which the browser selects without marking it).
function isDefault(e) {
  if (e.type === "checkbox") return e.checked === e.defaultChecked;
  if (e.tagName === "SELECT") return e.selectedIndex === Math.max(0, Array.from(e.options).findIndex((o) => o.defaultSelected));
  return urlValue(e) === e.defaultValue;
}

function urlValue(e) {
  if (e.type === "checkbox") return e.checked ? "1" : "0";
  const light = LIGHT_FIELDS.indexOf(e.id);
  return light >= 0 && lightFieldsValid() ? String(round(lightAtZero()[light])) : e.value;
}

function saveToUrl() {
  const params = new URLSearchParams();
  for (const e of controls()) {
    if (isDefault(e)) continue;
    const value = urlValue(e);
    // A model is chosen in the scene list but named by its own parameter.
    if (e.id === "scene" && value.startsWith(MODEL_PREFIX)) params.set("model", value.slice(MODEL_PREFIX.length));
    else params.set(e.name, value);
  }
  sceneJsonToUrl(params);
  const query = cameraToUrl(params.toString());
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
    syncAnimations();  // its animations, before the address chooses one
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
    } else if (e.type === "date" || e.type === "time") {
      e.value = value;  // the browser empties a value it cannot take
      if (e.value !== value) {
        e.value = e.defaultValue;
        skipped.push(e.name);
      }
    } else if (e.type === "color") {
      if (/^#[0-9a-fA-F]{6}$/.test(value)) e.value = value.toLowerCase();
      else skipped.push(e.name);
    }
  }
  state.lightAtZero = null;
  if (lightFieldsValid()) {
    state.lightAtZero = LIGHT_FIELDS.map(number);
    showLightAtTime();
  }
  sceneJsonFromUrl(params, skipped);
  const camera = cameraFromUrl(params, skipped);
  state.camera = camera && roundedCamera(camera);
  if (sameCamera(state.camera, defaultCamera())) state.camera = null;
  const known = new Set(controls().map((e) => e.name).concat("model", "camera", "camera_target", "scene_json"));
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
    const response = await apiFetch(path);
    return response.ok ? await response.json() : null;
  } catch (_) {
    return null;
  }
}

// --- The API's defaults -------------------------------------------------------------
// The controls start at the API's own defaults, read from the server's
// OpenAPI document (GET /api/openapi.json) rather than copied into the page:
// each control below names the field whose default it takes. They become
// the controls' default values, so that the address (saveToUrl) still
// leaves out whatever is unchanged. The camera's field of view, which the
// panel never changes, is the document's too.

const DEFAULTS_FROM_API = {
  // control id: [component of components.schemas, property]
  view: ["RenderRequest", "output"],
  time: ["RenderRequest", "time"],
  projection: ["Light", "projection"],
  color: ["Light", "color"],
  orbit: ["Light", "orbit_deg_per_s"],
  ambient: ["Light", "ambient"],
  size: ["Light", "size"],
  sun_north: ["Sun", "north_deg"],
  // The Sun hours mode's; the page's own values stand where the document
  // does not describe /api/sun-hours.
  sh_north: ["SunHoursSite", "north_deg"],
  sh_step: ["SunHoursPeriod", "step_minutes"],
  enabled: ["Shadow", "enabled"],
  filter: ["Shadow", "filter"],
  pcf_radius: ["Shadow", "pcf_radius"],
  map_size: ["Shadow", "map_size"],
  fit: ["Shadow", "fit"],
  cascades: ["Shadow", "cascades"],
  near: ["Shadow", "near"],
  far: ["Shadow", "far"],
  half: ["Shadow", "ortho_half_size"],
};
let apiSchemas = null;  // components.schemas of GET /api/openapi.json

// A field's default in the document; undefined if it has none (or the
// document could not be read).
function apiDefault(component, property) {
  const schema = apiSchemas && apiSchemas[component];
  const field = schema && schema.properties && schema.properties[property];
  return field ? field.default : undefined;
}

// "#rrggbb" for a linear [r, g, b] in 0..1, as the API reads it back.
function hexColor(rgb) {
  return `#${rgb.map((c) => Math.round(c * 255).toString(16).padStart(2, "0")).join("")}`;
}

function setDefault(e, value) {
  if (e.type === "checkbox") {
    e.defaultChecked = e.checked = value === true;
  } else if (e.tagName === "SELECT") {
    for (const option of e.options) option.defaultSelected = option.selected = option.value === String(value);
  } else {
    e.defaultValue = e.value = e.type === "color" && Array.isArray(value) ? hexColor(value) : String(value);
  }
}

function applyApiDefaults(apiDocument) {
  apiSchemas = apiDocument && apiDocument.components && apiDocument.components.schemas;
  if (!apiSchemas) {
    showError("The server's API document (GET /api/openapi.json) could not be read: the controls have no defaults.");
    return;
  }
  for (const [id, [component, property]] of Object.entries(DEFAULTS_FROM_API)) {
    const value = apiDefault(component, property);
    if (value !== undefined) setDefault($(id), value);
  }
  describeObjectTypes();
  const target = apiDefault("Light", "target");
  if (Array.isArray(target)) LIGHT_TARGET_FIELDS.forEach((id, i) => setDefault($(id), target[i]));
  const [width, height] = [apiDefault("RenderRequest", "width"), apiDefault("RenderRequest", "height")];
  setDefault($("resolution"), `${width}x${height}`);
}

// The editor's list of object types and their fields, from the document's
// SceneObject (each type's component), so that a type the server gains
// (cylinder, say) is listed without a change here.
function describeObjectTypes() {
  const mapping = apiSchemas.SceneObject && apiSchemas.SceneObject.discriminator && apiSchemas.SceneObject.discriminator.mapping;
  if (!mapping) return;
  const types = Object.entries(mapping).map(([type, ref]) => {
    const schema = apiSchemas[ref.split("/").pop()];
    const fields = schema && schema.properties ? Object.keys(schema.properties).filter((f) => f !== "type") : [];
    return `${type} (${fields.join(", ")})`;
  });
  $("object-types").textContent = `Object types: ${types.join("; ")}. See the API's SceneObject for each field's range and default.`;
}

// Without the lists (an older or unreachable server) the page's own two
// scenes stay, and the first frame reports what is wrong.
async function loadChoices() {
  const [scenes, held, apiDocument] = await Promise.all([
    getJson("/api/scenes"), getJson("/api/models"), getJson("/api/openapi.json"),
  ]);
  applyApiDefaults(apiDocument);
  if (scenes && Array.isArray(scenes.scenes) && scenes.scenes.length) fillScenes(scenes.scenes);
  if (held && Array.isArray(held.models)) for (const model of held.models) addModel(model);
}

// Replaces the scene options (not the models); the first is the default.
function fillScenes(scenes) {
  const select = $("scene");
  for (const option of Array.from(select.options)) if (!option.value.startsWith(MODEL_PREFIX)) option.remove();
  scenes.forEach((scene, i) => {
    if (scene.camera) sceneCameras.set(scene.name, { position: scene.camera.position, target: scene.camera.target });
    if (Array.isArray(scene.objects)) sceneObjects.set(scene.name, scene.objects);
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
        { type: "mesh", model: model.key, position: position.map(round), scale: round(scale), ...chosenAnimation(model) },
      ],
    },
    camera: { position: target.map((t, i) => round(t + CAMERA_DIRECTION[i] * distance)), target: target.map(round) },
  };
}

// --- Animated models ---------------------------------------------------------------
// A glTF model's animations (GET /api/models lists them) are offered in the
// Animation list; the one chosen plays at the request's time, so Time and
// Play move the model as they move the light (the server poses it).

// { animation: index } for the mesh object, or nothing (the rest pose).
function chosenAnimation(model) {
  const value = $("animation").value;
  const listed = Array.isArray(model.animations) ? model.animations : [];
  return value !== "" && listed.some((a) => String(a.index) === value) ? { animation: Number(value) } : {};
}

// The Animation list follows the chosen model: its animations, the choice
// kept where the model has it; hidden for a model without any.
function syncAnimations() {
  const model = chosenModel();
  const listed = model && Array.isArray(model.animations) ? model.animations : [];
  const select = $("animation");
  const kept = select.value;
  for (const option of Array.from(select.options)) if (option.value !== "") option.remove();
  for (const a of listed)
    select.add(new Option(`${a.name || `animation ${a.index}`} (${round(a.duration_s)} s)`, String(a.index)));
  select.value = listed.some((a) => String(a.index) === kept) ? kept : "";
  $("animation-row").hidden = listed.length === 0;
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

// Formats the server converts to glTF (docs/api.md, "Other formats"): named
// by ?format=, the file's extension.
const CONVERTED_FORMATS = ["obj", "stl", "ply", "dae", "fbx", "3ds", "ifc"];

function extensionOf(fileName) {
  const dot = fileName.lastIndexOf(".");
  return dot < 0 ? "" : fileName.slice(dot + 1).toLowerCase();
}

// CityJSON: "tile.city.json", or any ".json" a person picks as a model.
function isCityJson(fileName) {
  return /\.json$/i.test(fileName);
}

function contentTypeFor(fileName) {
  if (isCityJson(fileName)) return "application/city+json";
  if (CONVERTED_FORMATS.includes(extensionOf(fileName))) return "application/octet-stream";
  return /\.gltf$/i.test(fileName) ? "model/gltf+json" : "model/gltf-binary";
}

function uploadPathFor(fileName) {
  const ext = extensionOf(fileName);
  return CONVERTED_FORMATS.includes(ext) ? `/api/models?format=${ext}` : "/api/models";
}

// POST /api/models through XMLHttpRequest: fetch cannot report how much
// of a large body has been sent.
function sendModel(file, onProgress) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", uploadPathFor(file.name));
    for (const [name, value] of Object.entries(withToken({ "Content-Type": contentTypeFor(file.name) })))
      xhr.setRequestHeader(name, value);
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
    let answer;
    for (;;) {
      const token = savedToken();
      answer = await sendModel(file, (sent) => {
        status.textContent = sent < 1 ? `Uploading ${file.name}: ${Math.floor(100 * sent)} %` : `Loading ${file.name} on the server…`;
      });
      if (answer.status !== 401) break;
      status.textContent = `${file.name} needs an access token: enter it above.`;
      await tokenAfter401(token);
    }
    const model = answer.json;
    if ((answer.status !== 200 && answer.status !== 201) || !model || !model.id) {
      const detail = model && model.error ? model.error : `${answer.status} ${answer.statusText}`;
      throw new Error(`${file.name} was not loaded (${answer.status}): ${detail}`);
    }
    rememberFileName(model.id, file.name);
    if (state.custom) leaveCustomScene();  // the upload is chosen, as if picked in the list
    $("scene").value = addModel(model, file.name);
    state.camera = null;
    showCamera();
    syncAnimations();
    sunHoursSceneChanged();
    const animations = Array.isArray(model.animations) ? model.animations.length : 0;
    status.textContent = `${file.name}: ${model.triangles.toLocaleString("en")} triangles, ` +
      (model.closed ? "closed" : "open (drawn two-sided in the shadow pass)") +
      (animations ? `, ${animations} animation${animations > 1 ? "s" : ""} (choose one under Animation)` : "") +
      (answer.status === 200 ? ", already held." : ".");
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

// --- Your own scene ---------------------------------------------------------------
// The editor holds a JSON request fragment ({"scene": {"objects": [...]},
// "camera": {...}, "light": {...}}, or any other request field). "Render
// this" sends the form's request with the fragment's fields over it: an
// object field (light, shadow, camera) is merged key by key, anything else
// replaced. Its camera is then the scene's own: dragging moves from it,
// "Reset camera" goes back to it. Choosing another scene leaves it.
// The address keeps it as scene_json (minified) while that stays under
// SCENE_JSON_URL_LIMIT characters encoded; a longer one is not kept there.

const SCENE_JSON_URL_LIMIT = 2000;

const isPlainObject = (v) => v !== null && typeof v === "object" && !Array.isArray(v);

function withFragment(body, fragment) {
  const merged = { ...body };
  for (const [key, value] of Object.entries(fragment)) {
    merged[key] = isPlainObject(value) && isPlainObject(body[key]) ? { ...body[key], ...value } : value;
  }
  // A dragged camera moves from the fragment's, keeping its other keys (fov_y_deg).
  if (state.camera) merged.camera = { ...(isPlainObject(fragment.camera) ? fragment.camera : {}), ...state.camera };
  return merged;
}

// The fragment's camera, where it has a position and a target to orbit about.
function customCamera() {
  const camera = state.custom && state.custom.camera;
  const triple = (v) => Array.isArray(v) && v.length === 3 && v.every(Number.isFinite);
  if (!isPlainObject(camera) || !triple(camera.position) || !triple(camera.target)) return null;
  return { position: camera.position, target: camera.target };
}

// The chosen scene (or model view) as a fragment: its objects, the camera
// in use and the light as the form sends it, so that rendering it at once
// gives the frame shown.
function loadSceneIntoEditor() {
  const model = chosenModel();
  let scene;
  if (model) scene = modelView(model).scene;
  else if (sceneObjects.has($("scene").value)) scene = { objects: sceneObjects.get($("scene").value) };
  else scene = $("scene").value;  // the server did not list it: its name
  const fragment = { scene };
  const camera = currentCamera();
  if (camera) fragment.camera = { position: camera.position, target: camera.target };
  // A sun stays the form's (Placed by, place, date and time): a sun in the
  // editor would override every later change of those fields.
  if (!sunMode()) {
    const light = { position: lightAtZero().map(round) };
    const target = lightTarget();
    if (target.some((x) => x !== 0)) light.target = target;
    fragment.light = light;
  }
  $("scene-json").value = formatFragment(fragment);
  markSceneJson("");
  $("scene-json-status").textContent = `Loaded ${$("scene").selectedOptions[0].textContent}: edit it, then Render this.`;
}

// Two-space JSON with each number list on one line: an object per line is
// easier to edit than one number per line.
function formatFragment(fragment) {
  return JSON.stringify(fragment, null, 2).replace(/\[\s+([^\[\]{}]*?)\s+\]/g, (_, inner) => `[${inner.replace(/,\s+/g, ", ")}]`);
}

// The editor's text as a fragment, or null (the textarea marked) where it is not one.
function parseSceneJson() {
  let fragment;
  try {
    fragment = JSON.parse($("scene-json").value);
  } catch (e) {
    markSceneJson(`not valid JSON: ${e.message}`);
    return null;
  }
  if (!isPlainObject(fragment)) {
    markSceneJson("must be a JSON object, e.g. {\"scene\": {\"objects\": [...]}}");
    return null;
  }
  markSceneJson("");
  return fragment;
}

function markSceneJson(problem) {
  markField($("scene-json"), problem, "Scene JSON");
}

function renderSceneJson() {
  const fragment = parseSceneJson();
  if (!fragment) {
    $("scene-json-status").textContent = "";
    return;
  }
  state.custom = fragment;
  state.camera = null;
  showCamera();
  $("scene-json-status").textContent = sunHoursMode()
    ? "The editor's scene is the one analysed (Run); choosing another scene goes back to the form's."
    : "Rendering the editor's scene; choosing another scene goes back to the form's.";
  sunHoursSceneChanged();
  requestFrame();
}

// While marked, the mark follows the text (cleared once it parses).
function sceneJsonTyped() {
  if ($("scene-json").getAttribute("aria-invalid") === "true") parseSceneJson();
}

function leaveCustomScene() {
  state.custom = null;
  $("scene-json-status").textContent = "The form's scene is rendered again; the editor keeps its text.";
}

function sceneJsonToUrl(params) {
  if (!state.custom) return;
  const json = JSON.stringify(state.custom);
  if (encodeURIComponent(json).length <= SCENE_JSON_URL_LIMIT) params.set("scene_json", json);
  else $("scene-json-status").textContent = `The editor's scene is rendered, but it is too long for the address ` +
    `(over ${SCENE_JSON_URL_LIMIT} characters encoded): a link to this view does not keep it.`;
}

function sceneJsonFromUrl(params, skipped) {
  if (!params.has("scene_json")) return;
  let fragment = null;
  try {
    fragment = JSON.parse(params.get("scene_json"));
  } catch (_) { /* reported below */ }
  if (!isPlainObject(fragment)) {
    skipped.push("scene_json");
    return;
  }
  state.custom = fragment;
  $("scene-json").value = formatFragment(fragment);
  $("scene-json-status").textContent = "Rendering the editor's scene (from the address).";
}

// --- Sun hours ---------------------------------------------------------------------
// The Sun hours mode asks POST /api/sun-hours how many hours of direct sun
// each point of a horizontal grid gets over a period, for the scene the
// panel renders (a built-in scene's name, a model on its floor, or the
// editor's objects). The fields are sent by Run only. An analysis within the
// server's per-request budget is answered at once; a longer one is a job
// (202): its progress is read once a second from GET Location until the
// result, and Cancel deletes it. The hours are drawn one cell per point,
// north (-Z) up, on a colour ramp from dark blue (0 h) to yellow (the
// most), the points under the threshold hatched and outlined, with the
// legend beside it.

const SH_CENTRE = ["sh_cx", "sh_cy", "sh_cz"];
const SH_SITE = ["sh_lat", "sh_lon", "sh_north"];
const SH_MAP_SIZE = 480;  // the map's longer side, px, for grids up to that many points a side
const SH_POLL_MS = 1000;
const SH_READOUT_HINT = "Point at the map (or focus it and use the arrow keys) to read a point's hours.";
const SH_RAMP = [  // dark blue -> blue -> teal -> green -> yellow
  [0, [10, 20, 70]], [0.2, [27, 63, 155]], [0.4, [31, 127, 194]], [0.6, [43, 181, 154]], [0.8, [165, 214, 63]],
  [1, [253, 231, 37]],
];
// The fields a refusal names, as the panel's fields.
const SH_SERVER_FIELDS = {
  "site.latitude": "sh_lat", "site.longitude": "sh_lon", "site.north_deg": "sh_north",
  "period.start": "sh_date", "period.end": "sh_days", "period.step_minutes": "sh_step",
  "grid.center[0]": "sh_cx", "grid.center[1]": "sh_cy", "grid.center[2]": "sh_cz", "grid.center": "sh_cx",
  "grid.size": "sh_sx", "grid.size[0]": "sh_sx", "grid.size[1]": "sh_sz", "grid.spacing": "sh_spacing",
  "require_hours": "sh_require",
};
const sunHours = {
  active: null,  // the run in progress: { cancelled, controller, location }
  shown: null,   // the result shown: { answer (the JSON), body (as sent), location (a job's, or null), seconds }
};

class SunHoursCancelled extends Error {}

function sunHoursMode() {
  return $("mode").value === "sun-hours";
}

function isSunHoursField(e) {
  return !!e.closest && !!e.closest("#sun-hours-settings");
}

// The page's defaults that are not the document's: the first day is this
// year's 21 March (BR 209's day), the place the sun's; the place list is
// the sun's.
function setUpSunHours() {
  for (const option of $("sun_city").options) if (option.value) $("sh_city").append(option.cloneNode(true));
  setDefault($("sh_date"), `${String(new Date().getFullYear()).padStart(4, "0")}-03-21`);
  SH_SITE.forEach((id, i) => {
    const value = $(["sun_lat", "sun_lon", "sun_north"][i]).defaultValue;
    if (value !== "") setDefault($(id), value);
  });
  followSceneCentre("reset");
}

// After the address is read: the grid centre follows the scene the address
// chose, but for a centre the address gives.
function sunHoursAfterUrl() {
  const params = new URLSearchParams(location.search);
  followSceneCentre(SH_CENTRE.filter((id) => params.has(id)));
  syncSunHoursCity();
  syncMode();
  showGridPoints();
}

// The mode chosen: its controls and outputs shown, the other's hidden.
function syncMode() {
  document.body.classList.toggle("sun-hours-mode", sunHoursMode());
}

function modeChanged() {
  syncMode();
  // "Copy as curl" copies the mode's request: a command shown for the other is gone.
  $("curl").hidden = true;
  $("copy-status").textContent = "";
  // So does the other mode's error (a frame's is found again by rendering once back).
  if (sunHoursMode() && state.errorSource === "render") state.frameOwed = true;
  clearError(sunHoursMode() ? "render" : "sun-hours");
  if (sunHoursMode()) {
    if (state.playing) togglePlay();
    // A place the sun's fields hold is taken up, unless the fields here were changed.
    if (SH_SITE.every((id) => $(id).value === $(id).defaultValue)) {
      SH_SITE.forEach((id, i) => {
        const source = $(["sun_lat", "sun_lon", "sun_north"][i]);
        if (!fieldProblem(source) && source.value !== "") $(id).value = source.value;
      });
      syncSunHoursCity();
    }
    saveToUrl();
  } else if (state.frameOwed || !$("frame").src) {
    requestFrame();
  } else {
    saveToUrl();
  }
}

function sunHoursFieldChanged(input) {
  // A mark (the browser's or the server's) goes once the field holds a number again.
  if (input.getAttribute("aria-invalid") === "true") markField(input, fieldProblem(input));
  if (input.id === "sh_lat" || input.id === "sh_lon") syncSunHoursCity();
  if (input.id === "sh_city") return;
  showGridPoints();
  sunHoursSettingsChanged();
  saveToUrl();
}

function syncSunHoursCity() {
  const here = `${number("sh_lat")},${number("sh_lon")}`;
  const match = Array.from($("sh_city").options).find((o) => o.value === here);
  $("sh_city").value = match ? match.value : "";
}

function chooseSunHoursCity() {
  if (!$("sh_city").value) return;
  const [latitude, longitude] = $("sh_city").value.split(",");
  $("sh_lat").value = latitude;
  $("sh_lon").value = longitude;
  for (const id of ["sh_lat", "sh_lon"]) markField($(id), "");
  sunHoursSettingsChanged();
  saveToUrl();
}

// The scene the analysis is asked about: the editor's while it is rendered,
// else the form's (a built-in scene's name, or a model on its floor).
function sunHoursScene() {
  if (state.custom && "scene" in state.custom) return state.custom.scene;
  const model = chosenModel();
  return model ? modelView(model).scene : $("scene").value;
}

// The floor: the lowest plane's height (0 without one).
function floorHeight(scene) {
  const objects = typeof scene === "string" ? sceneObjects.get(scene) : isPlainObject(scene) && scene.objects;
  const heights = (Array.isArray(objects) ? objects : [])
    .filter((o) => isPlainObject(o) && o.type === "plane")
    .map((o) => (Array.isArray(o.center) && Number.isFinite(o.center[1]) ? o.center[1] : 0));
  return heights.length ? Math.min(...heights) : 0;
}

// The scene's target (its own camera's) at the floor's height + 0.01: the
// points lie just above the floor, not in it.
function sceneGridCentre() {
  const camera = defaultCamera();
  const target = camera ? camera.target : [0, 0, 0];
  return [target[0], floorHeight(sunHoursScene()) + 0.01, target[2]].map(round);
}

function setDefaultKeepingValue(e, value) {
  const kept = e.value;
  e.defaultValue = value;
  e.value = kept;
}

// The grid centre's default is the scene's. "reset" puts the fields there;
// a list keeps the values of the fields it names and resets the others;
// nothing: the fields follow the scene unless they were changed.
function followSceneCentre(keep) {
  const centre = sceneGridCentre();
  const untouched = SH_CENTRE.every((id) => $(id).value === $(id).defaultValue);
  SH_CENTRE.forEach((id, i) => {
    const value = String(centre[i]);
    const kept = Array.isArray(keep) ? keep.includes(id) : keep !== "reset" && !untouched;
    if (kept) setDefaultKeepingValue($(id), value);
    else {
      setDefault($(id), value);
      markField($(id), "");
    }
  });
}

// "Centre on the scene's target".
function centreGridOnScene() {
  followSceneCentre("reset");
  sunHoursSettingsChanged();
  saveToUrl();
}

function sunHoursSceneChanged() {
  followSceneCentre();
  sunHoursSettingsChanged();
}

// "80 × 80 = 6,400 points" under the grid's fields.
function showGridPoints() {
  const spacing = number("sh_spacing");
  const [columns, rows] = [number("sh_sx") / spacing, number("sh_sz") / spacing];
  const whole = (n) => Number.isFinite(n) && n >= 1 && Math.abs(n - Math.round(n)) <= 1e-9 * Math.max(1, n);
  $("sh-points").textContent = !(spacing > 0) ? "" : whole(columns) && whole(rows)
    ? `${Math.round(columns).toLocaleString("en")} × ${Math.round(rows).toLocaleString("en")} = ` +
      `${(Math.round(columns) * Math.round(rows)).toLocaleString("en")} points, one every ${spacing} (cell centres).`
    : "The size must be a whole number of cells of the spacing (the server refuses it otherwise).";
}

// A result shown for other settings says so.
function sunHoursSettingsChanged() {
  if (!sunHours.shown || sunHours.active) return;
  const body = sunHoursBody(false);
  const same = body && JSON.stringify(body) === JSON.stringify(sunHours.shown.body);
  $("sh-status").textContent = same ? doneText(sunHours.shown) : "The settings have changed since this map was computed: Run to update it.";
}

// RFC 3339 without milliseconds.
function utcText(ms) {
  return new Date(ms).toISOString().replace(/\.\d{3}Z$/, "Z");
}

// Days from the place's mean solar midnight, to the whole minute.
function sunHoursPeriod() {
  const [year, month, day] = $("sh_date").value.split("-").map(Number);
  const midnight = new Date(0);
  midnight.setUTCFullYear(year, month - 1, day);
  const start = midnight.getTime() + Math.round((-number("sh_lon") / 15) * 60) * 60000;
  const end = start + Math.round(number("sh_days")) * 86400000;
  return { start: utcText(start), end: utcText(end), step_minutes: number("sh_step") };
}

// The request body, or null where a field cannot be sent (marked, when
// `mark`; what is wrong said in the status line).
function sunHoursBody(mark = true) {
  const bad = [];
  for (const input of $("sun-hours-settings").querySelectorAll("input")) {
    const problem = fieldProblem(input);
    if (mark) markField(input, problem);
    if (problem) bad.push(fieldName(input));
  }
  if (bad.length) {
    if (mark) $("sh-status").textContent = `Not run: ${bad.join(", ")} cannot be sent as it is (marked on the left).`;
    return null;
  }
  const site = { latitude: number("sh_lat"), longitude: number("sh_lon") };
  if (number("sh_north") !== 0) site.north_deg = number("sh_north");
  return {
    scene: sunHoursScene(),
    site,
    period: sunHoursPeriod(),
    grid: { center: SH_CENTRE.map(number), size: [number("sh_sx"), number("sh_sz")], spacing: number("sh_spacing") },
    require_hours: number("sh_require"),
  };
}

// Resolves after `ms`, or at once when `signal` aborts.
function sleep(ms, signal) {
  return new Promise((resolve) => {
    const done = () => {
      clearTimeout(timer);
      signal.removeEventListener("abort", done);
      resolve();
    };
    const timer = setTimeout(done, ms);
    signal.addEventListener("abort", done);
  });
}

// A refusal as an Error naming its field ({"error", "field"} JSON).
async function sunHoursRefusal(response) {
  let detail = `${response.status} ${response.statusText}`, field = "", message = detail;
  try {
    const json = await response.json();
    field = json.field || "";
    message = json.error || message;
    detail = field ? `${field}: ${message}` : message;
  } catch (_) { /* not JSON */ }
  return Object.assign(new Error(`Sun hours not computed (${response.status}): ${detail}`), { field, reason: message });
}

// Asks for the analysis in `accept`'s format; a job (202) is followed once a
// second, its progress shown, until its answer. Resolves to the 200
// response; throws the refusal, or SunHoursCancelled.
async function askSunHours(run, body, accept) {
  const { signal } = run.controller;
  const send = async (path, init) => {
    try {
      return await apiFetch(path, { ...init, signal });
    } catch (e) {
      if (run.cancelled) throw new SunHoursCancelled();
      throw new Error(`The server is unreachable (${e.message}). Is umbra-server running?`);
    }
  };
  // An answer at once leaves no time for a bar; a longer wait shows one.
  const waiting = setTimeout(() => showProgress({ waiting: true }), 300);
  let response;
  try {
    response = await send("/api/sun-hours", {
      method: "POST", headers: { "Content-Type": "application/json", Accept: accept }, body: JSON.stringify(body),
    });
  } finally {
    clearTimeout(waiting);
  }
  while (response.status === 202) {
    const progress = await response.json().catch(() => ({}));
    if (!run.location) run.location = progress.location || response.headers.get("Location");
    if (!run.location) throw new Error("Sun hours not computed: the server answered 202 without the job's location.");
    $("sh-progress").dataset.location = run.location;
    if (progress.estimated_ms !== undefined && progress.state === "queued" && !progress.elapsed_s)
      $("sh-status").textContent = "Over the server's per-request budget, so it runs as a job: its progress is read once a second.";
    showProgress(progress);
    await sleep(SH_POLL_MS, signal);
    if (run.cancelled) throw new SunHoursCancelled();
    response = await send(run.location, { headers: { Accept: accept } });
  }
  if (run.cancelled) throw new SunHoursCancelled();
  if (!response.ok) throw await sunHoursRefusal(response);
  return response;
}

// "40 ms", "4.2 s", "37 s", "2 min 5 s", "1 h 12 min".
function duration(seconds) {
  if (!Number.isFinite(seconds)) return "?";
  if (seconds < 0.9995) return `${Math.round(seconds * 1000)} ms`;
  if (seconds < 9.95) return `${seconds.toFixed(1)} s`;
  const whole = Math.round(seconds);
  if (whole < 60) return `${whole} s`;
  const minutes = Math.floor(whole / 60);
  return minutes < 60 ? `${minutes} min ${whole % 60} s` : `${Math.floor(minutes / 60)} h ${minutes % 60} min`;
}

function bigNumber(n) {
  if (!Number.isFinite(n)) return "?";
  if (n >= 1e9) return `${(n / 1e9).toPrecision(3)} G`;
  if (n >= 1e6) return `${(n / 1e6).toPrecision(3)} M`;
  if (n >= 1e3) return `${(n / 1e3).toPrecision(3)} k`;
  return String(Math.round(n));
}

// The bar and its line: a job's state, share done and time left; or, while
// an answer is awaited, an indeterminate bar.
function showProgress(p) {
  const bar = $("sh-progress-bar");
  $("sh-progress").hidden = false;
  let text;
  if (p.waiting) {
    bar.removeAttribute("value");
    text = "Computing…";
  } else if (p.state === "running" && Number.isFinite(p.fraction_done)) {
    bar.value = p.fraction_done;
    text = `Job running: ${Math.floor(100 * p.fraction_done)} % done` +
      (Number.isFinite(p.seconds_left) ? ` · about ${duration(p.seconds_left)} left` : "") +
      (Number.isFinite(p.pairs_per_second) ? ` · ${bigNumber(p.pairs_per_second)} point-samples/s` : "");
  } else {
    bar.value = Number.isFinite(p.fraction_done) ? p.fraction_done : 0;
    text = `Job ${p.job || ""} queued` + (Number.isFinite(p.estimated_ms) ? ` (estimated ${duration(p.estimated_ms / 1000)})` : "") +
      (Number.isFinite(p.elapsed_s) && p.elapsed_s > 0 ? `: waiting for the server's jobs before it` : "");
  }
  $("sh-progress").dataset.state = p.waiting ? "waiting" : p.state || "queued";
  $("sh-progress-text").textContent = text;
}

function sunHoursBusy(run) {
  sunHours.active = run;
  $("sh-run").disabled = !!run;
  $("sh-csv").disabled = !!run;
  if (!run) {
    $("sh-progress").hidden = true;
    delete $("sh-progress").dataset.location;
  }
}

function markSunHoursRefusal(error) {
  const id = SH_SERVER_FIELDS[error.field];
  if (id) {
    markField($(id), "x");  // the mark and its message, which says what the server said
    $(`${id}-problem`).textContent = `${fieldName($(id))}: ${error.reason} (the server's answer).`;
  } else if ((error.field || "").startsWith("scene") && state.custom) {
    $("scene-json-status").textContent = `The editor's scene was not analysed: ${error.message}`;
  }
}

async function runSunHours() {
  if (sunHours.active) return;
  const body = sunHoursBody();
  if (!body) return;
  const firstDay = $("sh_date").value;
  const run = { cancelled: false, controller: new AbortController(), location: null };
  sunHoursBusy(run);
  clearError("sun-hours");
  $("sh-status").textContent = "Asking the server…";
  const started = performance.now();
  try {
    const response = await askSunHours(run, body, "application/json");
    const answer = await response.json();
    sunHours.shown = { answer, body, location: run.location, seconds: (performance.now() - started) / 1000, firstDay };
    showSunHours(sunHours.shown);
    $("sh-status").textContent = doneText(sunHours.shown);
  } catch (e) {
    if (e instanceof SunHoursCancelled) {
      // Said only once the server has answered the DELETE: until then the
      // job may still be held there.
      const deleted = run.deleting ? await run.deleting : null;
      $("sh-status").textContent = deleted === null ? "Cancelled."
        : deleted ? "Cancelled: the job was deleted on the server."
        : "Cancelled here, but the server did not confirm the job's deletion: it ends on its own once its result expires.";
    } else {
      showError(e.message, "sun-hours");
      markSunHoursRefusal(e);
      $("sh-status").textContent = "Not computed: see the message below.";
    }
  } finally {
    sunHoursBusy(null);
  }
}

async function cancelSunHours() {
  const run = sunHours.active;
  if (!run || run.cancelled) return;
  run.cancelled = true;
  run.controller.abort();  // an answer awaited at once: the server stops once the connection closes
  if (run.location) {
    // 404: already gone (expired, or its server restarted): nothing runs.
    run.deleting = apiFetch(run.location, { method: "DELETE" }).then((r) => r.ok || r.status === 404, () => false);
    await run.deleting;
  }
}

function doneText(shown) {
  const { columns, rows } = shown.answer.grid;
  return `Done in ${duration(shown.seconds)}: ${(columns * rows).toLocaleString("en")} points × ` +
    `${shown.answer.samples_count.toLocaleString("en")} samples` +
    (shown.location ? ", as a job (over the server's per-request budget)." : ".");
}

// --- The map and its legend

function rampColour(t) {
  const x = clamp(Number.isFinite(t) ? t : 0, 0, 1);
  let i = 1;
  while (i < SH_RAMP.length - 1 && SH_RAMP[i][0] < x) i += 1;
  const [t0, c0] = SH_RAMP[i - 1], [t1, c1] = SH_RAMP[i];
  const f = (x - t0) / (t1 - t0);
  return c0.map((c, k) => Math.round(c + (c1[k] - c) * f));
}

// "12.17" (hours to the hundredth, no trailing zeros).
function hoursText(h) {
  return String(Number(h.toFixed(2)));
}

function hoursAndMinutes(h) {
  const minutes = Math.round(h * 60);
  return `${Math.floor(minutes / 60)} h ${String(minutes % 60).padStart(2, "0")} min`;
}

function percent(share) {
  const p = 100 * share;
  if (p > 0 && p < 0.05) return "< 0.1 %";
  if (p < 100 && p >= 99.95) return "> 99.9 %";
  return `${Number(p.toFixed(1))} %`;
}

// As the server's pass_share: compared in minutes.
function reaches(hours, require) {
  const need = require * 60;
  return hours * 60 >= need - 1e-9 * Math.max(1, need);
}

function maxOf(values) {
  let max = 0;
  for (const v of values) if (v > max) max = v;
  return max;
}

function showSunHours(shown) {
  const { answer } = shown;
  shown.max = maxOf(answer.hours);
  $("sh-result").hidden = false;
  drawSunHoursMap(shown);
  drawSunHoursScale(shown);
  writeSunHoursLegend(shown);
  $("sh-readout").textContent = SH_READOUT_HINT;
  sunHours.point = null;
  $("sh-download-status").textContent = "";
}

function drawSunHoursMap(shown) {
  const { answer, max } = shown;
  const { columns, rows } = answer.grid;
  const require = answer.require_hours;
  // Whole pixels a cell where the grid fits, else less than one (no larger than the map).
  const side = Math.max(columns, rows);
  const cell = side <= SH_MAP_SIZE ? Math.floor(SH_MAP_SIZE / side) : SH_MAP_SIZE / side;
  const [width, height] = [Math.max(1, Math.round(columns * cell)), Math.max(1, Math.round(rows * cell))];
  // One pixel per point, then scaled up without smoothing: row 0 (-Z) on top.
  const points = Object.assign(document.createElement("canvas"), { width: columns, height: rows });
  const pixels = points.getContext("2d").createImageData(columns, rows);
  const short = Object.assign(document.createElement("canvas"), { width: columns, height: rows });
  const shortPixels = short.getContext("2d").createImageData(columns, rows);
  let anyShort = false;
  answer.hours.forEach((h, i) => {
    const [r, g, b] = rampColour(max > 0 ? h / max : 0);
    pixels.data.set([r, g, b, 255], 4 * i);
    if (require !== undefined && !reaches(h, require)) {
      shortPixels.data[4 * i + 3] = 255;
      anyShort = true;
    }
  });
  points.getContext("2d").putImageData(pixels, 0, 0);
  const canvas = $("sh-map");
  canvas.width = width;
  canvas.height = height;
  canvas.closest("figure").style.width = `${width}px`;  // the caption wraps under the map
  const context = canvas.getContext("2d");
  context.imageSmoothingEnabled = false;
  context.drawImage(points, 0, 0, width, height);
  if (anyShort) {
    short.getContext("2d").putImageData(shortPixels, 0, 0);
    const hatch = Object.assign(document.createElement("canvas"), { width, height });
    const h = hatch.getContext("2d");
    h.imageSmoothingEnabled = false;
    h.drawImage(short, 0, 0, width, height);
    h.globalCompositeOperation = "source-in";
    h.fillStyle = hatchPattern(h);
    h.fillRect(0, 0, width, height);
    context.drawImage(hatch, 0, 0);
    outlineShort(context, answer, cell);
  }
  const north = (answer.site && answer.site.north_deg) || 0;
  $("sh-orientation").textContent = north ? `−Z up, +X right; north is ${north}° clockwise from up (the arrow)`
                                          : "north (−Z) up, east (+X) right";
  $("sh-cursor").hidden = true;
  canvas.setAttribute("aria-label", `Hours of direct sun at ${columns} × ${rows} grid points, −Z up: ` +
    `0 h dark blue to ${hoursText(max)} h yellow` + (require !== undefined ? `; under ${hoursText(require)} h hatched` : ""));
}

// Diagonal lines, dark-edged so that they show on any colour of the ramp.
function hatchPattern(context) {
  const tile = Object.assign(document.createElement("canvas"), { width: 8, height: 8 });
  const t = tile.getContext("2d");
  for (const [style, width] of [["rgba(0, 0, 0, 0.55)", 3], ["rgba(255, 255, 255, 0.9)", 1]]) {
    t.strokeStyle = style;
    t.lineWidth = width;
    t.beginPath();
    for (const offset of [-8, 0, 8]) {
      t.moveTo(offset, 8);
      t.lineTo(offset + 8, 0);
    }
    t.stroke();
  }
  return context.createPattern(tile, "repeat");
}

// The edges between points under the threshold and the others (or the
// grid's edge).
function outlineShort(context, answer, cell) {
  const { columns, rows } = answer.grid;
  const require = answer.require_hours;
  const isShort = (c, r) => c >= 0 && r >= 0 && c < columns && r < rows && !reaches(answer.hours[r * columns + c], require);
  const path = new Path2D();
  for (let r = 0; r < rows; r += 1) {
    for (let c = 0; c < columns; c += 1) {
      if (!isShort(c, r)) continue;
      const [x, y] = [c * cell, r * cell];
      if (!isShort(c, r - 1)) { path.moveTo(x, y); path.lineTo(x + cell, y); }
      if (!isShort(c, r + 1)) { path.moveTo(x, y + cell); path.lineTo(x + cell, y + cell); }
      if (!isShort(c - 1, r)) { path.moveTo(x, y); path.lineTo(x, y + cell); }
      if (!isShort(c + 1, r)) { path.moveTo(x + cell, y); path.lineTo(x + cell, y + cell); }
    }
  }
  for (const [style, width] of [["#000000", 3], ["#ffffff", 1.25]]) {
    context.strokeStyle = style;
    context.lineWidth = width;
    context.stroke(path);
  }
}

// Tick values: 0 and a round step, at most six.
function hourTicks(max) {
  if (!(max > 0)) return [0];
  const steps = [0.25, 0.5, 1, 2, 3, 4, 6, 8, 12, 24, 48, 100, 200, 250, 500, 1000, 2000, 2500, 5000];
  const step = steps.find((s) => max / s <= 6) || Math.ceil(max / 6);
  const ticks = [];
  for (let t = 0; t <= max + 1e-9; t += step) ticks.push(t);
  return ticks;
}

// The colour scale (hours, yellow on top), the hatch's key and a north arrow.
function drawSunHoursScale(shown, canvas = $("sh-scale")) {
  const { answer, max } = shown;
  const context = canvas.getContext("2d");
  const [top, bottom, left, barWidth] = [30, 250, 10, 22];
  context.clearRect(0, 0, canvas.width, canvas.height);
  context.font = "12px system-ui, sans-serif";
  context.textBaseline = "middle";
  context.fillStyle = "#e6e6e6";
  context.fillText("hours of sun (h)", left, 12);
  const gradient = context.createLinearGradient(0, bottom, 0, top);
  for (const [t, c] of SH_RAMP) gradient.addColorStop(t, `rgb(${c.join(",")})`);
  context.fillStyle = gradient;
  context.fillRect(left, top, barWidth, bottom - top);
  context.strokeStyle = "#3a404b";
  context.strokeRect(left + 0.5, top + 0.5, barWidth - 1, bottom - top - 1);
  const y = (h) => (max > 0 ? bottom - ((bottom - top) * h) / max : bottom);
  const label = (h, text) => {
    context.fillStyle = "#c3c7cf";
    context.fillRect(left + barWidth, Math.round(y(h)), 5, 1);
    context.fillText(text, left + barWidth + 8, clamp(y(h), top, bottom));
  };
  label(max, `${hoursText(max)} h (most)`);
  for (const t of hourTicks(max)) if (y(t) - y(max) >= 14) label(t, `${hoursText(t)} h`);
  // The hatch's key.
  if (answer.require_hours !== undefined) {
    const key = { x: left, y: 266, w: barWidth, h: 16 };
    context.fillStyle = `rgb(${rampColour(0.15).join(",")})`;
    context.fillRect(key.x, key.y, key.w, key.h);
    context.fillStyle = hatchPattern(context);
    context.fillRect(key.x, key.y, key.w, key.h);
    context.strokeStyle = "#ffffff";
    context.strokeRect(key.x + 0.5, key.y + 0.5, key.w - 1, key.h - 1);
    context.fillStyle = "#c3c7cf";
    context.fillText(`< ${hoursText(answer.require_hours)} h`, left + barWidth + 8, key.y + key.h / 2);
  }
  // North: -Z (up) turned by north_deg clockwise.
  const north = ((answer.site && answer.site.north_deg) || 0) * Math.PI / 180;
  const [cx, cy, r] = [canvas.width - 24, 292, 14];
  context.save();
  context.translate(cx, cy);
  context.strokeStyle = "#a0a4ad";
  context.beginPath();
  context.arc(0, 0, r + 4, 0, 2 * Math.PI);
  context.stroke();
  context.rotate(north);
  context.fillStyle = "#e6e6e6";
  context.beginPath();
  context.moveTo(0, -r);
  context.lineTo(5, 4);
  context.lineTo(0, 1);
  context.lineTo(-5, 4);
  context.closePath();
  context.fill();
  context.fillText("N", -4, -r - 12);
  context.restore();
}

function degrees(value, positive, negative) {
  return `${Math.abs(value)}° ${value < 0 ? negative : positive}`;
}

function utcMinutes(text) {
  return text.replace("T", " ").replace(/:\d\d(\.\d+)?Z$/, " UTC");
}

// The legend's lines: [term, text, class]. Also the PNG's.
function sunHoursLegendLines(shown) {
  const { answer, body, max } = shown;
  const lines = [];
  lines.push(["Scale", `hours of direct sun at each point, 0 h (dark blue) to ${hoursText(max)} h (yellow)`]);
  const site = answer.site || body.site;
  lines.push(["Place", `${degrees(site.latitude, "N", "S")}, ${degrees(site.longitude, "E", "W")}` +
    (site.north_deg ? `; north ${site.north_deg}° clockwise from −Z` : "; north is −Z (up)")]);
  const period = answer.period || body.period;
  const days = Math.round((Date.parse(period.end) - Date.parse(period.start)) / 86400000);
  const first = shown.firstDay;
  const step = period.step_minutes;
  lines.push(["Period", `${first || utcMinutes(period.start)}, ${days} day${days === 1 ? "" : "s"} of mean solar time ` +
    `(${utcMinutes(period.start)} to ${utcMinutes(period.end)}), every ${step} min: ` +
    `${answer.samples_count.toLocaleString("en")} samples, ${answer.samples_up.toLocaleString("en")} with the sun up ` +
    `(${hoursText((answer.samples_up * step) / 60)} h)`]);
  if (answer.pass_share !== undefined) {
    const require = hoursText(answer.require_hours);
    const half = answer.pass_share >= 0.5;
    const br209 = answer.require_hours === 2 && days === 1 && /-03-21$/.test(shown.firstDay || "");
    const verdict = br209 ? (half ? "passes BR 209" : "fails BR 209 (it asks for at least half the area)")
                          : (half ? "at least half the area" : "under half the area");
    lines.push(["Threshold", `${percent(answer.pass_share)} of points get ≥ ${require} h: ${verdict}`, half ? "pass" : "fail"]);
  }
  const share = answer.pairs > 0 ? answer.pairs_ray_cast / answer.pairs : 0;
  lines.push(["Path", `${answer.path}: ${percent(share)} of the ${answer.pairs.toLocaleString("en")} point-samples ` +
    `with the sun up ray cast (${answer.pairs_ray_cast.toLocaleString("en")}), ` +
    `${answer.pairs_by_maps.toLocaleString("en")} proved lit by footprints` + (answer.exact ? "; exact" : "")]);
  const g = answer.grid;
  lines.push(["Grid", `${g.columns} × ${g.rows} points every ${g.spacing}, at y = ${round(g.origin[1])}, ` +
    `(x, z) from (${round(g.origin[0])}, ${round(g.origin[2])}) at the top left to ` +
    `(${round(g.origin[0] + (g.columns - 1) * g.spacing)}, ${round(g.origin[2] + (g.rows - 1) * g.spacing)}) at the bottom right`]);
  return lines;
}

function writeSunHoursLegend(shown) {
  const list = $("sh-legend");
  list.replaceChildren();
  for (const [term, text, kind] of sunHoursLegendLines(shown)) {
    const dd = Object.assign(document.createElement("dd"), { textContent: text });
    if (kind) dd.className = kind;
    dd.dataset.term = term.toLowerCase();
    list.append(Object.assign(document.createElement("dt"), { textContent: term }), dd);
  }
}

// The point under the pointer (or chosen with the arrow keys, the map
// focused): where it is, its hours and longest run, and a box around it.
function readSunHoursPoint(e) {
  const shown = sunHours.shown;
  if (!shown) return;
  const { columns, rows } = shown.answer.grid;
  const box = $("sh-map").getBoundingClientRect();
  const column = Math.floor(((e.clientX - box.left) / box.width) * columns);
  const row = Math.floor(((e.clientY - box.top) / box.height) * rows);
  if (column >= 0 && row >= 0 && column < columns && row < rows) showSunHoursPoint(column, row);
}

function sunHoursKey(e) {
  const shown = sunHours.shown;
  const moves = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] };
  if (!shown || !moves[e.key]) return;
  e.preventDefault();
  const { columns, rows } = shown.answer.grid;
  const at = sunHours.point || { column: Math.floor(columns / 2), row: Math.floor(rows / 2) };
  const step = e.shiftKey ? 10 : 1;
  showSunHoursPoint(clamp(at.column + moves[e.key][0] * step, 0, columns - 1), clamp(at.row + moves[e.key][1] * step, 0, rows - 1));
}

function showSunHoursPoint(column, row) {
  const { answer } = sunHours.shown;
  const { columns, rows, origin, spacing } = answer.grid;
  sunHours.point = { column, row };
  const i = row * columns + column;
  const hours = answer.hours[i], run = answer.longest_run_hours[i];
  const x = round(origin[0] + column * spacing), z = round(origin[2] + row * spacing);
  const verdict = answer.require_hours === undefined ? ""
    : reaches(hours, answer.require_hours) ? ` — reaches ${hoursText(answer.require_hours)} h`
    : ` — under ${hoursText(answer.require_hours)} h`;
  const readout = $("sh-readout");
  readout.textContent = `x ${x}, z ${z} (column ${column}, row ${row}): ${hoursText(hours)} h of sun ` +
    `(${hoursAndMinutes(hours)}), longest run ${hoursText(run)} h${verdict}`;
  readout.dataset.index = String(i);
  // The box: the cell as shown (the canvas may be scaled down), at least 5 px.
  const canvas = $("sh-map");
  const [w, h] = [canvas.clientWidth / columns, canvas.clientHeight / rows];
  const size = [Math.max(w, 5), Math.max(h, 5)];
  Object.assign($("sh-cursor").style, {
    left: `${canvas.offsetLeft + (column + 0.5) * w - size[0] / 2}px`, top: `${canvas.offsetTop + (row + 0.5) * h - size[1] / 2}px`,
    width: `${size[0]}px`, height: `${size[1]}px`,
  });
  $("sh-cursor").hidden = false;
}

function leaveSunHoursMap() {
  if (document.activeElement === $("sh-map") && sunHours.point) return;  // the keys' point stays
  $("sh-readout").textContent = SH_READOUT_HINT;
  $("sh-cursor").hidden = true;
  sunHours.point = null;
}

// --- Downloads

function sunHoursFileName(shown, extension) {
  const site = shown.body.site;
  return `sun-hours-${shown.firstDay || "period"}-${site.latitude}_${site.longitude}.${extension}`;
}

function saveBlob(blob, name) {
  const url = URL.createObjectURL(blob);
  const link = Object.assign(document.createElement("a"), { href: url, download: name });
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

// The same analysis as text/csv: from the job's location while the server
// holds its result, else the same body posted again with Accept: text/csv.
async function downloadSunHoursCsv() {
  const shown = sunHours.shown;
  if (!shown || sunHours.active) return;
  const status = $("sh-download-status");
  status.textContent = "Asking for the CSV…";
  let text = null;
  if (shown.location) {
    try {
      const response = await apiFetch(shown.location, { headers: { Accept: "text/csv" } });
      if (response.status === 200) text = await response.text();
    } catch (_) { /* asked again below */ }
  }
  if (text === null) {
    const run = { cancelled: false, controller: new AbortController(), location: null };
    sunHoursBusy(run);
    try {
      text = await (await askSunHours(run, shown.body, "text/csv")).text();
    } catch (e) {
      status.textContent = e instanceof SunHoursCancelled ? "CSV cancelled." : "No CSV: see the message below.";
      if (!(e instanceof SunHoursCancelled)) showError(e.message, "sun-hours");
      return;
    } finally {
      sunHoursBusy(null);
    }
  }
  saveBlob(new Blob([text], { type: "text/csv" }), sunHoursFileName(shown, "csv"));
  status.textContent = `Saved ${sunHoursFileName(shown, "csv")} (x, y, z, hours, longest_run_hours a point).`;
}

// The map, its scale and the legend's lines in one PNG, for a report.
function downloadSunHoursPng() {
  const shown = sunHours.shown;
  if (!shown) return;
  const map = $("sh-map"), scale = $("sh-scale");
  const lines = sunHoursLegendLines(shown).map(([term, text]) => `${term}: ${text}`);
  const out = document.createElement("canvas");
  const context = out.getContext("2d");
  context.font = "13px system-ui, sans-serif";
  const textWidth = Math.max(...lines.map((l) => context.measureText(l).width));
  out.width = Math.ceil(Math.max(map.width + scale.width + 48, textWidth + 32));
  out.height = Math.max(map.height, scale.height) + 32 + 20 * lines.length;
  context.fillStyle = "#15171b";
  context.fillRect(0, 0, out.width, out.height);
  context.drawImage(map, 16, 16);
  context.drawImage(scale, map.width + 32, 16);
  context.font = "13px system-ui, sans-serif";
  context.fillStyle = "#e6e6e6";
  context.textBaseline = "top";
  lines.forEach((line, i) => context.fillText(line, 16, Math.max(map.height, scale.height) + 24 + 20 * i));
  out.toBlob((blob) => {
    saveBlob(blob, sunHoursFileName(shown, "png"));
    $("sh-download-status").textContent = `Saved ${sunHoursFileName(shown, "png")}.`;
  });
}

function sunHoursCurl(body) {
  const json = JSON.stringify(body).replace(/'/g, "'\\''");
  const token = savedToken() ? ` -H "Authorization: Bearer $UMBRA_TOKEN"` : "";
  return `curl -X POST '${location.origin}/api/sun-hours' -H 'Content-Type: application/json'${token} -d '${json}' -o sun-hours.json` +
    "  # a 202 answer names the job's location: GET it until 200";
}

// --- Copy as curl --------------------------------------------------------------

function curlCommand(body) {
  const json = JSON.stringify(body).replace(/'/g, "'\\''");
  const file = body.output === "color" ? "frame.png" : `${body.output}.png`;
  // The token itself stays out of the page: the shell fills it in.
  const token = savedToken() ? ` -H "Authorization: Bearer $UMBRA_TOKEN"` : "";
  return `curl -X POST '${location.origin}/api/render' -H 'Content-Type: application/json'${token} -d '${json}' -o ${file}`;
}

async function copyCurl() {
  let command;
  if (sunHoursMode()) {
    const body = sunHoursBody();
    if (!body) return;
    command = sunHoursCurl(body);
  } else {
    command = curlCommand(buildRequest());
  }
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
  setUpSunHours();
  loadFromUrl();
  sunHoursAfterUrl();
  showCamera();
  syncFixedSettings();
  syncSizeNote();
  requestFrame();
}

function isCameraField(e) {
  return CAMERA_FIELDS.position.includes(e.id) || CAMERA_FIELDS.target.includes(e.id);
}

$("controls").addEventListener("input", (e) => {
  if (e.target.id === "model-file") return;  // its "change" uploads; the frame follows the answer
  if (e.target.id === "scene-json") return sceneJsonTyped();  // sent by "Render this" only
  if (e.target.id === "mode") return modeChanged();
  if (isSunHoursField(e.target)) return sunHoursFieldChanged(e.target);  // sent by Run only
  clearError("upload");
  if (isCameraField(e.target)) {
    const camera = cameraFromFields();
    if (camera) setCamera(camera);
    return;
  }
  // Another scene is seen from its own camera.
  if (e.target.id === "scene") {
    if (state.custom) leaveCustomScene();
    state.camera = null;
    showCamera();
    syncAnimations();
    sunHoursSceneChanged();
  }
  if ([...LIGHT_FIELDS, ...LIGHT_TARGET_FIELDS, "orbit"].includes(e.target.id)) lightFieldsEdited();
  if (e.target.id === "time") showLightAtTime();
  if (e.target.id === "sun_city") return;  // chooseSunCity fills the fields and renders
  if (e.target.id === "sun_lat" || e.target.id === "sun_lon") syncSunCity();
  syncSizeNote(e.target.id);
  syncFixedSettings();
  requestFrame();
});
$("controls").addEventListener("submit", (e) => e.preventDefault());
$("play").addEventListener("click", togglePlay);
$("sun_city").addEventListener("change", chooseSunCity);
$("reset-camera").addEventListener("click", () => setCamera(null));
// The gain only changes how the frame is shown: no request.
$("gain").addEventListener("input", () => {
  drawHeatmap();
  saveToUrl();
});
$("viewport").addEventListener("pointerdown", pointerDown);
$("viewport").addEventListener("pointermove", pointerMove);
$("viewport").addEventListener("pointerup", pointerUp);
$("viewport").addEventListener("pointercancel", pointerUp);
$("viewport").addEventListener("wheel", wheel, { passive: false });
$("viewport").addEventListener("contextmenu", (e) => e.preventDefault());  // right-drag pans
$("copy-curl").addEventListener("click", copyCurl);
$("load-scene").addEventListener("click", loadSceneIntoEditor);
$("render-json").addEventListener("click", renderSceneJson);
$("model-file").addEventListener("change", () => {
  const file = $("model-file").files[0];
  if (file) uploadModel(file);
});
document.addEventListener("dragover", dragOver);
document.addEventListener("dragleave", (e) => { if (e.relatedTarget === null) document.body.classList.remove("dropping"); });
document.addEventListener("drop", drop);
$("sh_city").addEventListener("change", chooseSunHoursCity);
$("sh-centre").addEventListener("click", centreGridOnScene);
$("sh-run").addEventListener("click", runSunHours);
$("sh-cancel").addEventListener("click", cancelSunHours);
$("sh-csv").addEventListener("click", downloadSunHoursCsv);
$("sh-png").addEventListener("click", downloadSunHoursPng);
$("sh-map").addEventListener("pointermove", readSunHoursPoint);
$("sh-map").addEventListener("pointerdown", readSunHoursPoint);
$("sh-map").addEventListener("pointerleave", leaveSunHoursMap);
$("sh-map").addEventListener("keydown", sunHoursKey);
start();
