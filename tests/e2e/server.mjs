// The real umbra-server for the browser and contract tests: started on any
// free port, which its "listening on" line on stderr names.
import { spawn } from "node:child_process";

// `args`: more flags (e.g. ["--tokens", file]).
export function startServer(serverBinary, args = []) {
  const child = spawn(serverBinary, ["--port", "0", "--quiet", ...args], { stdio: ["ignore", "ignore", "pipe"] });
  let log = "";
  const exited = new Promise((resolve) => child.on("exit", (code, signal) => resolve({ code, signal })));
  const port = new Promise((resolve, reject) => {
    child.stderr.on("data", (chunk) => {
      log += chunk;
      const match = log.match(/listening on http:\/\/[^:]+:(\d+)\//);
      if (match) resolve(Number(match[1]));
    });
    exited.then(() => reject(new Error("umbra-server exited before listening:\n" + log)));
    // unref: a pending timer would keep node alive for the full 60 s after
    // every check has passed.
    setTimeout(() => reject(new Error("umbra-server did not listen within 60 s:\n" + log)), 60000).unref();
  });
  return { child, port, exited, log: () => log };
}
