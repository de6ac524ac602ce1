// The web panel as a person uses it: Debian's chromium (headless, driven by
// playwright-core) against the real umbra-server binary.
//
//   node tests/e2e/panel.test.mjs SERVER_BINARY [ARTIFACTS_DIR]
//
// Each step writes a screenshot to ARTIFACTS_DIR (default artifacts/e2e).
// Exits non-zero, naming the step, at the first failed check.
import assert from "node:assert/strict";
import { createHash } from "node:crypto";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { chromium } from "playwright-core";
import { startServer } from "./server.mjs";

const [serverBinary, artifacts = "artifacts/e2e"] = process.argv.slice(2);
if (!serverBinary) {
  console.error("usage: node panel.test.mjs SERVER_BINARY [ARTIFACTS_DIR]");
  process.exit(2);
}
const chromiumPath = process.env.UMBRA_CHROMIUM || "/usr/bin/chromium";
fs.mkdirSync(artifacts, { recursive: true });

// --- The page ------------------------------------------------------------

// Counts the panel's requests and how many are in flight at once, by
// wrapping fetch before the panel's script runs.
function countRequests() {
  const counter = { sent: 0, depthSent: 0, inFlight: 0, maxInFlight: 0, frames: 0, lastRenderBody: null, lastSunHoursBody: null };
  window.__umbra = counter;
  const original = window.fetch.bind(window);
  window.fetch = async (...args) => {
    counter.sent += 1;
    if (String(args[0]).endsWith("/api/render")) counter.lastRenderBody = args[1].body;
    if (String(args[0]).endsWith("/api/depth")) counter.depthSent += 1;
    if (String(args[0]).endsWith("/api/sun-hours")) counter.lastSunHoursBody = args[1].body;
    counter.inFlight += 1;
    counter.maxInFlight = Math.max(counter.maxInFlight, counter.inFlight);
    try {
      return await original(...args);
    } finally {
      counter.inFlight -= 1;
    }
  };
  // Every new frame image that finishes loading.
  document.addEventListener("load", (e) => { if (e.target.id === "frame") counter.frames += 1; }, true);
}

// Size and mean colour of a loaded <img>, read through a canvas.
async function imageStats(page, id) {
  return page.$eval(`#${id}`, (img) => {
    const canvas = document.createElement("canvas");
    canvas.width = img.naturalWidth;
    canvas.height = img.naturalHeight;
    const context = canvas.getContext("2d");
    context.drawImage(img, 0, 0);
    const data = context.getImageData(0, 0, canvas.width, canvas.height).data;
    let r = 0, g = 0, b = 0, digest = 0;
    for (let i = 0; i < data.length; i += 4) {
      r += data[i];
      g += data[i + 1];
      b += data[i + 2];
      digest = (digest * 31 + data[i] + 7 * data[i + 1] + 13 * data[i + 2]) % 1000000007;
    }
    const n = data.length / 4;
    return { width: img.naturalWidth, height: img.naturalHeight, r: r / n, g: g / n, b: b / n, digest, src: img.src };
  });
}

// Waits until both images have been replaced since `before` (and loaded).
async function waitForNewImages(page, before) {
  await page.waitForFunction(
    ([frameSrc, depthSrc]) => {
      const frame = document.getElementById("frame");
      const depth = document.getElementById("depth");
      return frame.src !== frameSrc && depth.src !== depthSrc && frame.complete && depth.complete &&
             frame.naturalWidth > 0 && depth.naturalWidth > 0 && window.__umbra.inFlight === 0;
    },
    [before.frame, before.depth],
    { timeout: 60000 },
  );
}

async function currentSources(page) {
  return page.evaluate(() => ({ frame: document.getElementById("frame").src, depth: document.getElementById("depth").src }));
}

// --- A model to upload ------------------------------------------------------

// A .glb holding one 2 x 1 x 1 box as 12 triangles (or, with mode 1, the
// same indices as LINES, which the server refuses): little-endian header
// "glTF" v2, a JSON chunk padded with spaces, a BIN chunk padded with zeros.
function boxGlb(mode = 4) {
  const min = [-1, 0, -0.5], max = [1, 1, 0.5];
  const corners = [];
  for (let i = 0; i < 8; i += 1) corners.push([i & 4 ? max[0] : min[0], i & 2 ? max[1] : min[1], i & 1 ? max[2] : min[2]]);
  // Each face as two triangles wound counter-clockwise seen from outside:
  // flipped wherever the normal points inwards.
  const faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
  const indices = [];
  for (const [a, b, c, d] of faces) {
    for (const t of [[a, b, c], [a, c, d]]) {
      const [p, q, r] = t.map((i) => corners[i]);
      const u = q.map((v, k) => v - p[k]), w = r.map((v, k) => v - p[k]);
      const normal = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
      const centre = [p, q, r].reduce((sum, v) => sum.map((x, k) => x + v[k] / 3), [0, 0, 0]);
      const outwards = normal.reduce((dot, x, k) => dot + x * centre[k], 0) - normal[1] * 0.5 > 0;  // box centre (0, 0.5, 0)
      indices.push(...(outwards ? t : [t[0], t[2], t[1]]));
    }
  }
  const positions = Buffer.from(new Float32Array(corners.flat()).buffer);
  const indexBytes = Buffer.from(new Uint16Array(indices).buffer);
  const bin = pad(Buffer.concat([positions, indexBytes]), 0);
  const json = {
    asset: { version: "2.0" },
    scene: 0,
    scenes: [{ nodes: [0] }],
    nodes: [{ mesh: 0 }],
    meshes: [{ primitives: [{ attributes: { POSITION: 0 }, indices: 1, mode }] }],
    accessors: [
      { bufferView: 0, componentType: 5126, count: 8, type: "VEC3", min, max },
      { bufferView: 1, componentType: 5123, count: indices.length, type: "SCALAR" },
    ],
    bufferViews: [
      { buffer: 0, byteOffset: 0, byteLength: positions.length, target: 34962 },
      { buffer: 0, byteOffset: positions.length, byteLength: indexBytes.length, target: 34963 },
    ],
    buffers: [{ byteLength: positions.length + indexBytes.length }],
  };
  const text = pad(Buffer.from(JSON.stringify(json)), 0x20);
  const header = Buffer.alloc(12);
  header.write("glTF", 0, "ascii");
  header.writeUInt32LE(2, 4);
  header.writeUInt32LE(12 + 8 + text.length + 8 + bin.length, 8);
  return Buffer.concat([header, chunkHeader(text.length, "JSON"), text, chunkHeader(bin.length, "BIN\0"), bin]);
}

function pad(buffer, byte) {
  return Buffer.concat([buffer, Buffer.alloc((4 - (buffer.length % 4)) % 4, byte)]);
}

function chunkHeader(length, type) {
  const header = Buffer.alloc(8);
  header.writeUInt32LE(length, 0);
  header.write(type, 4, "latin1");
  return header;
}

// Chooses a file in the panel's file input.
async function chooseFile(page, name, buffer) {
  await page.setInputFiles("#model-file", { name, mimeType: "application/octet-stream", buffer });
}

// Drops a file on the page as a person would drag it from a file manager.
async function dropFile(page, name, bytes) {
  await page.evaluate(([name, bytes]) => {
    const data = new DataTransfer();
    data.items.add(new File([new Uint8Array(bytes)], name));
    for (const type of ["dragover", "drop"]) {
      document.body.dispatchEvent(new DragEvent(type, { dataTransfer: data, bubbles: true, cancelable: true }));
    }
  }, [name, Array.from(bytes)]);
}

// Runs the panel's "Copy as curl" command (as curl would) and checks that
// it returns the very PNG the panel shows.
async function checkCurlGivesTheFrame(page, port) {
  await page.click("#copy-curl");
  const command = await page.$eval("#curl", (pre) => pre.textContent);
  const match = command.match(/^curl -X POST '([^']+)' -H 'Content-Type: application\/json' -d '(.*)' -o \S+$/);
  assert.ok(match, `a curl command: ${command}`);
  assert.equal(match[1], `http://127.0.0.1:${port}/api/render`);
  const body = JSON.parse(match[2].replace(/'\\''/g, "'"));
  assert.deepEqual(body, JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)));
  // Sent as it is, it gives the very PNG the panel shows.
  const response = await fetch(match[1], { method: "POST", headers: { "Content-Type": "application/json" }, body: match[2] });
  assert.equal(response.status, 200);
  const curlBytes = Buffer.from(await response.arrayBuffer());
  const panelBytes = Buffer.from(await page.evaluate(async () => {
    const blob = await (await fetch(document.getElementById("frame").src)).arrayBuffer();
    return Array.from(new Uint8Array(blob));
  }));
  assert.ok(curlBytes.equals(panelBytes), "same PNG bytes as the panel's frame");
  return command;
}

// The camera the panel would send: the request's own, else the fields'
// (which show the scene's default camera, not sent).
async function cameraInUse(page) {
  const body = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
  if (body.camera) return { sent: true, ...body.camera };
  const read = (ids) => page.evaluate((ids) => ids.map((id) => Number(document.getElementById(id).value)), ids);
  return { sent: false, position: await read(["cx", "cy", "cz"]), target: await read(["ctx", "cty", "ctz"]) };
}

function distance(camera) {
  return Math.hypot(...camera.position.map((x, i) => x - camera.target[i]));
}

// The frame's box on screen, scrolled into view first (clicking a control
// further down the form scrolls the page).
async function viewportBox(page) {
  await page.$eval("#viewport", (v) => v.scrollIntoView({ block: "nearest" }));
  return page.$eval("#viewport", (v) => { const r = v.getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; });
}

// Synthetic touch pointers (pointerType "touch") on the frame: what a
// finger sends, without a touch screen.
async function touch(page, type, pointerId, x, y) {
  await page.$eval("#viewport", (element, [type, pointerId, x, y]) => {
    element.dispatchEvent(new PointerEvent(type, { pointerId, pointerType: "touch", clientX: x, clientY: y,
                                                   isPrimary: pointerId === 1, bubbles: true, cancelable: true }));
  }, [type, pointerId, x, y]);
}

