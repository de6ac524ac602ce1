// docs/openapi.json against itself and against the real server.
//
//   node tests/e2e/openapi.test.mjs SERVER_BINARY OPENAPI_JSON
//
// 1. The document is valid OpenAPI 3.1 (@apidevtools/swagger-parser, pinned
//    in package-lock.json), and every request example but those of a
//    refusal is valid against its own request schema (ajv, JSON Schema
//    2020-12).
// 2. umbra-server (started here on a free port) serves it byte for byte at
//    GET /api/openapi.json.
// 3. Every documented GET route answers with a documented status and content
//    type, its JSON valid against the documented schema; a path parameter's
//    examples are each tried.
// 4. Every example request body renders (200 image/png, with the documented
//    required headers) at the path it is documented for, unless a response
//    of that operation holds an example of the same name: then the server
//    answers that status with exactly that JSON.
// 5. With --tokens, every operation that lists the bearer scheme answers
//    401 (with WWW-Authenticate) without a token and 403 with a token of
//    another scope, as documented, and the others need none.
// Exits non-zero, naming the check, at the first failure.
import assert from "node:assert/strict";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import SwaggerParser from "@apidevtools/swagger-parser";
import Ajv2020 from "ajv/dist/2020.js";
import { startServer } from "./server.mjs";

const [serverBinary, documentPath] = process.argv.slice(2);
if (!serverBinary || !documentPath) {
  console.error("usage: node openapi.test.mjs SERVER_BINARY OPENAPI_JSON");
  process.exit(2);
}
const documentBytes = fs.readFileSync(documentPath);
let checks = 0;

function step(name, fn) {
  return fn().then(
    () => console.log(`ok: ${name}`),
    (e) => {
      e.message = `${name}: ${e.message}`;
      throw e;
    },
  );
}

// --- The document ------------------------------------------------------------

// validate() dereferences what it is given: each call gets its own copy.
const fresh = () => JSON.parse(documentBytes.toString("utf8"));
let api; // dereferenced: every $ref replaced by what it points at

const ajv = new Ajv2020({ strict: false, allErrors: true });
ajv.addKeyword("discriminator"); // OpenAPI's own keyword, not JSON Schema's
const validators = new Map();
function validate(schema, value, what) {
  if (!validators.has(schema)) validators.set(schema, ajv.compile(schema));
  const check = validators.get(schema);
  assert.ok(check(value), `${what} does not match its schema: ${ajv.errorsText(check.errors)}\n${JSON.stringify(value)}`);
  checks += 1;
}

let base;
async function request(method, path, body, contentType, token) {
  const init = { method, headers: {} };
  if (token) init.headers.Authorization = `Bearer ${token}`;
  if (body !== undefined) {
    init.body = body;
    init.headers["Content-Type"] = contentType;
  }
  const res = await fetch(base + path, init);
  const bytes = Buffer.from(await res.arrayBuffer());
  return { status: res.status, headers: res.headers, bytes };
}

const mediaType = (res) => (res.headers.get("content-type") || "").split(";")[0].trim();

// The documented response for `status`, or the "default" one.
function documented(operation, status, what) {
  const response = operation.responses[String(status)] ?? operation.responses.default;
  assert.ok(response, `${what} answered ${status}, which the document does not list for it`);
  return response;
}

// Checks an answer against its documented response: status, content type,
// required headers, and JSON against its schema.
function checkAnswer(operation, res, what) {
  const response = documented(operation, res.status, what);
  const type = mediaType(res);
  if (response.content) {
    const media = response.content[type];
    assert.ok(media, `${what} answered ${res.status} as ${type}; documented: ${Object.keys(response.content).join(", ")}`);
    if (type === "application/json" && media.schema) {
      validate(media.schema, JSON.parse(res.bytes.toString("utf8")), `${what} (${res.status})`);
    }
  }
  for (const [name, header] of Object.entries(response.headers ?? {})) {
    if (header.required) assert.ok(res.headers.has(name), `${what} answered ${res.status} without ${name}`);
    if (res.headers.has(name) && header.schema) validate(header.schema, res.headers.get(name), `${what}'s ${name}`);
  }
  checks += 1;
  return response;
}

