#!/usr/bin/env python3
"""The longest functions of the workspace's Rust sources, longest first.

    python3 scripts/function-lengths.py [--all] [--top N]

Counts lines from a `fn` line to its closing brace at the same indentation. Test modules
(`mod tests`), `tests/` and `benches/` are left out unless `--all` is given."""
import argparse
import os
import re

FN = re.compile(r'^(\s*)(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?fn\s+(\w+)')


def functions(path):
    lines = open(path, encoding="utf-8").read().split("\n")
    in_tests = False
    for i, line in enumerate(lines):
        if re.match(r"\s*(pub(\(crate\))?\s+)?mod tests\s*\{", line):
            in_tests = True
        m = FN.match(line)
        if not m or in_tests:
            continue
        indent = " " * len(m.group(1))
        for j in range(i + 1, len(lines)):
            if lines[j].startswith(indent + "}") and not lines[j].startswith(indent + " "):
                yield j - i + 1, m.group(7), i + 1
                break


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--all", action="store_true", help="count tests and benchmarks too")
    ap.add_argument("--top", type=int, default=15)
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    found = []
    for dirpath, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d != "target"]
        rel = os.path.relpath(dirpath, root)
        parts = rel.split(os.sep)
        if not a.all and ("tests" in parts or "benches" in parts):
            continue
        for f in files:
            if f.endswith(".rs"):
                p = os.path.join(dirpath, f)
                for n, name, line in functions(p):
                    found.append((n, os.path.relpath(p, root), name, line))
    found.sort(reverse=True)
    for n, p, name, line in found[: a.top]:
        print(f"{n:5d}  {p}:{line}  {name}")


if __name__ == "__main__":
    main()
