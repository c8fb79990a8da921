#!/usr/bin/env python3
"""Runs every `hpcm ...` command shown in the code blocks of the given Markdown files, as a user
would copy it, at a small size: phantom lattices become 24x24x16 and CT inputs are read with
--downsample 4 (or more where the command asks for more). Each must exit 0 and leave what it
names (--out, --export, a redirected file). Commands of the viewer and lines that are not hpcm
commands are listed as not run.

usage: doc_commands.py HPCM SCRATCH DATA_DIR FILE.md [FILE.md ...]
The inputs the docs name are links in SCRATCH to the shared test data (DATA_DIR): a missing
DATA_DIR skips the commands that need it.
"""
import os
import re
import shlex
import shutil
import subprocess
import sys

# The file names the docs use for a user's own CT, and which shared file stands in for each.
INPUTS = {
    "abdomen_ct.nii.gz": "abdomen-ct/abdomen_ct.nii.gz",
    "ct.nii.gz": "abdomen-ct/abdomen_ct.nii.gz",
    "abdomen-ct-dicom": "abdomen-ct-dicom",
    "patient_ct": "abdomen-ct-dicom",
}
SMALL_PHANTOM = "24,24,16"
SMALL_DOWNSAMPLE = 4


def commands(md_path):
    """(line number, command) for each hpcm command in a fenced code block."""
    out, fenced = [], False
    with open(md_path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            if line.lstrip().startswith("```"):
                fenced = not fenced
                continue
            text = line.strip()
            if fenced and re.match(r"hpcm\s", text):
                out.append((n, re.sub(r"\s+#.*$", "", text)))
    return out


def small(argv):
    """The same command at a small size; also returns whether it reads a CT input."""
    argv, reads_input = list(argv), False
    for i, a in enumerate(argv[:-1]):
        if a in ("--phantom", "--size"):
            argv[i + 1] = SMALL_PHANTOM
        if a == "--input":
            reads_input = True
    if argv[1] == "info" and len(argv) > 2 and not argv[2].startswith("-"):
        reads_input = True
    if reads_input and argv[1] in ("run", "experiment", "bench"):
        if "--downsample" in argv:
            i = argv.index("--downsample")
            argv[i + 1] = str(max(int(argv[i + 1]), SMALL_DOWNSAMPLE))
        else:
            argv += ["--downsample", str(SMALL_DOWNSAMPLE)]
    return argv, reads_input


def main():
    hpcm, scratch, data, docs = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
    shutil.rmtree(scratch, ignore_errors=True)
    os.makedirs(scratch)
    have_data = os.path.isdir(data)
    if have_data:
        for name, target in INPUTS.items():
            os.symlink(os.path.join(os.path.abspath(data), target), os.path.join(scratch, name.rstrip("/")))
    failures, ran = [], 0
    for doc in docs:
        for n, cmd in commands(doc):
            where = f"{os.path.basename(doc)}:{n}"
            words = shlex.split(cmd)
            stdout_file = None
            if ">" in words:
                i = words.index(">")
                stdout_file, words = words[i + 1], words[:i]
            argv, reads_input = small(words)
            if reads_input and not have_data:
                print(f"SKIP {where}: {cmd} (no shared data in {data})")
                continue
            argv[0] = hpcm
            out = open(os.path.join(scratch, stdout_file), "w") if stdout_file else subprocess.PIPE
            p = subprocess.run(argv, cwd=scratch, stdout=out, stderr=subprocess.PIPE, text=True, timeout=600)
            if stdout_file:
                out.close()
            ran += 1
            problems = []
            if p.returncode != 0:
                problems.append(f"exit {p.returncode}: {p.stderr.strip()[:400]}")
            for opt in ("--out", "--export"):
                if opt in argv:
                    d = os.path.join(scratch, argv[argv.index(opt) + 1])
                    if not os.path.isdir(d) or not os.listdir(d):
                        problems.append(f"{opt} {argv[argv.index(opt) + 1]} is missing or empty after the command")
            if "--export" in argv and not os.path.isfile(os.path.join(scratch, argv[argv.index("--export") + 1], "export.json")):
                problems.append("no export.json in the --export folder")
            if stdout_file and os.path.getsize(os.path.join(scratch, stdout_file)) == 0:
                problems.append(f"{stdout_file} is empty")
            status = "FAIL" if problems else "ok"
            print(f"{status} {where}: {cmd}" + ("".join("\n    " + x for x in problems)))
            if problems:
                failures.append(where)
    print(f"{ran} documented commands run, {len(failures)} failed")
    if ran == 0:
        print("FAIL: no command found or run")
        return 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