// Types text into a field as a person would (fill() refuses "1e" in a
// number field, which is exactly what a person can type).
async function typeInto(page, id, text) {
  await page.click(`#${id}`, { clickCount: 3 });
  await page.keyboard.press("Control+A");
  await page.keyboard.press("Backspace");
  await page.keyboard.type(text);
}

// The requests sent once the panel has gone quiet. A frame's depth request
// follows its render request once the render has arrived, so "nothing in
// flight" can fall between the two: nothing may have been sent for 300 ms
// as well.
async function quietSent(page) {
  let sent = -1;
  for (;;) {
    await page.waitForFunction(() => window.__umbra.inFlight === 0, null, { timeout: 60000 });
    const now = await page.evaluate(() => window.__umbra.sent);
    if (now === sent) return sent;
    sent = now;
    await page.waitForTimeout(300);
  }
}

async function sentStaysAt(page, sent, ms = 800) {
  await page.waitForTimeout(ms);
  assert.equal(await page.evaluate(() => window.__umbra.sent), sent, "nothing sent");
}

// The depth map's tiles as shown: each one's label, and the grey range of
// its canvas and of the same tile in the PNG as sent (far-plane texels,
// 255 in the PNG and FAR_COLOUR on the canvas, left out of both).
async function depthTiles(page) {
  return page.evaluate(() => {
    const image = document.getElementById("depth");
    const raw = Object.assign(document.createElement("canvas"), { width: image.naturalWidth, height: image.naturalHeight });
    raw.getContext("2d").drawImage(image, 0, 0);
    const rawData = raw.getContext("2d").getImageData(0, 0, raw.width, raw.height).data;
    const tiles = Array.from(document.querySelectorAll("#depth-tiles .depth-tile"));
    const grid = Math.ceil(Math.sqrt(tiles.length) - 1e-9);
    return tiles.map((tile, i) => {
      const canvas = tile.querySelector("canvas");
      const shown = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
      let shownMin = 255, shownMax = 0, grey = 0;
      for (let o = 0; o < shown.length; o += 4) {
        if (shown[o] !== shown[o + 1] || shown[o] !== shown[o + 2]) continue;  // the far plane's colour
        grey += 1;
        shownMin = Math.min(shownMin, shown[o]);
        shownMax = Math.max(shownMax, shown[o]);
      }
      const size = raw.width, column = i % grid, row = Math.floor(i / grid);
      let rawMin = 255, rawMax = 0;
      for (let y = Math.round((row * size) / grid) + 2; y < Math.round(((row + 1) * size) / grid) - 2; y += 1) {
        for (let x = Math.round((column * size) / grid) + 2; x < Math.round(((column + 1) * size) / grid) - 2; x += 1) {
          const v = rawData[4 * (y * size + x)];
          if (v === 255) continue;
          rawMin = Math.min(rawMin, v);
          rawMax = Math.max(rawMax, v);
        }
      }
      return { label: tile.querySelector("figcaption").textContent, shownMin, shownMax, rawMin, rawMax, grey };
    });
  });
}

// --- Sun hours -------------------------------------------------------------

// As the panel writes hours and shares.
const hoursText = (h) => String(Number(h.toFixed(2)));
function percentText(share) {
  const p = 100 * share;
  if (p > 0 && p < 0.05) return "< 0.1 %";
  if (p < 100 && p >= 99.95) return "> 99.9 %";
  return `${Number(p.toFixed(1))} %`;
}

// The centre of cell `i` of the sun-hours map, in page coordinates.
async function sunHoursCell(page, answer, i) {
  await page.$eval("#sh-map", (c) => c.scrollIntoView({ block: "nearest" }));
  const box = await page.$eval("#sh-map", (c) => { const r = c.getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; });
  const { columns, rows } = answer.grid;
  const column = i % columns, row = Math.floor(i / columns);
  return [box[0] + ((column + 0.5) * box[2]) / columns, box[1] + ((row + 0.5) * box[3]) / rows];
}

// The map's pixel at the centre of cell `i` (canvas coordinates).
async function sunHoursPixel(page, answer, i) {
  return page.$eval("#sh-map", (canvas, [i, columns, rows]) => {
    const x = Math.floor((((i % columns) + 0.5) * canvas.width) / columns);
    const y = Math.floor(((Math.floor(i / columns) + 0.5) * canvas.height) / rows);
    return Array.from(canvas.getContext("2d").getImageData(x, y, 1, 1).data.slice(0, 3));
  }, [i, answer.grid.columns, answer.grid.rows]);
}

// Clicks "Download CSV" and returns the saved file's lines.
async function downloadedCsv(page) {
  const [download] = await Promise.all([page.waitForEvent("download", { timeout: 60000 }), page.click("#sh-csv")]);
  assert.match(download.suggestedFilename(), /^sun-hours-.+\.csv$/);
  return fs.readFileSync(await download.path(), "utf8").trimEnd().split("\n");
}

// Records every state the progress line shows (it may show one for under a second).
function recordProgress() {
  window.__progress = [];
  const record = () => {
    const box = document.getElementById("sh-progress");
    if (!box.hidden) window.__progress.push(`${box.dataset.state}: ${document.getElementById("sh-progress-text").textContent}`);
  };
  new MutationObserver(record).observe(document.getElementById("sh-progress"), { attributes: true, childList: true, subtree: true, characterData: true });
}

let stepNumber = 0;
// The light's fields show the last request's light.position turned about
// light.target by time x orbit_deg_per_s (the server's orbit_light_position).
// The panel turns the fields and sends the request in one task, so one
// evaluate sees both as they were sent, even while playing.
async function checkLightFieldsShowTheOrbit(page) {
  const { body, fields } = await page.evaluate(() => ({
    body: JSON.parse(window.__umbra.lastRenderBody),
    fields: ["lx", "ly", "lz"].map((id) => Number(document.getElementById(id).value)),
  }));
  const target = body.light.target || [0, 0, 0];
  const angle = ((body.time * (body.light.orbit_deg_per_s ?? 20)) % 360) * Math.PI / 180;
  const [x, y, z] = body.light.position.map((v, i) => v - target[i]);
  const turned = [x * Math.cos(angle) + z * Math.sin(angle), y, -x * Math.sin(angle) + z * Math.cos(angle)].map((v, i) => v + target[i]);
  for (let i = 0; i < 3; ++i) {
    assert.ok(Math.abs(fields[i] - turned[i]) < 1e-4,
              `light field ${"xyz"[i]} shows ${fields[i]}, the light is at ${turned[i].toFixed(5)} at t = ${body.time} (sent ${body.light.position})`);
  }
}

async function step(page, name, body) {
  stepNumber += 1;
  const label = `${String(stepNumber).padStart(2, "0")}-${name}`;
  try {
    await body();
  } finally {
    await page.screenshot({ path: path.join(artifacts, `${label}.png`), fullPage: true }).catch(() => {});
  }
  console.log(`ok ${stepNumber} - ${name}`);
}

// --- The checks ------------------------------------------------------------

