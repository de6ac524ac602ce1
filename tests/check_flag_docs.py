#!/usr/bin/env python3
"""docs/operations.md against the server's own flag table.

The defaults of umbra-server's flags live once, in server/main.cpp's flag
table, which prints them in `--help`. The operator's guide repeats them (the
synopsis `[--queue 16]`, and prose such as "`--max-model-mib N` (default
64"): this compares every such default with --help's, and checks that the
synopsis names every flag --help prints and no other.

Usage: tests/check_flag_docs.py UMBRA_SERVER_BINARY DOCS/OPERATIONS.MD
"""
import re
import subprocess
import sys


def help_flags(binary):
    """{flag: default text or None} from `umbra-server --help`."""
    ran = subprocess.run([binary, "--help"], capture_output=True, text=True)
    text = ran.stdout + ran.stderr
    flags = {}
    current = None
    for line in text.split("\n"):
        m = re.match(r"^  (--[a-z][a-z-]*)", line)
        if m:
            current = m.group(1)
            flags[current] = None
        if current:
            d = re.search(r"\(default ([^):]+)", line)
            if d and flags[current] is None:
                flags[current] = d.group(1).strip()
    return flags


def main():
    binary, doc = sys.argv[1], sys.argv[2]
    flags = help_flags(binary)
    if len(flags) < 10:
        print(f"--help printed only {len(flags)} flags: {sorted(flags)}")
        return 1
    text = open(doc, encoding="utf-8").read()
    problems = []
    synopsis = re.search(r"```\n(umbra-server \[.*?)```", text, re.S)
    if not synopsis:
        return print("no umbra-server synopsis block in " + doc) or 1
    in_synopsis = set()
    for flag in re.findall(r"--[a-z][a-z-]*", synopsis.group(1)):
        in_synopsis.add(flag)
        if flag not in flags:
            problems.append(f"synopsis: {flag} is not a flag of umbra-server")
    for flag, value in re.findall(r"\[(--[a-z-]+) ([^\]|]+)", synopsis.group(1)):
        if flag in flags and re.fullmatch(r"[0-9.]+", value.strip()) and flags[flag] != value.strip():
            problems.append(f"synopsis: [{flag} {value}] but --help says default {flags[flag]}")
    for flag in flags:
        if flag not in in_synopsis and flag != "--help":
            problems.append(f"synopsis: {flag} is missing")
    for flag, value in re.findall(r"`(--[a-z-]+) N` \(default ([0-9.]+)", text):
        if flags.get(flag) != value:
            problems.append(f"`{flag} N` (default {value}) but --help says default {flags.get(flag)}")
    for p in problems:
        print(p)
    if problems:
        return 1
    print(f"docs/operations.md agrees with --help on {len(flags)} flags")
    return 0


if __name__ == "__main__":
    sys.exit(main())