// The response that holds an example named `name`: [status, example value].
function responseExample(operation, name) {
  for (const [status, response] of Object.entries(operation.responses)) {
    for (const media of Object.values(response.content ?? {})) {
      if (media.examples && name in media.examples) return [Number(status), media.examples[name].value];
    }
  }
  return null;
}

// A path with its parameters filled from a name -> value map.
const fill = (path, values) => path.replace(/\{([^}]+)\}/g, (_, name) => encodeURIComponent(values[name]));

async function main() {
  await step("the document is valid OpenAPI 3.1", async () => {
    const validated = await SwaggerParser.validate(fresh());
    assert.equal(validated.openapi.slice(0, 4), "3.1.");
    api = await SwaggerParser.dereference(fresh());
  });

  await step("every request example matches its request schema", async () => {
    for (const [path, item] of Object.entries(api.paths)) {
      for (const [method, operation] of Object.entries(item)) {
        for (const [type, media] of Object.entries(operation.requestBody?.content ?? {})) {
          for (const [name, example] of Object.entries(media.examples ?? {})) {
            // An example of a refusal may break the schema on purpose.
            const refused = responseExample(operation, name)?.[0] >= 400;
            if (!refused) validate(media.schema, example.value, `${method.toUpperCase()} ${path} example "${name}" (${type})`);
          }
        }
      }
    }
  });

  const server = startServer(serverBinary);
  try {
    base = `http://127.0.0.1:${await server.port}`;

    await step("GET /api/openapi.json is docs/openapi.json byte for byte", async () => {
      const res = await request("GET", "/api/openapi.json");
      assert.equal(res.status, 200);
      assert.equal(mediaType(res), "application/json");
      assert.ok(res.bytes.equals(documentBytes), "the served document differs from the repository's file");
    });

    await step("every documented GET route answers as documented", async () => {
      let routes = 0;
      for (const [path, item] of Object.entries(api.paths)) {
        const operation = item.get;
        if (!operation) continue;
        const params = (operation.parameters ?? []).filter((p) => p.in === "path");
        // Every combination is not needed: each example of each parameter.
        const cases = params.length === 0 ? [["", {}]] : [];
        for (const p of params) {
          assert.ok(p.examples, `GET ${path}: path parameter ${p.name} has no examples to try`);
          for (const [name, example] of Object.entries(p.examples)) cases.push([name, { [p.name]: example.value }]);
        }
        for (const [name, values] of cases) {
          const target = fill(path, values);
          const what = `GET ${target}`;
          const res = await request("GET", target);
          checkAnswer(operation, res, what);
          const expected = name && responseExample(operation, name);
          if (expected) {
            assert.equal(res.status, expected[0], `${what}: documented as ${expected[0]}`);
            assert.deepEqual(JSON.parse(res.bytes.toString("utf8")), expected[1], `${what}: not the documented answer`);
          } else {
            assert.ok(res.status >= 200 && res.status < 300, `${what} answered ${res.status}: ${res.bytes.toString().slice(0, 300)}`);
          }
          routes += 1;
        }
      }
      assert.ok(routes >= 8, `only ${routes} GET requests made`);
    });

    await step("every example request answers as documented", async () => {
      let renders = 0, refusals = 0;
      for (const [path, item] of Object.entries(api.paths)) {
        for (const [method, operation] of Object.entries(item)) {
          for (const [type, media] of Object.entries(operation.requestBody?.content ?? {})) {
            for (const [name, example] of Object.entries(media.examples ?? {})) {
              const what = `${method.toUpperCase()} ${path} example "${name}"`;
              const res = await request(method.toUpperCase(), path, JSON.stringify(example.value), type);
              checkAnswer(operation, res, what);
              const expected = responseExample(operation, name);
              if (expected) {
                const [status, value] = expected;
                assert.equal(res.status, status, `${what}: ${res.bytes.toString().slice(0, 300)}`);
                assert.deepEqual(JSON.parse(res.bytes.toString("utf8")), value, `${what}: not the documented answer`);
                if (status >= 400) refusals += 1;
                else renders += 1;
              } else {
                assert.equal(res.status, 200, `${what}: ${res.bytes.toString().slice(0, 300)}`);
                assert.equal(mediaType(res), "image/png", `${what}: not a PNG`);
                assert.ok(res.bytes.subarray(0, 8).equals(Buffer.from("\x89PNG\r\n\x1a\n", "latin1")), `${what}: not a PNG`);
                renders += 1;
              }
            }
          }
        }
      }
      assert.ok(renders >= 10 && refusals >= 5, `only ${renders} renders and ${refusals} refusals tried`);
    });

    await step("a route the document does not list is 404, as documented for unknown paths", async () => {
      const res = await request("GET", "/api/not-a-route");
      assert.equal(res.status, 404);
      validate(api.components.schemas.Error, JSON.parse(res.bytes.toString("utf8")), "GET /api/not-a-route");
    });
  } finally {
    server.child.kill("SIGTERM");
    await server.exited;
  }

  await step("with --tokens, the bearer scheme is what each operation needs", async () => {
    const scopes = ["render", "upload", "metrics"];
    const tokens = Object.fromEntries(scopes.map((s) => [s, `openapi-test-token-${s}-0123456789`]));
    const file = path.join(os.tmpdir(), `umbra-openapi-tokens-${process.pid}`);
    fs.writeFileSync(file, scopes.map((s) => `${tokens[s]} ${s}\n`).join(""));
    const guarded = startServer(serverBinary, ["--tokens", file]);
    try {
      base = `http://127.0.0.1:${await guarded.port}`;
      let secured = 0;
      for (const [route, item] of Object.entries(api.paths)) {
        for (const [method, operation] of Object.entries(item)) {
          if (method === "options" || !operation.responses) continue;
          const example = Object.values(Object.values(operation.requestBody?.content ?? {})[0]?.examples ?? {})[0];
          const params = Object.fromEntries((operation.parameters ?? []).filter((p) => p.in === "path")
            .map((p) => [p.name, Object.values(p.examples)[0].value]));
          const type = Object.keys(operation.requestBody?.content ?? {})[0];
          const target = fill(route, { file: "index.html", ...params });
          const what = `${method.toUpperCase()} ${target} with --tokens`;
          const send = (token) => request(method.toUpperCase(), target, example && JSON.stringify(example.value), type, token);
          const needed = (operation.security ?? []).find((s) => s.bearer)?.bearer ?? [];
          if (needed.length === 0) {
            const res = await send();
            assert.ok(res.status < 400, `${what} needs no token, yet answered ${res.status}`);
            continue;
          }
          const none = await send();
          assert.equal(none.status, 401, `${what} without a token`);
          checkAnswer(operation, none, `${what} without a token`);
          const other = scopes.find((s) => !needed.includes(s));
          const wrong = await send(tokens[other]);
          assert.equal(wrong.status, 403, `${what} with a ${other} token`);
          checkAnswer(operation, wrong, `${what} with a ${other} token`);
          const right = await send(tokens[needed[0]]);
          assert.ok(right.status !== 401 && right.status !== 403, `${what} with a ${needed[0]} token: ${right.status}`);
          secured += 1;
        }
      }
      assert.ok(secured >= 8, `only ${secured} operations need a token`);
    } finally {
      guarded.child.kill("SIGTERM");
      await guarded.exited;
      fs.rmSync(file, { force: true });
    }
  });
  console.log(`docs/openapi.json: all checks passed (${checks} answers and values checked)`);
}

main().catch((e) => {
  console.error("FAILED:", e.message);
  process.exit(1);
});
