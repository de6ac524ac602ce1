#!/usr/bin/env python3
"""The layers of docs/architecture.md, held to every #include.

    service    the GL thread and the cost model
    gpu        EGL, GL objects, the shader interface, the shadow renderer
    plan | reference | assets
    core       the typed request, scenes, shapes, light math, the sun

A folder of renderer/ is a layer; a layer includes only itself and the
layers listed for it below. server/ sees the service, the model store and
the request's own types, nothing else of the renderer. Only gpu/ touches GL,
and core/ holds no JSON and no threads.

Usage: tests/check_layers.py [ROOT]    (ROOT: the repository, default ..)
       tests/check_layers.py --self-test
Exit status 0 when every include keeps the rules; otherwise each crossing is
printed as FILE:LINE and the status is 1.
"""
import os
import re
import shutil
import sys
import tempfile

# What each layer may include besides itself.
BELOW = {
    "core": set(),
    "plan": {"core"},
    "reference": {"core"},
    "assets": {"core"},
    "gpu": {"core", "plan"},
    "service": {"core", "plan", "reference", "assets", "gpu"},
}
# server/ includes the renderer only through these: the service, the model
# store (uploads go there) and the types a request is made of.
SERVER_MAY_INCLUDE = [
    re.compile(r"service/.*"),
    re.compile(r"assets/.*"),
    re.compile(r"core/(request|scene|image|sun_position|sun_hours|builtin_models)\.hpp"),
]
# Crossings known and not yet removed: (file, included header, why). A
# listed crossing that no longer happens fails the check too, so that the
# list only shrinks.
KNOWN = {
}
GL_INCLUDE = re.compile(r'#\s*include\s*[<"](GL/|EGL/|gpu/gl\.hpp)')
GL_CALL = re.compile(r"\b(gl[A-Z]\w*|egl[A-Z]\w*)\s*\(")
JSON_INCLUDE = re.compile(r"#\s*include\s*<nlohmann/")
THREAD_INCLUDE = re.compile(r"#\s*include\s*<(thread|mutex|condition_variable|future|atomic)>")
LOCAL_INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')


def sources(root, folder):
    for dirpath, _, names in os.walk(os.path.join(root, folder)):
        for name in sorted(names):
            if name.endswith((".hpp", ".cpp", ".h")):
                yield os.path.relpath(os.path.join(dirpath, name), root)


def check(root):
    """Returns the list of crossings, each a line of text."""
    crossings = []
    seen_known = set()
    layers = set(BELOW)
    for folder in ["renderer", "server"]:
        for path in sources(root, folder):
            parts = path.split(os.sep)
            if folder == "renderer":
                if len(parts) < 3 or parts[1] not in layers:  # a layer may hold folders (core/shapes/)
                    crossings.append(f"{path}: renderer/ holds sources only in its layer folders {sorted(layers)}")
                    continue
                layer = parts[1]
            else:
                layer = "server"
            with open(os.path.join(root, path), encoding="utf-8") as f:
                lines = f.read().split("\n")
            for number, line in enumerate(lines, 1):
                where = f"{path}:{number}"
                if layer in ("core", "plan", "reference", "assets", "server") and GL_INCLUDE.search(line):
                    crossings.append(f"{where}: {layer} includes GL ({line.strip()}); only gpu/ may")
                code = line.split("//")[0]
                if layer in ("core", "plan", "reference", "assets") and GL_CALL.search(code):
                    crossings.append(f"{where}: {layer} calls GL ({GL_CALL.search(code).group(1)}); only gpu/ may")
                if layer == "core" and JSON_INCLUDE.search(line):
                    crossings.append(f"{where}: core holds no JSON ({line.strip()})")
                if layer == "core" and THREAD_INCLUDE.search(line):
                    crossings.append(f"{where}: core holds no threads ({line.strip()})")
                m = LOCAL_INCLUDE.match(line)
                if not m:
                    continue
                header = m.group(1)
                target = header.split("/")[0] if "/" in header else None
                key = (path.replace(os.sep, "/"), header)
                if layer == "server":
                    if target not in layers:
                        continue  # server's own headers
                    if any(p.fullmatch(header) for p in SERVER_MAY_INCLUDE):
                        continue
                    rule = "server includes only service/, assets/ and the request's types"
                else:
                    if target is None:
                        crossings.append(f"{where}: include {header} by its layer path (\"{layer}/...\")")
                        continue
                    if target == layer or target in BELOW[layer]:
                        continue
                    rule = f"{layer} may include only {sorted(BELOW[layer] | {layer})}"
                if key in KNOWN:
                    seen_known.add(key)
                    continue
                crossings.append(f"{where}: {header} crosses a layer: {rule}")
    for key, why in KNOWN.items():
        if key not in seen_known and os.path.exists(os.path.join(root, key[0])):
            crossings.append(f"{key[0]}: no longer includes {key[1]}: remove it from KNOWN in tests/check_layers.py")
    return crossings


def self_test():
    """The check must catch each kind of crossing: a tree with one of each."""
    cases = {
        "renderer/core/a.hpp": '#include "gpu/b.hpp"\n',                  # upward
        "renderer/plan/a.cpp": "void f() { glClear(0); }\n",               # GL outside gpu
        "renderer/reference/a.hpp": '#include "plan/a.hpp"\n',             # sideways
        "renderer/core/b.cpp": "#include <nlohmann/json.hpp>\n",           # JSON in core
        "renderer/core/c.cpp": "#include <thread>\n",                      # threads in core
        "renderer/loose.cpp": "\n",                                        # outside the layers
        "renderer/gpu/a.cpp": '#include "service/x.hpp"\n',                # gpu upward
        "server/a.cpp": '#include "gpu/shadow_renderer.hpp"\n',            # server below the service
        "server/b.cpp": "#include <GL/gl.h>\n",                            # server GL
        "renderer/core/shapes/a.cpp": '#include "gpu/b.hpp"\n',           # upward from a layer's folder
    }
    allowed = {
        "renderer/gpu/b.hpp": '#include "core/a.hpp"\n#include "plan/a.hpp"\n',
        "renderer/service/x.hpp": '#include "gpu/b.hpp"\n#include "reference/a.hpp"\n',
        "server/c.cpp": '#include "service/x.hpp"\n#include "core/request.hpp"\n#include "c.hpp"\n',
        "renderer/core/shapes/b.cpp": '#include "core/a.hpp"\n',
    }
    root = tempfile.mkdtemp()
    try:
        for path, text in {**cases, **allowed}.items():
            os.makedirs(os.path.join(root, os.path.dirname(path)), exist_ok=True)
            with open(os.path.join(root, path), "w") as f:
                f.write(text)
        found = [c for c in check(root) if "no longer includes" not in c]
        failed = False
        for path in cases:
            if not any(c.startswith(path) for c in found):
                print(f"self-test: the crossing in {path} was not caught")
                failed = True
        for path in allowed:
            if any(c.startswith(path) for c in found):
                print(f"self-test: {path} keeps the rules but was refused")
                failed = True
        print("self-test:", "FAILED" if failed else f"all {len(cases)} crossings caught, {len(allowed)} allowed files passed")
        return 1 if failed else 0
    finally:
        shutil.rmtree(root)


def main():
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    crossings = check(root)
    for c in crossings:
        print(c)
    if crossings:
        print(f"{len(crossings)} include(s) cross a layer the wrong way (docs/architecture.md)")
        return 1
    left = "; ".join(f"{a} -> {b}" for a, b in KNOWN)
    print(f"layers kept; {len(KNOWN)} known crossing(s) left" + (f": {left}" if left else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
