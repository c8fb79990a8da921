#!/usr/bin/env python3
"""Every scenario file that docs/scenarios.md shows (each ```toml block is a whole file) is
checked with `hpcm params --check-scenario` and played with `hpcm run` on a phantom, as a user
would copy it; each must exit 0 and, when played, leave frames.csv with one row per frame.

usage: scenario_docs.py HPCM SCRATCH FILE.md
"""
import os
import shutil
import subprocess
import sys

PHANTOM = "48,48,32"


def toml_blocks(md_path):
    """(line number of the opening fence, text) for each ```toml block."""
    blocks, current, start = [], None, 0
    with open(md_path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            fence = line.strip()
            if current is None and fence == "```toml":
                current, start = [], n
            elif current is not None and fence.startswith("```"):
                blocks.append((start, "".join(current)))
                current = None
            elif current is not None:
                current.append(line)
    return blocks


def main():
    hpcm, scratch, doc = sys.argv[1], os.path.abspath(sys.argv[2]), sys.argv[3]
    shutil.rmtree(scratch, ignore_errors=True)
    os.makedirs(scratch)
    failures, blocks = [], toml_blocks(doc)
    for line, text in blocks:
        where = f"{os.path.basename(doc)}:{line}"
        name = f"block_{line}.toml"
        with open(os.path.join(scratch, name), "w", encoding="utf-8") as f:
            f.write(text)
        problems = []
        p = subprocess.run([hpcm, "params", "--check-scenario", name], cwd=scratch, capture_output=True, text=True,
                           timeout=60)
        if p.returncode != 0:
            problems.append(f"--check-scenario exit {p.returncode}: {p.stderr.strip()[:400]}")
        out = f"run_{line}"
        r = subprocess.run([hpcm, "run", "--scenario", name, "--phantom", PHANTOM, "--no-link-check", "--out", out],
                           cwd=scratch, capture_output=True, text=True, timeout=600)
        if r.returncode != 0:
            problems.append(f"run exit {r.returncode}: {r.stderr.strip()[:400]}")
        else:
            csv = os.path.join(scratch, out, "frames.csv")
            rows = sum(1 for _ in open(csv, encoding="utf-8")) - 1 if os.path.isfile(csv) else 0
            if rows < 1:
                problems.append(f"{out}/frames.csv has no frame")
        print(("FAIL " if problems else "ok ") + where + "".join("\n    " + x for x in problems))
        if problems:
            failures.append(where)
    print(f"{len(blocks)} scenario files from {os.path.basename(doc)} checked and played, {len(failures)} failed")
    if not blocks:
        print("FAIL: no ```toml block found")
        return 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
