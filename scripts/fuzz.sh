#!/usr/bin/env bash
# Fuzzes the request parser, the sun-hours parser, the HTTP reader, the
# glTF loader, the CityJSON reader and the conversion of other formats with
# libFuzzer for a bounded time (a sixth of it each).
#   scripts/fuzz.sh [SECONDS]   (default 60)
# Seeds: fuzz/corpus and bench/scenes, fuzz/corpus-sun-hours, fuzz/corpus-http, fuzz/corpus-cityjson,
# fuzz/corpus-gltf (its box-*.glb: Debian's gltfpack and draco_transcoder output of
# assimp-testmodels' BoxTextured.glb, compressed seeds), fuzz/corpus-import (small files of
# assimp-testmodels, each after a byte naming its format).
# New inputs go to build-asan/corpus*; a crash is written to fuzz/crashes/
# and fails the run: add it as a regression test (tests/test_request_parser.cpp,
# tests/test_http_message.cpp, tests/test_gltf_loader.cpp), then fix the code.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
# The same tree as scripts/sanitize.sh: after it, only the fuzz targets
# themselves are compiled here.
bash scripts/asan-build.sh fuzz_request_parser fuzz_sun_hours_parser fuzz_http_reader fuzz_gltf_loader fuzz_cityjson_loader \
  fuzz_model_import
mkdir -p build-asan/corpus fuzz/crashes
share=$(( seconds / 6 > 0 ? seconds / 6 : 1 ))
parser_seconds=$(( seconds - 5 * share > 0 ? seconds - 5 * share : 1 ))
# -max_len: bodies up to 64 KiB (the server takes 1 MiB, but nothing in the
# grammar needs more to be reached); -timeout: a slow input is a finding too.
build-asan/fuzz/fuzz_request_parser build-asan/corpus fuzz/corpus bench/scenes \
  -dict=fuzz/request.dict -max_total_time="$parser_seconds" -max_len=65536 -timeout=5 -rss_limit_mb=2048 \
  -artifact_prefix=fuzz/crashes/ -print_final_stats=1 2>&1 | tail -n 25
# The sun-hours body: the same grammar plus its own fields.
mkdir -p build-asan/corpus-sun-hours
build-asan/fuzz/fuzz_sun_hours_parser build-asan/corpus-sun-hours fuzz/corpus-sun-hours \
  -dict=fuzz/request.dict -max_total_time="$share" -max_len=65536 -timeout=5 -rss_limit_mb=2048 \
  -artifact_prefix=fuzz/crashes/ -print_final_stats=1 2>&1 | tail -n 25
# The HTTP reader: inputs up to 4 KiB (its limits are set small inside).
mkdir -p build-asan/corpus-http
build-asan/fuzz/fuzz_http_reader build-asan/corpus-http fuzz/corpus-http \
  -max_total_time="$share" -max_len=4096 -timeout=5 -rss_limit_mb=2048 \
  -artifact_prefix=fuzz/crashes/ -print_final_stats=1 2>&1 | tail -n 25
# The glTF loader: models up to 16 KiB (room for a few hundred triangles
# and every structure the loader checks).
mkdir -p build-asan/corpus-gltf
build-asan/fuzz/fuzz_gltf_loader build-asan/corpus-gltf fuzz/corpus-gltf \
  -dict=fuzz/gltf.dict -max_total_time="$share" -max_len=16384 -timeout=5 -rss_limit_mb=2048 \
  -artifact_prefix=fuzz/crashes/ -print_final_stats=1 2>&1 | tail -n 25
# The CityJSON reader: city files up to 16 KiB; seeds also the conformance
# corpus of others (tests/data/cityjson-corpus).
mkdir -p build-asan/corpus-cityjson
build-asan/fuzz/fuzz_cityjson_loader build-asan/corpus-cityjson fuzz/corpus-cityjson tests/data/cityjson-corpus \
  -max_total_time="$share" -max_len=16384 -timeout=5 -rss_limit_mb=2048 \
  -artifact_prefix=fuzz/crashes/ -print_final_stats=1 2>&1 | tail -n 25
# Other formats: a process per input (umbra-model-import), so few inputs;
# files up to 16 KiB.
mkdir -p build-asan/corpus-import
build-asan/fuzz/fuzz_model_import build-asan/corpus-import fuzz/corpus-import \
  -max_total_time="$share" -max_len=16384 -timeout=10 -rss_limit_mb=2048 \
  -artifact_prefix=fuzz/crashes/ -print_final_stats=1 2>&1 | tail -n 25