const server = startServer(serverBinary);
const port = await server.port;
let guarded = null;  // the server with --tokens, for the last step
let jobServer = null;  // the server whose every sun-hours analysis is a job
const browser = await chromium.launch({
  executablePath: chromiumPath,
  args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"],
});
let failed = false;
try {
  const context = await browser.newContext({ viewport: { width: 1400, height: 1000 } });
  await context.grantPermissions(["clipboard-read", "clipboard-write"], { origin: `http://127.0.0.1:${port}` });
  const page = await context.newPage();
  await page.addInitScript(countRequests);
  await page.goto(`http://127.0.0.1:${port}/`);

  let ortho;
  await step(page, "first-frame-and-depth-preview", async () => {
    await waitForNewImages(page, { frame: "", depth: "" });
    const frame = await imageStats(page, "frame");
    const depth = await imageStats(page, "depth");
    const mapSize = Number(await page.$eval("#map_size", (s) => s.value));
    assert.deepEqual([frame.width, frame.height], [960, 540], "the frame is 960x540");
    assert.deepEqual([depth.width, depth.height], [mapSize, mapSize], "the depth preview is map_size square");
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    assert.equal(new URL(page.url()).search, "", "the first address is clean");
    const camera = await cameraInUse(page);
    assert.ok(!camera.sent, "the scene's own camera is not sent");
    const listed = (await (await fetch(`http://127.0.0.1:${port}/api/scenes`)).json()).scenes[0].camera;
    assert.deepEqual([camera.position, camera.target], [listed.position, listed.target], "the fields show the scene's camera");
    ortho = { frame, depth };
  });

  await step(page, "perspective-changes-frame-and-depth", async () => {
    const before = await currentSources(page);
    await page.selectOption("#projection", "perspective");
    await waitForNewImages(page, before);
    const frame = await imageStats(page, "frame");
    const depth = await imageStats(page, "depth");
    assert.notEqual(frame.digest, ortho.frame.digest, "the frame changed");
    assert.notEqual(depth.digest, ortho.depth.digest, "the depth preview changed");
    const back = await currentSources(page);
    await page.selectOption("#projection", "orthographic");
    await waitForNewImages(page, back);
  });

  await step(page, "red-light-tints-the-frame", async () => {
    const white = await imageStats(page, "frame");
    const before = await currentSources(page);
    await page.$eval("#color", (input) => {
      input.value = "#ff0000";
      input.dispatchEvent(new Event("input", { bubbles: true }));
    });
    await waitForNewImages(page, before);
    const red = await imageStats(page, "frame");
    // White light: about grey-balanced. Red light: green and blue keep only
    // the ambient share, red keeps all of it.
    assert.ok(red.r > 1.5 * red.g && red.r > 1.5 * red.b, `red dominates (r ${red.r.toFixed(1)}, g ${red.g.toFixed(1)}, b ${red.b.toFixed(1)})`);
    assert.ok(red.g < 0.8 * white.g, "green fell under a red light");
  });

  await step(page, "play-advances-time-one-request-at-a-time", async () => {
    const time0 = Number(await page.$eval("#time", (i) => i.value));
    const frames0 = await page.evaluate(() => window.__umbra.frames);
    await page.evaluate(() => { window.__umbra.maxInFlight = 0; });
    await page.click("#play");
    assert.equal(await page.$eval("#play", (b) => b.getAttribute("aria-pressed")), "true");
    await page.waitForFunction((n) => window.__umbra.frames >= n + 3, frames0, { timeout: 60000 });
    const time1 = Number(await page.$eval("#time", (i) => i.value));
    assert.ok(time1 > time0, `time advanced (${time0} -> ${time1})`);
    // The position fields follow the light along its orbit; the request
    // keeps sending where it is at time 0.
    const played = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    assert.deepEqual(played.light.position, [-2, 4, -1], "the request's light.position is the time-0 position");
    await checkLightFieldsShowTheOrbit(page);
    assert.equal(await page.evaluate(() => window.__umbra.maxInFlight), 1, "never more than one request in flight");
    assert.match(await page.$eval("#timing", (p) => p.textContent), /frames\/s/, "frames per second shown while playing");
  });

  await step(page, "pause-stops-the-requests", async () => {
    await page.click("#play");
    assert.equal(await page.$eval("#play", (b) => b.getAttribute("aria-pressed")), "false");
    const sent = await quietSent(page);
    const time = await page.$eval("#time", (i) => i.value);
    await page.waitForTimeout(1500);
    assert.equal(await page.evaluate(() => window.__umbra.sent), sent, "no request after pausing");
    assert.equal(await page.$eval("#time", (i) => i.value), time, "time stands still");
  });

  await step(page, "settings-live-in-the-url", async () => {
    const before = await currentSources(page);
    await page.selectOption("#scene", "three-cubes");
    await page.selectOption("#cascades", "3");
    await waitForNewImages(page, before);
    const url = new URL(page.url());
    assert.equal(url.searchParams.get("scene"), "three-cubes");
    assert.equal(url.searchParams.get("color"), "#ff0000");
    assert.equal(url.searchParams.get("cascades"), "3");
    assert.ok(!url.searchParams.has("map_size"), "defaults stay out of the link");
    const body = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    // The link opens the same view: same controls, same request.
    const other = await page.context().newPage();
    await other.addInitScript(countRequests);
    await other.goto(url.href);
    await waitForNewImages(other, { frame: "", depth: "" });
    assert.equal(await other.$eval("#scene", (s) => s.value), "three-cubes");
    assert.equal(await other.$eval("#color", (c) => c.value), "#ff0000");
    assert.deepEqual(JSON.parse(await other.evaluate(() => window.__umbra.lastRenderBody)), body);
    await other.screenshot({ path: path.join(artifacts, "settings-link-opened.png"), fullPage: true });
    await other.close();
    // A link with a value no control can take says so and renders the rest.
    const bad = await page.context().newPage();
    await bad.goto(`http://127.0.0.1:${port}/?map_size=3&bogus=1&scene=three-cubes`);
    await bad.waitForFunction(() => /map_size, bogus/.test(document.getElementById("notice").textContent));
    assert.equal(await bad.$eval("#scene", (s) => s.value), "three-cubes");
    await bad.close();
  });

  await step(page, "depth-map-views-are-labelled-and-stretched", async () => {
    // Three cascades: a 2 x 2 grid in the PNG, three tiles shown (not the grey fourth cell).
    assert.match(await page.$eval("#timing", (p) => p.textContent), /light views: cascades; views=3/);
    let tiles = await depthTiles(page);
    assert.deepEqual(tiles.map((t) => t.label), ["cascade 0", "cascade 1", "cascade 2"]);
    for (const t of tiles) {
      console.log(`  ${t.label}: PNG grey ${t.rawMin}..${t.rawMax}, shown ${t.shownMin}..${t.shownMax}`);
      assert.ok(t.shownMax - t.shownMin >= 250, `${t.label} is stretched to black..white (${t.shownMin}..${t.shownMax})`);
    }
    // The nearest cascade spans a small part of the PNG's grey scale (about
    // 90 of 255 levels here; a farther one can span nearly all of it).
    assert.ok(tiles.some((t) => t.shownMax - t.shownMin >= 2 * (t.rawMax - t.rawMin)),
              "a cascade's contrast is stretched well beyond the PNG's");
    // A point light: six cube faces, labelled in the renderer's layer order.
    const before = await currentSources(page);
    await page.selectOption("#projection", "perspective");
    await waitForNewImages(page, before);
    await page.waitForFunction(() => document.querySelectorAll("#depth-tiles .depth-tile").length === 6, null, { timeout: 60000 });
    tiles = await depthTiles(page);
    assert.deepEqual(tiles.map((t) => t.label.replace(" (empty)", "")),
                     ["cube face +X", "cube face −X", "cube face +Y", "cube face −Y", "cube face +Z", "cube face −Z"]);
    await page.$eval("#depth-figure", (f) => f.scrollIntoView());
    await page.screenshot({ path: path.join(artifacts, "depth-cube-faces.png"), fullPage: true });
    const back = await currentSources(page);
    await page.selectOption("#projection", "orthographic");
    await waitForNewImages(page, back);
  });

  await step(page, "copy-as-curl-is-the-exact-request", async () => {
    const command = await checkCurlGivesTheFrame(page, port);
    assert.equal(await page.$eval("#copy-status", (s) => s.textContent), "Copied to the clipboard.");
    assert.equal(await page.evaluate(() => navigator.clipboard.readText()), command, "the clipboard holds it");
  });

  await step(page, "drag-orbits-the-camera", async () => {
    const start = await cameraInUse(page);
    const box = await viewportBox(page);
    const before = await currentSources(page);
    await page.mouse.move(box[0] + box[2] / 2, box[1] + box[3] / 2);
    await page.mouse.down();
    await page.mouse.move(box[0] + box[2] / 2 + 120, box[1] + box[3] / 2 + 40, { steps: 6 });
    await page.mouse.up();
    await waitForNewImages(page, before);
    // The drag's last position is sent once the request in flight is
    // answered: wait until the page has sent what its fields show.
    await page.waitForFunction(() => {
      const body = JSON.parse(window.__umbra.lastRenderBody);
      const fields = ["cx", "cy", "cz"].map((id) => Number(document.getElementById(id).value));
      return window.__umbra.inFlight === 0 && body.camera && body.camera.position.every((x, i) => x === fields[i]);
    }, null, { timeout: 60000 }).catch(() => {});  // on timeout the assertions below say what differs
    const moved = await cameraInUse(page);
    assert.ok(moved.sent, "the next request has a camera");
    assert.deepEqual(moved.target, start.target, "orbiting keeps the target");
    assert.notDeepEqual(moved.position, start.position, "the position moved");
    assert.ok(Math.abs(distance(moved) - distance(start)) < 1e-3 * distance(start), "at the same distance");
    assert.ok(moved.position[1] > start.position[1], "dragging down raises the camera (OrbitControls)");
    const fields = await page.evaluate(() => ["cx", "cy", "cz"].map((id) => Number(document.getElementById(id).value)));
    assert.deepEqual(fields, moved.position, "the fields follow the camera");
    const url = new URL(page.url());
    assert.equal(url.searchParams.get("camera"), moved.position.join(","), "the camera is in the address");
    assert.equal(url.searchParams.get("camera_target"), moved.target.join(","));
    await checkCurlGivesTheFrame(page, port);
    // The link opens the same view.
    const other = await page.context().newPage();
    await other.addInitScript(countRequests);
    await other.goto(url.href);
    await waitForNewImages(other, { frame: "", depth: "" });
    assert.deepEqual(JSON.parse(await other.evaluate(() => window.__umbra.lastRenderBody)),
                     JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)));
    await other.close();
  });

  await step(page, "wheel-dollies-right-drag-pans", async () => {
    const start = await cameraInUse(page);
    const box = await viewportBox(page);
    const centre = [box[0] + box[2] / 2, box[1] + box[3] / 2];
    let before = await currentSources(page);
    await page.mouse.move(...centre);
    await page.mouse.wheel(0, -300);  // towards the scene
    await waitForNewImages(page, before);
    await page.waitForFunction((d) => {
      const c = JSON.parse(window.__umbra.lastRenderBody).camera;
      return Math.hypot(...c.position.map((x, i) => x - c.target[i])) < 0.9 * d && window.__umbra.inFlight === 0;
    }, distance(start), { timeout: 60000 });
    const zoomed = await cameraInUse(page);
    assert.deepEqual(zoomed.target, start.target, "dollying keeps the target");
    // Right-drag pans: position and target move together.
    before = await currentSources(page);
    await page.mouse.down({ button: "right" });
    await page.mouse.move(centre[0] - 80, centre[1], { steps: 4 });
    await page.mouse.up({ button: "right" });
    await waitForNewImages(page, before);
    const panned = await cameraInUse(page);
    assert.notDeepEqual(panned.target, zoomed.target, "the target moved");
    const offset = (c) => c.position.map((x, i) => x - c.target[i]);
    offset(panned).forEach((x, i) => assert.ok(Math.abs(x - offset(zoomed)[i]) < 1e-3, "the view direction is kept"));
  });

  await step(page, "touch-pinch-and-one-finger-orbit", async () => {
    const start = await cameraInUse(page);
    const before = await currentSources(page);
    // Two fingers spread apart: dolly in.
    await touch(page, "pointerdown", 1, 400, 300);
    await touch(page, "pointerdown", 2, 500, 300);
    await touch(page, "pointermove", 1, 350, 300);
    await touch(page, "pointermove", 2, 550, 300);
    await touch(page, "pointerup", 1, 350, 300);
    await touch(page, "pointerup", 2, 550, 300);
    await waitForNewImages(page, before);
    await page.waitForFunction(() => window.__umbra.inFlight === 0);
    const pinched = await cameraInUse(page);
    assert.ok(distance(pinched) < 0.6 * distance(start), `spreading two fingers dollies in (${distance(start)} -> ${distance(pinched)})`);
    // One finger orbits.
    const again = await currentSources(page);
    await touch(page, "pointerdown", 3, 400, 300);
    await touch(page, "pointermove", 3, 300, 300);
    await touch(page, "pointerup", 3, 300, 300);
    await waitForNewImages(page, again);
    const orbited = await cameraInUse(page);
    assert.deepEqual(orbited.target, pinched.target);
    assert.notDeepEqual(orbited.position, pinched.position);
  });

  await step(page, "reset-camera-cleans-the-address", async () => {
    const before = await currentSources(page);
    await page.click("#reset-camera");
    await waitForNewImages(page, before);
    assert.ok(!(await cameraInUse(page)).sent, "the scene's own camera again, not sent");
    assert.ok(!new URL(page.url()).searchParams.has("camera"), "no camera in the address");
  });

  await step(page, "bad-field-is-marked-and-nothing-sent", async () => {
    // On the way to "1e" the field held "1", a number, which was sent.
    await typeInto(page, "ly", "1e");
    await page.waitForSelector("#ly[aria-invalid=true]");
    assert.match(await page.$eval("#ly-problem", (p) => p.textContent), /^Light position y: not a number\./);
    assert.ok(await page.$eval("#held", (p) => !p.hidden), "the panel says nothing was sent");
    const sent = await quietSent(page);
    await sentStaysAt(page, sent);
    assert.notEqual(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).light.position[1], 0,
                    "never sent as 0 (the light on the horizon)");
    await page.keyboard.press("Backspace");  // "1": a number again
    await page.waitForFunction(() => !document.getElementById("ly-problem"));
    await page.waitForFunction((n) => window.__umbra.sent > n, sent);
    assert.equal(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).light.position[1], 1);
    // Size -3 is below the field's minimum.
    const sent2 = await quietSent(page);
    await typeInto(page, "size", "-3");
    await page.waitForSelector("#size[aria-invalid=true]");
    assert.match(await page.$eval("#size-problem", (p) => p.textContent), /at least 0/);
    await sentStaysAt(page, sent2);
    // A size with the PCF filter: the panel chooses PCSS and says why.
    await typeInto(page, "size", "2");
    await page.waitForFunction(() => document.getElementById("filter").value === "pcss");
    assert.match(await page.$eval("#size-note", (p) => p.textContent), /PCSS/);
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && JSON.parse(window.__umbra.lastRenderBody).light.size === 2);
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    await page.selectOption("#filter", "pcf");
    assert.match(await page.$eval("#size-note", (p) => p.textContent), /Size not used/);
    // Back as it was.
    await typeInto(page, "size", "0");
    await typeInto(page, "ly", "4");
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && JSON.parse(window.__umbra.lastRenderBody).light.position[1] === 4);
    assert.equal(await page.$eval("#size-note", (p) => p.textContent), "");
  });

  await step(page, "error-view-shows-its-figures-and-an-amplified-heatmap", async () => {
    const before = await currentSources(page);
    await page.selectOption("#view", "error");
    await waitForNewImages(page, before);
    await page.waitForSelector("#error-panel:not([hidden]) #figure-mae");
    // The figures are the server's header, as sent for this very request.
    const body = await page.evaluate(() => window.__umbra.lastRenderBody);
    const response = await fetch(`http://127.0.0.1:${port}/api/render`, { method: "POST", body });
    const header = response.headers.get("Umbra-Shadow-Error");
    const mae = header.match(/mae=([\d.]+)/)[1];
    assert.equal(await page.$eval("#figure-mae", (d) => d.textContent), mae);
    for (const key of ["wrong", "false_shadow", "false_light", "artifacts"]) {
      assert.match(await page.$eval(`#figure-${key}`, (d) => d.textContent), /^[\d.]+ %$/, key);
    }
    assert.match(await page.$eval("#figure-pixels", (d) => d.textContent), /^[\d,]+$/);
    // The heatmap shown is the PNG amplified (x16 by default), the legend says so.
    assert.ok(await page.$eval("#frame", (i) => i.hidden), "the raw PNG is not what is shown");
    assert.match(await page.$eval("#legend", (p) => p.textContent), /Gain ×16/);
    const sums = await page.evaluate(() => {
      const sum = (canvas) => canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data.reduce((a, b) => a + b, 0);
      const image = document.getElementById("frame");
      const raw = Object.assign(document.createElement("canvas"), { width: image.naturalWidth, height: image.naturalHeight });
      raw.getContext("2d").drawImage(image, 0, 0);
      return { raw: sum(raw), shown: sum(document.getElementById("heatmap")) };
    });
    assert.ok(sums.shown > sums.raw, `the heatmap is brighter than the PNG (${sums.shown} > ${sums.raw})`);
    await page.screenshot({ path: path.join(artifacts, "error-view.png"), fullPage: true });
    // The gain is the browser's: changing it sends nothing.
    const sent = await page.evaluate(() => window.__umbra.sent);
    await page.selectOption("#gain", "64");
    assert.match(await page.$eval("#legend", (p) => p.textContent), /Gain ×64/);
    await sentStaysAt(page, sent, 300);
    assert.equal(new URL(page.url()).searchParams.get("gain"), "64");
    await checkCurlGivesTheFrame(page, port);
    await page.selectOption("#gain", "16");
    const back = await currentSources(page);
    await page.selectOption("#view", "color");
    await waitForNewImages(page, back);
    assert.ok(await page.$eval("#error-panel", (a) => a.hidden), "the figures go with the error view");
  });

  await step(page, "exact-filter-certifies-and-shows-the-share", async () => {
    const filter = await page.$eval("#filter", (s) => s.value);
    const before = await currentSources(page);
    await page.selectOption("#filter", "exact");
    await waitForNewImages(page, before);
    const sent = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    assert.equal(sent.shadow.filter, "exact");
    assert.ok(!("pcf_radius" in sent.shadow), "no pcf_radius with filter exact");
    // The share the server ray cast, from Umbra-Certified, and its settle stage.
    const timing = await page.$eval("#timing", (p) => p.textContent);
    assert.match(timing, /certified: [\d.]+ % of pixels ray cast \([\d,]+ of [\d,]+\), by the maps/);
    assert.match(timing, /settle [\d.]+/);
    // Its shadow term is the exact reference's: the error view is black.
    const toError = await currentSources(page);
    await page.selectOption("#view", "error");
    await waitForNewImages(page, toError);
    await page.waitForSelector("#error-panel:not([hidden]) #figure-mae");
    assert.equal(Number(await page.$eval("#figure-mae", (d) => d.textContent)), 0, "mae 0 with filter exact");
    assert.equal(await page.$eval("#figure-wrong", (d) => d.textContent), "0.0000 %");
    const toColor = await currentSources(page);
    await page.selectOption("#view", "color");
    await waitForNewImages(page, toColor);
    // An area light needs PCSS: a size chooses it, as with hard and PCF.
    await typeInto(page, "size", "2");
    await page.waitForFunction(() => document.getElementById("filter").value === "pcss");
    assert.match(await page.$eval("#size-note", (p) => p.textContent), /PCSS/);
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && JSON.parse(window.__umbra.lastRenderBody).light.size === 2);
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    // The timing line follows the image it belongs to, which the page shows
    // once decoded, after the answer: wait for the PCSS frame's line.
    await page.waitForFunction(() => !/certified/.test(document.getElementById("timing").textContent));
    // Back as it was.
    await typeInto(page, "size", "0");
    await page.selectOption("#filter", filter);
    await quietSent(page);
    assert.equal(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).shadow.filter, filter);
  });

  await step(page, "alt-drag-moves-the-light-target-and-orbit-speed", async () => {
    const start = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    const box = await viewportBox(page);
    const before = await currentSources(page);
    await page.keyboard.down("Alt");
    await page.mouse.move(box[0] + box[2] / 2, box[1] + box[3] / 2);
    await page.mouse.down();
    await page.mouse.move(box[0] + box[2] / 2 + 60, box[1] + box[3] / 2, { steps: 3 });
    await page.mouse.up();
    await page.keyboard.up("Alt");
    await waitForNewImages(page, before);
    const moved = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    assert.notDeepEqual(moved.light.position, start.light.position, "the light moved");
    assert.ok(Math.abs(moved.light.position[1] - start.light.position[1]) < 1e-3, "a drag across keeps its height");
    assert.deepEqual(moved.camera, start.camera, "the camera stayed");
    await checkLightFieldsShowTheOrbit(page);
    // Target and orbit speed are sent once they differ from the API's defaults.
    const again = await currentSources(page);
    await typeInto(page, "lty", "0.5");
    await typeInto(page, "orbit", "45");
    await waitForNewImages(page, again);
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && JSON.parse(window.__umbra.lastRenderBody).light.orbit_deg_per_s === 45);
    const body = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    assert.deepEqual(body.light.target, [0, 0.5, 0]);
    if (body.time !== 0) assert.match(await page.$eval("#light-now", (p) => p.textContent), /^Shown at t = [\d.]+ s; sent as position \(/);
    await checkLightFieldsShowTheOrbit(page);
    await checkCurlGivesTheFrame(page, port);
    // Back to the defaults: neither is sent.
    await typeInto(page, "lty", "0");
    await typeInto(page, "orbit", "20");
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && !("orbit_deg_per_s" in JSON.parse(window.__umbra.lastRenderBody).light));
    assert.ok(!("target" in JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).light));
  });

  await step(page, "sun-mode-places-the-light-by-place-and-time-and-plays-the-day", async () => {
    const lastBody = async () => JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    const time0 = await page.$eval("#time", (i) => i.value);
    await typeInto(page, "time", "0");
    let before = await currentSources(page);
    await page.selectOption("#light_mode", "sun");
    await waitForNewImages(page, before);
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && "sun" in JSON.parse(window.__umbra.lastRenderBody).light);
    let body = await lastBody();
    assert.deepEqual(body.light.sun, { latitude: 48.8566, longitude: 2.3522, utc: "2026-12-21T14:00:00Z" });
    for (const key of ["position", "projection", "orbit_deg_per_s"]) assert.ok(!(key in body.light), `no ${key} with a sun`);
    assert.equal(await page.$eval("#sun_city", (s) => s.selectedOptions[0].textContent), "Paris");
    // Paris on a winter afternoon: low in the south-west, as the server's Umbra-Sun says.
    const sunNow = async () => page.$eval("#sun-now", (p) => ({ text: p.textContent, azimuth: Number(p.dataset.azimuth), elevation: Number(p.dataset.elevation) }));
    let sun = await sunNow();
    assert.match(sun.text, /^2026-12-21 14:00 UTC: sun at azimuth [\d.]+°, elevation [\d.]+°\.$/);
    assert.ok(sun.azimuth > 180 && sun.azimuth < 270 && sun.elevation > 5 && sun.elevation < 20, sun.text);
    await page.screenshot({ path: path.join(artifacts, "sun-paris-winter-afternoon.png"), fullPage: true });
    assert.ok(!(await page.$eval("#orbit-settings", (d) => d.hidden === false)), "the orbit's fields are hidden");
    assert.ok(await page.$eval("#projection", (s) => s.disabled), "a sun is directional");
    await checkCurlGivesTheFrame(page, port);
    // The link opens the same sun.
    const link = await page.context().newPage();
    await link.addInitScript(countRequests);
    await link.goto(page.url());
    await waitForNewImages(link, { frame: "", depth: "" });
    assert.equal(await link.$eval("#light_mode", (s) => s.value), "sun");
    assert.deepEqual(JSON.parse(await link.evaluate(() => window.__umbra.lastRenderBody)), body);
    await link.close();
    // A city preset fills the place; the other side of the date line works too.
    before = await currentSources(page);
    await page.selectOption("#sun_city", { label: "Auckland" });
    await waitForNewImages(page, before);
    body = await lastBody();
    assert.deepEqual([body.light.sun.latitude, body.light.sun.longitude], [-36.8485, 174.7633]);
    // 14:00 UTC is 03:00 in Auckland the next day: night, ambient only.
    await page.waitForFunction(() => /below the horizon/.test(document.getElementById("sun-now").textContent));
    // Play runs the clock at the chosen speed: an hour of sun in a few frames.
    await typeInto(page, "sun_speed", "7200");
    const frames0 = await page.evaluate(() => window.__umbra.frames);
    await page.click("#play");
    await page.waitForFunction((n) => window.__umbra.frames >= n + 3, frames0, { timeout: 60000 });
    await page.click("#play");
    await page.waitForFunction(() => window.__umbra.inFlight === 0, null, { timeout: 60000 });
    body = await lastBody();
    assert.ok(body.time > 100, `the clock ran fast (time ${body.time} s)`);
    assert.equal(body.light.sun.utc, "2026-12-21T14:00:00Z", "Play advances time, not the date and time fields");
    // A latitude past the pole is marked on its field and nothing is sent.
    await typeInto(page, "sun_lat", "95");
    await page.waitForFunction(() => document.getElementById("sun_lat").getAttribute("aria-invalid") === "true");
    const sent = await quietSent(page);
    await page.keyboard.press("Tab");
    await sentStaysAt(page, sent);
    assert.notEqual(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).light.sun.latitude, 95, "95 never sent");
    assert.equal(await page.$eval("#sun_city", (s) => s.value), "", "no city is at latitude 95");
    // Back to the orbit, as the steps after this one expect.
    await typeInto(page, "sun_lat", "48.8566");
    await typeInto(page, "sun_lon", "2.3522");
    await typeInto(page, "sun_speed", "1800");
    before = await currentSources(page);
    await page.selectOption("#light_mode", "orbit");
    await waitForNewImages(page, before);
    // Back on the orbit at the time the sun's Play left: the fields show
    // where the orbiting light is now.
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && !("sun" in JSON.parse(window.__umbra.lastRenderBody).light));
    await checkLightFieldsShowTheOrbit(page);
    await typeInto(page, "time", time0);
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && !("sun" in JSON.parse(window.__umbra.lastRenderBody).light));
    assert.equal(await page.$eval("#sun-now", (p) => p.textContent), "");
  });

  await step(page, "sun-hours-mode-maps-hours-of-direct-sun", async () => {
    await quietSent(page);
    const sent = await page.evaluate(() => window.__umbra.sent);
    const sceneName = await page.$eval("#scene", (s) => s.value);
    await page.selectOption("#mode", "sun-hours");
    assert.ok(await page.$eval("#viewport", (v) => v.getClientRects().length === 0), "the frame is hidden");
    assert.ok(await page.$eval("#sun-hours-settings", (f) => f.getClientRects().length > 0), "the mode's fields are shown");
    await sentStaysAt(page, sent, 500);
    // The page's defaults: this year's 21 March, a day at 10-minute steps,
    // the sun's place, a 20 x 20 grid every 0.25 about the scene's target
    // just above its floor, a 2 h threshold.
    const year = new Date().getFullYear();
    assert.equal(await page.$eval("#sh_date", (i) => i.value), `${year}-03-21`);
    const listed = (await (await fetch(`http://127.0.0.1:${port}/api/scenes`)).json()).scenes.find((s) => s.name === sceneName);
    const floor = Math.min(...listed.objects.filter((o) => o.type === "plane").map((o) => o.center[1]));
    const centre = [listed.camera.target[0], floor + 0.01, listed.camera.target[2]].map((x) => Number(x.toPrecision(6)));
    const fields = await page.evaluate(() => ["sh_cx", "sh_cy", "sh_cz"].map((id) => Number(document.getElementById(id).value)));
    assert.deepEqual(fields, centre, "the grid is centred on the scene's target, 0.01 above its floor");
    assert.match(await page.$eval("#sh-points", (p) => p.textContent), /^80 × 80 = 6,400 points/);
    await page.click("#sh-run");
    await page.waitForSelector("#sh-result:not([hidden])", { timeout: 60000 });
    await page.waitForFunction(() => /^Done/.test(document.getElementById("sh-status").textContent));
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    const body = JSON.parse(await page.evaluate(() => window.__umbra.lastSunHoursBody));
    assert.deepEqual(body, {
      scene: sceneName,
      site: { latitude: 48.8566, longitude: 2.3522 },
      // Paris's mean solar midnight: 9 minutes before UTC's.
      period: { start: `${year}-03-20T23:51:00Z`, end: `${year}-03-21T23:51:00Z`, step_minutes: 10 },
      grid: { center: centre, size: [20, 20], spacing: 0.25 },
      require_hours: 2,
    });
    const answer = await (await fetch(`http://127.0.0.1:${port}/api/sun-hours`, { method: "POST", body: JSON.stringify(body) })).json();
    assert.deepEqual([answer.grid.columns, answer.grid.rows], [80, 80]);
    assert.deepEqual(await page.$eval("#sh-map", (c) => [c.width, c.height]), [480, 480], "6 px a point");
    // The legend: the pass share against the threshold, the place, the period, the path.
    const legend = await page.$eval("#sh-legend", (d) => d.textContent);
    const verdict = answer.pass_share >= 0.5 ? "passes BR 209" : "fails BR 209";
    assert.ok(legend.includes(`${percentText(answer.pass_share)} of points get ≥ 2 h: ${verdict}`), legend);
    assert.match(legend, /48\.8566° N, 2\.3522° E/);
    assert.match(legend, new RegExp(`every 10 min: 144 samples, ${answer.samples_up} with the sun up`));
    assert.ok(legend.includes(`${answer.path}: `) && legend.includes(`(${answer.pairs_ray_cast.toLocaleString("en")}),`), legend);
    assert.match(legend, /12\.17 h \(yellow\)/, "the scale's top is the most hours");
    // The map: the most hours yellow, north (row 0, -Z) on top; a point in
    // the shade reads its own hours under the pointer.
    const max = Math.max(...answer.hours);
    const sunny = answer.hours.indexOf(max);
    assert.deepEqual(await sunHoursPixel(page, answer, sunny), [253, 231, 37], "the most hours are yellow");
    const shaded = answer.hours.findIndex((h) => h > 2.5 && h < max - 1);
    assert.ok(shaded >= 0, "some point is in the shade part of the day");
    const shadedColour = await sunHoursPixel(page, answer, shaded);
    assert.ok(shadedColour[2] > 37 && shadedColour[0] < 253, `a shaded point is not yellow (${shadedColour})`);
    await page.mouse.move(...(await sunHoursCell(page, answer, shaded)));
    const x = answer.grid.origin[0] + (shaded % 80) * 0.25, z = answer.grid.origin[2] + Math.floor(shaded / 80) * 0.25;
    await page.waitForFunction((i) => document.getElementById("sh-readout").dataset.index === String(i), shaded);
    const readout = await page.$eval("#sh-readout", (p) => p.textContent);
    assert.ok(readout.startsWith(`x ${Number(x.toPrecision(6))}, z ${Number(z.toPrecision(6))} (column ${shaded % 80}, row ${Math.floor(shaded / 80)}): ` +
                                 `${hoursText(answer.hours[shaded])} h of sun`), readout);
    assert.ok(readout.includes(`longest run ${hoursText(answer.longest_run_hours[shaded])} h — reaches 2 h`), readout);
    // Under the threshold: hatched, and said so.
    const short = answer.hours.findIndex((h) => h < 2);
    if (short >= 0) {
      await page.mouse.move(...(await sunHoursCell(page, answer, short)));
      await page.waitForFunction(() => / — under 2 h$/.test(document.getElementById("sh-readout").textContent));
    }
    // With the map focused, the arrow keys move from point to point.
    await page.focus("#sh-map");
    await page.keyboard.press("ArrowRight");
    const last = short >= 0 ? short : shaded;
    assert.equal(Number(await page.$eval("#sh-readout", (p) => p.dataset.index)), last + 1, "the arrow key moved one point east");
    assert.ok(await page.$eval("#sh-cursor", (c) => !c.hidden), "the point is boxed on the map");
    await page.screenshot({ path: path.join(artifacts, "sun-hours-map.png"), fullPage: true });
    // The map with its legend as one PNG.
    const [png] = await Promise.all([page.waitForEvent("download", { timeout: 60000 }), page.click("#sh-png")]);
    const pngBytes = fs.readFileSync(await png.path());
    assert.ok(pngBytes.subarray(0, 8).equals(Buffer.from("\x89PNG\r\n\x1a\n", "latin1")), "a PNG");
    assert.ok(pngBytes.readUInt32BE(16) > 480 && pngBytes.readUInt32BE(20) > 480, "the map and more");
    // The CSV is the server's for the same body.
    const csv = await downloadedCsv(page);
    assert.equal(csv[0], "x,y,z,hours,longest_run_hours");
    assert.equal(csv.length, 6401);
    assert.equal(Number(csv[1 + shaded].split(",")[3]), answer.hours[shaded]);
    // "Copy as curl" gives the analysis.
    await page.click("#copy-curl");
    const command = await page.$eval("#curl", (p) => p.textContent);
    assert.ok(command.startsWith(`curl -X POST 'http://127.0.0.1:${port}/api/sun-hours' -H 'Content-Type: application/json' -d '${JSON.stringify(body)}'`), command);
    // A step the day does not divide into: the server's 400 names the field, which is marked.
    await typeInto(page, "sh_step", "7");
    await page.click("#sh-run");
    await page.waitForFunction(() => !document.getElementById("error").hidden, null, { timeout: 60000 });
    assert.match(await page.$eval("#error", (e) => e.textContent), /^Sun hours not computed \(400\): period\.step_minutes: .*whole number of steps of 7 minutes/);
    assert.equal(await page.$eval("#sh_step", (i) => i.getAttribute("aria-invalid")), "true");
    assert.match(await page.$eval("#sh_step-problem", (p) => p.textContent), /^Step \(minutes\): .*7 minutes \(the server's answer\)/);
    // A value the field cannot take is marked and nothing is sent.
    await typeInto(page, "sh_spacing", "-1");
    const before = await page.evaluate(() => window.__umbra.sent);
    await page.click("#sh-run");
    assert.match(await page.$eval("#sh_spacing-problem", (p) => p.textContent), /^Grid spacing: at least/);
    assert.match(await page.$eval("#sh-status", (p) => p.textContent), /^Not run: .*Grid spacing/);
    await sentStaysAt(page, before, 300);
    await typeInto(page, "sh_spacing", "0.25");
    await typeInto(page, "sh_step", "10");
    assert.equal(await page.$eval("#sh_step", (i) => i.getAttribute("aria-invalid")), null, "fixed: no longer marked");
    await page.click("#sh-run");
    await page.waitForFunction(() => /^Done/.test(document.getElementById("sh-status").textContent), null, { timeout: 60000 });
    assert.ok(await page.$eval("#error", (e) => e.hidden), "the error goes with the next result");
    assert.equal(new URL(page.url()).searchParams.get("mode"), "sun-hours");
    // Back to frames: as it was, nothing of the mode left in the address.
    await page.selectOption("#mode", "render");
    await page.waitForFunction(() => window.__umbra.inFlight === 0);
    assert.ok(await page.$eval("#viewport", (v) => v.getClientRects().length > 0), "the frame is shown again");
    assert.ok(!new URL(page.url()).searchParams.has("mode"));
    assert.ok(![...new URL(page.url()).searchParams.keys()].some((k) => k.startsWith("sh_")), page.url());
  });

  await step(page, "sun-hours-jobs-show-progress-cancel-and-complete", async () => {
    // A server whose budget a request is 1 ms: every analysis is a job.
    jobServer = startServer(serverBinary, ["--max-request-ms", "1"]);
    const jobsPort = await jobServer.port;
    const jobs = await page.context().newPage();
    const calls = [];
    jobs.on("request", (r) => { if (new URL(r.url()).pathname.startsWith("/api/sun-hours")) calls.push(`${r.method()} ${new URL(r.url()).pathname}`); });
    try {
      // A year over the teapot, a point every 4 cm: long enough (seconds even on
      // many cores) to watch and cancel.
      await jobs.goto(`http://127.0.0.1:${jobsPort}/?mode=sun-hours&scene=teapot&sh_days=365&sh_spacing=0.04`);
      await jobs.waitForFunction(() => document.body.classList.contains("sun-hours-mode") && document.getElementById("sh_cx").value !== "");
      await jobs.click("#sh-run");
      await jobs.waitForFunction(() => document.getElementById("sh-progress").dataset.state === "running" &&
                                       / left/.test(document.getElementById("sh-progress-text").textContent), null, { timeout: 60000 });
      const progress = await jobs.$eval("#sh-progress-text", (p) => p.textContent);
      assert.match(progress, /^Job running: \d+ % done · about [\d.]+ (ms|s|min \d+ s|h \d+ min) left · [\d.]+ [kMG]? ?point-samples\/s$/);
      assert.ok(await jobs.$eval("#sh-progress-bar", (b) => b.value > 0 && b.value < 1), "the bar shows the share done");
      assert.ok(await jobs.$eval("#sh-run", (b) => b.disabled), "one run at a time");
      await jobs.screenshot({ path: path.join(artifacts, "sun-hours-job-running.png"), fullPage: true });
      const location = await jobs.$eval("#sh-progress", (d) => d.dataset.location);
      assert.match(location, /^\/api\/sun-hours\/jobs\/[\w.-]+$/);
      await jobs.click("#sh-cancel");
      await jobs.waitForFunction(() => /^Cancelled: the job was deleted/.test(document.getElementById("sh-status").textContent));
      assert.ok(await jobs.$eval("#sh-progress", (d) => d.hidden), "the bar goes");
      assert.ok(calls.includes(`DELETE ${location}`), calls.join(", "));
      assert.ok(calls.filter((c) => c === `GET ${location}`).length >= 1, "its progress was read from its location");
      assert.equal((await fetch(`http://127.0.0.1:${jobsPort}${location}`)).status, 404, "the job is gone from the server");
      // A week over the default scene: a short job, followed to its result.
      await jobs.goto(`http://127.0.0.1:${jobsPort}/?mode=sun-hours&sh_days=7`);
      await jobs.waitForFunction(() => document.body.classList.contains("sun-hours-mode") && document.getElementById("sh_cx").value !== "");
      await jobs.evaluate(recordProgress);
      calls.length = 0;
      await jobs.click("#sh-run");
      await jobs.waitForFunction(() => /^Done/.test(document.getElementById("sh-status").textContent), null, { timeout: 120000 });
      assert.match(await jobs.$eval("#sh-status", (p) => p.textContent), /as a job/);
      const states = await jobs.evaluate(() => window.__progress);
      assert.ok(states.some((s) => /^(queued|running): Job /.test(s)), `the job's progress was shown: ${states.join(" | ")}`);
      assert.ok(await jobs.$eval("#sh-progress", (d) => d.hidden), "the bar goes once done");
      assert.match(calls[0], /^POST \/api\/sun-hours$/);
      assert.ok(calls.slice(1).every((c) => /^GET \/api\/sun-hours\/jobs\//.test(c)) && calls.length >= 2, calls.join(", "));
      const legend = await jobs.$eval("#sh-legend", (d) => d.textContent);
      assert.match(legend, /[\d.]+ % of points get ≥ 2 h: (at least|under) half the area/, "7 days: not BR 209's test");
      assert.match(legend, /7 days of mean solar time/);
      assert.ok(await jobs.$eval("#error", (e) => e.hidden), "no error shown");
      // The CSV comes from the job's result, not a new analysis.
      calls.length = 0;
      const csv = await downloadedCsv(jobs);
      assert.equal(csv.length, 6401);
      assert.equal(calls.length, 1, calls.join(", "));
      assert.match(calls[0], /^GET \/api\/sun-hours\/jobs\//);
      await jobs.screenshot({ path: path.join(artifacts, "sun-hours-job-done.png"), fullPage: true });
    } finally {
      await jobs.close();
      jobServer.child.kill("SIGTERM");
      await jobServer.exited;
    }
  });

  await step(page, "resolution-and-depth-map-at-a-lower-rate-while-playing", async () => {
    let before = await currentSources(page);
    await page.selectOption("#resolution", "480x270");
    await waitForNewImages(page, before);
    const small = await imageStats(page, "frame");
    assert.deepEqual([small.width, small.height], [480, 270]);
    assert.equal(new URL(page.url()).searchParams.get("resolution"), "480x270");
    const counts0 = await page.evaluate(() => ({ frames: window.__umbra.frames, depth: window.__umbra.depthSent }));
    await page.click("#play");
    await page.waitForFunction((n) => window.__umbra.frames >= n + 6, counts0.frames, { timeout: 60000 });
    await page.click("#play");
    await page.waitForFunction(() => window.__umbra.inFlight === 0, null, { timeout: 60000 });
    const counts1 = await page.evaluate(() => ({ frames: window.__umbra.frames, depth: window.__umbra.depthSent }));
    assert.ok(counts1.depth - counts0.depth < counts1.frames - counts0.frames,
              `fewer depth maps (${counts1.depth - counts0.depth}) than frames (${counts1.frames - counts0.frames}) while playing`);
    // Paused, the depth map is the last frame's.
    await page.waitForFunction(() => window.__umbra.inFlight === 0 && document.getElementById("depth").complete);
    before = await currentSources(page);
    await page.selectOption("#resolution", "960x540");
    await waitForNewImages(page, before);
  });

  await step(page, "keyboard-and-labels", async () => {
    const unlabelled = await page.$$eval("#controls input, #controls select, button", (elements) =>
      elements.filter((e) => !(e.labels && e.labels.length) && !e.getAttribute("aria-label") && !e.textContent.trim())
              .map((e) => e.id));
    assert.deepEqual(unlabelled, [], "every control has a label");
    await page.focus("#time");
    await page.keyboard.press("Shift+Tab");
    assert.equal(await page.evaluate(() => document.activeElement.id), "play", "Play is reached with the keyboard");
    await page.keyboard.press("Space");
    assert.equal(await page.$eval("#play", (b) => b.getAttribute("aria-pressed")), "true");
    await page.keyboard.press("Space");
    assert.equal(await page.$eval("#play", (b) => b.getAttribute("aria-pressed")), "false");
    await page.waitForFunction(() => window.__umbra.inFlight === 0, null, { timeout: 60000 });
  });

  await step(page, "scene-list-is-the-servers", async () => {
    const listed = (await (await fetch(`http://127.0.0.1:${port}/api/scenes`)).json()).scenes.map((s) => s.name);
    assert.deepEqual(listed, ["cube-on-plane", "three-cubes", "teapot", "torus-knot"]);
    const offered = await page.$$eval("#scene > option", (options) => options.map((o) => o.value));
    assert.deepEqual(offered, listed, "the scene list holds the server's scenes");
    const models = await page.$$eval("#scene optgroup[label=Models] option", (options) => options.map((o) => o.value));
    assert.ok(models.includes("model:teapot") && models.includes("model:torus-knot"), `built-in models offered: ${models}`);
    const before = await currentSources(page);
    await page.selectOption("#scene", "teapot");
    await waitForNewImages(page, before);
    assert.equal(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).scene, "teapot");
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    assert.equal(new URL(page.url()).searchParams.get("scene"), "teapot");
  });

  await step(page, "scene-editor-loads-edits-and-renders", async () => {
    let before = await currentSources(page);
    await page.selectOption("#scene", "three-cubes");
    await waitForNewImages(page, before);
    const listed = (await (await fetch(`http://127.0.0.1:${port}/api/scenes`)).json()).scenes.find((s) => s.name === "three-cubes");
    await page.click("#load-scene");
    const loaded = JSON.parse(await page.$eval("#scene-json", (t) => t.value));
    assert.deepEqual(loaded.scene.objects, listed.objects, "the editor holds three-cubes' objects");
    const original = await imageStats(page, "frame");
    // Move the big red-brown cube and make it near black (under the red light set earlier).
    loaded.scene.objects[1].center[0] += 1;
    loaded.scene.objects[1].color = [0.05, 0.05, 0.05];
    await page.fill("#scene-json", JSON.stringify(loaded, null, 2));
    before = await currentSources(page);
    await page.click("#render-json");
    await waitForNewImages(page, before);
    const body = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    assert.deepEqual(body.scene.objects, loaded.scene.objects, "the request carries the edited objects");
    assert.deepEqual(body.light.position, loaded.light.position);
    assert.equal(body.light.color, await page.$eval("#color", (c) => c.value), "the form's other light fields stay");
    const edited = await imageStats(page, "frame");
    assert.notEqual(edited.digest, original.digest, "the frame changed");
    assert.ok(edited.r < original.r, `darker (red ${original.r.toFixed(1)} -> ${edited.r.toFixed(1)})`);
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    await checkCurlGivesTheFrame(page, port);
    // The address keeps it (short enough), and opens the same request.
    const url = new URL(page.url());
    assert.deepEqual(JSON.parse(url.searchParams.get("scene_json")), loaded);
    const other = await page.context().newPage();
    await other.addInitScript(countRequests);
    await other.goto(url.href);
    await waitForNewImages(other, { frame: "", depth: "" });
    assert.deepEqual(JSON.parse(await other.evaluate(() => window.__umbra.lastRenderBody)), body);
    await other.close();
    // The object types come from the served document: every one is listed,
    // and a cylinder (the newest) renders from the editor.
    const served = await (await fetch(`http://127.0.0.1:${port}/api/openapi.json`)).json();
    const types = Object.keys(served.components.schemas.SceneObject.discriminator.mapping);
    assert.ok(types.includes("cylinder"), "the document has the cylinder");
    const hint = await page.$eval("#object-types", (p) => p.textContent);
    for (const type of types) assert.ok(hint.includes(`${type} (`), `the editor lists ${type}: ${hint}`);
    assert.match(hint, /cylinder \(center, radius, height, color\)/);
    const columns = { scene: { objects: [{ type: "plane" }, { type: "cylinder", center: [0, 1, 0], radius: 0.3, height: 2 }] } };
    await page.fill("#scene-json", JSON.stringify(columns));
    before = await currentSources(page);
    await page.click("#render-json");
    await waitForNewImages(page, before);
    assert.deepEqual(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).scene, columns.scene);
    assert.ok(await page.$eval("#error", (e) => e.hidden), "the cylinder renders: no error shown");
    // Bad JSON is marked and nothing is sent.
    await page.waitForFunction(() => window.__umbra.inFlight === 0);
    const sent = await page.evaluate(() => window.__umbra.sent);
    await page.fill("#scene-json", '{"scene": {"objects": [}');
    await page.click("#render-json");
    assert.equal(await page.$eval("#scene-json", (t) => t.getAttribute("aria-invalid")), "true");
    assert.match(await page.$eval("#scene-json-problem", (p) => p.textContent), /^Scene JSON: not valid JSON: .+Nothing is sent/);
    await sentStaysAt(page, sent);
    await page.screenshot({ path: path.join(artifacts, "scene-editor-bad-json.png"), fullPage: true });
    // A server 400 names its field; the last good frame stays.
    const frameSrc = await page.$eval("#frame", (img) => img.src);
    await page.fill("#scene-json", '{"scene": {"objects": [{"type": "box", "size": [-1, 1, 1]}]}}');
    assert.equal(await page.$eval("#scene-json", (t) => t.getAttribute("aria-invalid")), null, "fixed: no longer marked");
    await page.click("#render-json");
    await page.waitForFunction(() => !document.getElementById("error").hidden, null, { timeout: 60000 });
    assert.match(await page.$eval("#error", (e) => e.textContent), /\(400\): scene\.objects\[0\]\.size/);
    assert.match(await page.$eval("#scene-json-status", (p) => p.textContent), /scene\.objects\[0\]\.size/);
    assert.equal(await page.$eval("#frame", (img) => img.src), frameSrc);
    // Choosing a scene goes back to the form's.
    before = await currentSources(page);
    await page.selectOption("#scene", "teapot");
    await waitForNewImages(page, before);
    assert.equal(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).scene, "teapot");
    assert.ok(!new URL(page.url()).searchParams.has("scene_json"));
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
  });

  const box = boxGlb();
  const boxId = "sha256:" + createHash("sha256").update(box).digest("hex");
  let boxFrame;
  await step(page, "upload-a-glb-and-render-it", async () => {
    const teapot = await imageStats(page, "frame");
    const before = await currentSources(page);
    await chooseFile(page, "box.glb", box);
    await page.waitForFunction((value) => document.getElementById("scene").value === value, `model:${boxId}`,
                               { timeout: 60000 });
    await waitForNewImages(page, before);
    const option = await page.$eval("#scene", (s) => s.selectedOptions[0].textContent);
    assert.equal(option, "model: box.glb (12 triangles)");
    assert.match(await page.$eval("#model-status", (p) => p.textContent), /box\.glb: 12 triangles, closed/);
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    // The model on a floor, nothing the server reports as unused.
    const body = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    assert.deepEqual(body.scene.objects.map((o) => o.type), ["plane", "mesh"]);
    assert.equal(body.scene.objects[1].model, boxId);
    assert.doesNotMatch(await page.$eval("#timing", (p) => p.textContent), /unused/);
    assert.equal(new URL(page.url()).searchParams.get("model"), boxId);
    assert.ok(!new URL(page.url()).searchParams.has("scene"), "a model replaces the scene in the link");
    boxFrame = await imageStats(page, "frame");
    assert.notEqual(boxFrame.digest, teapot.digest, "the frame changed");
    await checkCurlGivesTheFrame(page, port);
  });

  await step(page, "refused-uploads-show-the-servers-message", async () => {
    const frameSrc = await page.$eval("#frame", (img) => img.src);
    await chooseFile(page, "broken.glb", Buffer.from("not a glb"));
    await page.waitForFunction(() => !document.getElementById("error").hidden, null, { timeout: 60000 });
    assert.match(await page.$eval("#error", (e) => e.textContent),
                 /^broken\.glb was not loaded \(400\): not a glTF binary \(\.glb\): it does not start with "glTF"/);
    assert.match(await page.$eval("#model-status", (p) => p.textContent), /broken\.glb: not loaded/);
    // Dropped on the page: valid glTF, but lines, not triangles (422).
    await dropFile(page, "lines.glb", boxGlb(1));
    await page.waitForFunction(() => /lines\.glb/.test(document.getElementById("error").textContent), null,
                               { timeout: 60000 });
    assert.match(await page.$eval("#error", (e) => e.textContent),
                 /^lines\.glb was not loaded \(422\): the model has no triangles .*1 primitives of points or lines were left out/);
    // The box stays chosen and shown.
    assert.equal(await page.$eval("#scene", (s) => s.value), `model:${boxId}`);
    assert.equal(await page.$eval("#frame", (img) => img.src), frameSrc);
  });

  await step(page, "an-obj-is-converted-by-the-server", async () => {
    // A cube as SketchUp or Blender writes OBJ: eight vertices, six quads.
    const cube = ["v -1 0 -1", "v 1 0 -1", "v 1 2 -1", "v -1 2 -1", "v -1 0 1", "v 1 0 1", "v 1 2 1", "v -1 2 1",
                  "f 1 4 3 2", "f 5 6 7 8", "f 1 2 6 5", "f 2 3 7 6", "f 3 4 8 7", "f 4 1 5 8"].join("\n") + "\n";
    await chooseFile(page, "cube.obj", Buffer.from(cube));
    await page.waitForFunction(() => /cube\.obj: 12 triangles/.test(document.getElementById("model-status").textContent),
                               null, { timeout: 60000 });
    assert.match(await page.$eval("#scene", (s) => s.selectedOptions[0].textContent), /^model: cube\.obj \(12 triangles\)$/);
    // Back to the box for the steps that follow.
    const before = await currentSources(page);
    await page.selectOption("#scene", `model:${boxId}`);
    await waitForNewImages(page, before);
  });

  await step(page, "an-animated-model-plays", async () => {
    // The glTF tutorial's skin (Debian's assimp-testmodels): one animation,
    // its upper joint swinging a quarter turn either way over 5.5 s.
    const time0 = await page.$eval("#time", (i) => i.value);
    const skin = fs.readFileSync("/usr/share/assimp/models/glTF2/simple_skin/simple_skin.gltf");
    await chooseFile(page, "simple_skin.gltf", skin);
    await page.waitForFunction(() => /simple_skin\.gltf: .*1 animation/.test(document.getElementById("model-status").textContent),
                               null, { timeout: 60000 });
    assert.ok(!(await page.$eval("#animation-row", (d) => d.hidden)), "the Animation list is shown");
    assert.deepEqual(await page.$$eval("#animation option", (os) => os.map((o) => o.textContent)),
                     ["none: the rest pose", "animation 0 (5.5 s)"]);
    // At time 1 the joint has turned +90 degrees: the frame with the
    // animation is not the rest pose's.
    let before = await currentSources(page);
    await page.fill("#time", "1");
    await page.dispatchEvent("#time", "input");
    await waitForNewImages(page, before);
    const rest = await imageStats(page, "frame");
    before = await currentSources(page);
    await page.selectOption("#animation", "0");
    await waitForNewImages(page, before);
    const body = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    assert.equal(body.scene.objects[1].animation, 0);
    assert.equal(body.time, 1);
    assert.equal(new URL(page.url()).searchParams.get("animation"), "0");
    assert.notEqual((await imageStats(page, "frame")).digest, rest.digest, "the model is posed");
    assert.ok(await page.$eval("#error", (e) => e.hidden), "no error shown");
    // Play runs the time on: frames keep the animation.
    await page.click("#play");
    await page.waitForFunction(() => Number(document.getElementById("time").value) > 1.2, null, { timeout: 60000 });
    await page.click("#play");
    assert.equal(JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).scene.objects[1].animation, 0);
    // Back to the box (no animations: the list hides) at the time before.
    before = await currentSources(page);
    await page.selectOption("#scene", `model:${boxId}`);
    await page.fill("#time", time0);
    await page.dispatchEvent("#time", "input");
    await waitForNewImages(page, before);
    assert.ok(await page.$eval("#animation-row", (d) => d.hidden), "the Animation list is hidden for the box");
    assert.ok(!("animation" in JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody)).scene.objects[1]));
  });

  await step(page, "model-link-chooses-the-model", async () => {
    const body = JSON.parse(await page.evaluate(() => window.__umbra.lastRenderBody));
    const other = await page.context().newPage();
    await other.addInitScript(countRequests);
    await other.goto(page.url());
    await waitForNewImages(other, { frame: "", depth: "" });
    assert.equal(await other.$eval("#scene", (s) => s.value), `model:${boxId}`);
    assert.equal(await other.$eval("#scene", (s) => s.selectedOptions[0].textContent), "model: box.glb (12 triangles)");
    assert.deepEqual(JSON.parse(await other.evaluate(() => window.__umbra.lastRenderBody)), body);
    assert.equal((await imageStats(other, "frame")).digest, boxFrame.digest, "the same frame");
    await other.screenshot({ path: path.join(artifacts, "model-link-opened.png"), fullPage: true });
    await other.close();
    // A model the server does not hold: its 400, naming the field.
    const gone = await page.context().newPage();
    await gone.goto(`http://127.0.0.1:${port}/?model=sha256:${"0".repeat(64)}`);
    await gone.waitForFunction(() => !document.getElementById("error").hidden, null, { timeout: 60000 });
    assert.match(await gone.$eval("#error", (e) => e.textContent), /\(400\): scene\.objects\[0\]\.model: unknown model/);
    await gone.screenshot({ path: path.join(artifacts, "model-link-unknown.png"), fullPage: true });
    await gone.close();
  });

  await step(page, "server-error-is-a-readable-message", async () => {
    // A bad value first: the server's 400 names the field.
    await page.$eval("#lx", (input) => {
      input.value = "1e9";
      input.dispatchEvent(new Event("input", { bubbles: true }));
    });
    await page.waitForFunction(() => !document.getElementById("error").hidden, null, { timeout: 60000 });
    assert.match(await page.$eval("#error", (e) => e.textContent), /light\.position/, "the message names the field");
    // Then the server goes away.
    server.child.kill("SIGTERM");
    await server.exited;
    await page.$eval("#lx", (input) => {
      input.value = "-2";
      input.dispatchEvent(new Event("input", { bubbles: true }));
    });
    await page.waitForFunction(() => /unreachable/.test(document.getElementById("error").textContent), null,
                               { timeout: 60000 });
    const frame = await imageStats(page, "frame");
    assert.equal(frame.width, 960, "the last good frame stays, not a broken image");
  });

  // A server run with --tokens answers 401 to the panel's calls: the panel
  // asks for a token, sends it on every call, and renders.
  const token = "panel-test-token-0123456789";
  const tokens = path.join(os.tmpdir(), `umbra-panel-tokens-${process.pid}`);
  fs.writeFileSync(tokens, `${token} render,upload\n`);
  guarded = startServer(serverBinary, ["--tokens", tokens]);
  const guardedPort = await guarded.port;
  fs.rmSync(tokens, { force: true });
  const locked = await page.context().newPage();
  await locked.addInitScript(countRequests);
  const sentAuthorizations = new Set();
  locked.on("request", (r) => { if (new URL(r.url()).pathname.startsWith("/api/")) sentAuthorizations.add(r.headers().authorization || "none"); });

  await step(locked, "a-server-with-tokens-asks-for-one", async () => {
    await locked.goto(`http://127.0.0.1:${guardedPort}/`);
    await locked.waitForSelector("#auth:not([hidden])", { timeout: 60000 });
    assert.match(await locked.$eval("#auth-reason", (p) => p.textContent), /needs an access token \(401\)/);
    assert.equal(await locked.$eval("#token", (i) => i.type), "password", "the token is typed into a password field");
    assert.equal(await locked.$eval("label[for=token]", (l) => l.textContent.length > 0), true, "the field is labelled");
    // A wrong one is refused and asked again.
    await locked.fill("#token", "not-the-token-0123456789");
    await locked.click("#use-token");
    await locked.waitForFunction(() => /did not accept/.test(document.getElementById("auth-reason").textContent) &&
                                       !document.getElementById("auth").hidden, null, { timeout: 60000 });
    await locked.fill("#token", token);
    await locked.click("#use-token");
    await waitForNewImages(locked, { frame: "", depth: "" });
    assert.ok(await locked.$eval("#auth", (f) => f.hidden), "the field is gone once the token works");
    assert.ok(await locked.$eval("#error", (e) => e.hidden), "no error shown");
    assert.ok(sentAuthorizations.has(`Bearer ${token}`), "the token went as a bearer token");
    // The lists came with it: the server's scenes and models.
    assert.ok(await locked.$eval("#scene", (s) => Array.from(s.options).some((o) => o.value === "teapot")),
              "the server's scene list was loaded with the token");
    assert.equal(await locked.evaluate(() => sessionStorage.getItem("umbra.token")), token, "kept for this tab");
    // Copy as curl leaves the token out of the page.
    await locked.click("#copy-curl");
    assert.match(await locked.$eval("#curl", (p) => p.textContent), /Authorization: Bearer \$UMBRA_TOKEN/);
    assert.ok(!(await locked.$eval("#curl", (p) => p.textContent)).includes(token), "the token is not shown");
  });

  await step(locked, "a-reload-keeps-the-token-and-uploads-send-it", async () => {
    sentAuthorizations.clear();
    await locked.reload();
    await waitForNewImages(locked, { frame: "", depth: "" });
    assert.ok(await locked.$eval("#auth", (f) => f.hidden), "not asked again in the same tab");
    const before = await currentSources(locked);
    await chooseFile(locked, "box.glb", box);
    await locked.waitForFunction((value) => document.getElementById("scene").value === value, `model:${boxId}`,
                                 { timeout: 60000 });
    await waitForNewImages(locked, before);
    assert.deepEqual([...sentAuthorizations], [`Bearer ${token}`], "every API call carried the token");
  });
} catch (error) {
  failed = true;
  console.error(`not ok ${stepNumber + 1} - ${error.message}`);
  if (error.stack) console.error(error.stack);
  console.error("server log:\n" + server.log());
} finally {
  await browser.close();
  if (server.child.exitCode === null) server.child.kill("SIGKILL");
  if (guarded && guarded.child.exitCode === null) guarded.child.kill("SIGKILL");
  if (jobServer && jobServer.child.exitCode === null) jobServer.child.kill("SIGKILL");
}
console.log(`screenshots in ${artifacts}`);
process.exit(failed ? 1 : 0);
