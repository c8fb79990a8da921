#!/usr/bin/env python3
"""Runs every command shown in the shell code blocks of the given Markdown files, as a user
would copy it, at a small size, so that no documented command can rot unnoticed:
  * `hpcm ...` with the built CLI; `hpcm-viewer ...` (under `xvfb-run`) with the built viewer
    when it plays by script and exits (--screenshot, --record, --bench-drag);
  * `/usr/bin/python3 ...` (`-m hpcm.cohort`, `-c`, `python/examples/...`) with the built
    Python module on PYTHONPATH and HPCM_EXE set to the built CLI.
Small size: phantom lattices become 24x24x16 (also `phantom:NX,NY,NZ` cohort inputs and the
Python example's default), CT inputs are read with --downsample 4 (or more where the command
asks for more), the viewer plays at most 20 frames and --bench-drag runs 2 s, and `...` in a synopsis-like line becomes a short run.
Each command must exit 0 and leave what it names (--out, --export, --screenshot, a redirected
file). What cannot run here is listed with the reason (`not run`): the viewer's interactive
commands, installers (pip, apt-get, sudo), other tools (plastimatch), the two top-level
scripts (they build and test everything), option synopses, and `--backend cuda` without a
device (that command must then fail saying `no CUDA device`).

usage: doc_commands.py HPCM SCRATCH DATA_DIR [--viewer EXE] [--python-path DIR]
                       [--source-dir DIR] FILE.md|DIR [...]
A DIR stands for its *.md files. The inputs the docs name are links in SCRATCH to the shared
test data (DATA_DIR): a missing DATA_DIR skips the commands that need it. A relative path a
command names that exists in the source tree (docs/..., examples/..., python/...) is given as
that file.
"""
import argparse
import glob
import os
import re
import shlex
import shutil
import subprocess
import sys
import time

# The file names the docs use for a user's own CT, and which shared file stands in for each.
INPUTS = {
    "abdomen_ct.nii.gz": "abdomen-ct/abdomen_ct.nii.gz",
    "ct.nii.gz": "abdomen-ct/abdomen_ct.nii.gz",
    "abdomen-ct-dicom": "abdomen-ct-dicom",
    "patient_ct": "abdomen-ct-dicom",
    "cts/abdomen_ct.nii.gz": "abdomen-ct/abdomen_ct.nii.gz",
}
# Files the docs' commands take as the user's own, written before the first command.
SWEEP_TOML = '[grid]\n"dynamics.alpha" = [0.8, 0.95]\n'
SCENARIO_TOML = ('[scenario]\nname = "short"\nframes = 30\n\n[[grab]]\ncentre = "auto"\nrelease = 10\n'
                 'keyframes = [[5, 0.0, -2.0, 0.0]]\n')
SMALL_PHANTOM = "24,24,16"
SMALL_DOWNSAMPLE = 4
SMALL_BENCH_DRAG = "2"
SMALL_VIEWER_FRAMES = 20
# `hpcm run --params my_params.toml ...`: the elided options of a synopsis line.
ELLIPSIS_ARGS = ["--phantom", SMALL_PHANTOM, "--frames", "10", "--out", "ellipsis_run"]
# Whole programs the test does not run, with the reason it says.
NOT_RUN = {
    "bash": "a top-level script (builds and runs everything; CI runs it)",
    "sudo": "installs into the system",
    "apt-get": "installs packages",
    "plastimatch": "another tool (tests/io checks plastimatch on hpcm's exports)",
}
# The programs a documented command may start with; other lines of a code block are output.
PROGRAMS = ("hpcm", "hpcm-viewer", "xvfb-run", "python", "python3", "cmake", "ctest", "mkdir") + tuple(NOT_RUN)
CT_SUFFIXES = (".nii", ".nii.gz", ".nrrd", ".mha", ".mhd")


def commands(md_path):
    """(line number, command) for each command line in a shell-like fenced code block
    (no language, sh, bash, console): backslash continuations joined, trailing comments cut."""
    out, fenced, lang, pending, start = [], False, "", "", 0
    with open(md_path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            stripped = line.strip()
            if stripped.startswith("```"):
                fenced, lang = not fenced, stripped[3:].strip()
                continue
            if not fenced or lang not in ("", "sh", "bash", "console", "shell"):
                continue
            text = re.sub(r"\s+#.*$", "", stripped)
            if not pending:
                start = n
            if text.endswith("\\"):
                pending += text[:-1] + " "
                continue
            text, pending = (pending + text).strip(), ""
            if is_command(text):
                out.append((start, text))
    return out


def is_command(text):
    """Whether a code line is a command (and not program output shown in a block): its first
    word, after VAR=value words, is a program a user runs."""
    words = text.split()
    while words and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*=\S*", words[0]):
        words = words[1:]
    return bool(words) and (words[0] in PROGRAMS or words[0].startswith(("/", "./", "~/")))


def split_env(words):
    """Leading VAR=value words as a dict, and the rest."""
    env = {}
    while words and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*=.*", words[0]):
        k, v = words[0].split("=", 1)
        env[k], words = v, words[1:]
    return env, words


def small(argv):
    """The same command at a small size; also returns whether it reads a CT input."""
    argv, reads_input = list(argv), False
    if "..." in argv:
        i = argv.index("...")
        argv[i:i + 1] = ELLIPSIS_ARGS
    for i, a in enumerate(argv[:-1]):
        if a in ("--phantom", "--size"):
            argv[i + 1] = SMALL_PHANTOM
        if a == "--input":
            reads_input = True
        if a == "--bench-drag":
            argv[i + 1] = SMALL_BENCH_DRAG
        if a == "--frames" and argv[0].endswith("xvfb-run") and argv[i + 1].isdigit():
            argv[i + 1] = str(min(int(argv[i + 1]), SMALL_VIEWER_FRAMES))
    for i, a in enumerate(argv):
        m = re.fullmatch(r"phantom:[0-9]+,[0-9]+,[0-9]+(:.*)?", a)
        if m:
            argv[i] = "phantom:" + SMALL_PHANTOM + (m.group(1) or "")
        elif i > 0 and not a.startswith("-") and (a.endswith(CT_SUFFIXES) or a.rstrip("/") in INPUTS
                                                  or a.endswith("inputs.csv") or a == "cts/"):
            reads_input = True
    if len(argv) > 1 and argv[1] == "info" and len(argv) > 2 and not argv[2].startswith("-"):
        reads_input = True
    # A cohort's --downsample applies to its phantoms too; its manifests carry their own factor.
    cohort_of_cts = "hpcm.cohort" in argv and not any(a.startswith("phantom:") for a in argv)
    downsampled = reads_input and (argv[1] in ("run", "experiment", "bench") or cohort_of_cts
                                   or any(a.endswith("paper_protocol.py") for a in argv))
    if downsampled:
        if "--downsample" in argv:
            i = argv.index("--downsample")
            argv[i + 1] = str(max(int(argv[i + 1]), SMALL_DOWNSAMPLE))
        else:
            argv += ["--downsample", str(SMALL_DOWNSAMPLE)]
    # The Python example's default lattice is the main job's 96x96x64.
    if any(a.endswith("paper_protocol.py") for a in argv) and "--input" not in argv and "--phantom" not in argv:
        argv += ["--phantom", SMALL_PHANTOM]
    return argv, reads_input


def in_source_tree(argv, scratch, source):
    """Relative paths that name a file of the source tree (docs/..., examples/...) as that file.
    Files only: a folder such as out/ stays in the scratch folder, so no documented command
    writes into (or is refused by) the source tree."""
    out = []
    for a in argv:
        if source and "/" in a and not a.startswith(("/", "-")) and not os.path.exists(os.path.join(scratch, a)) \
                and os.path.isfile(os.path.join(source, a)):
            a = os.path.join(source, a)
        out.append(a)
    return out


def prepare(scratch, data, hpcm):
    """Links to the shared inputs and the user's own files the docs' commands name."""
    have_data = os.path.isdir(data)
    if have_data:
        for name, target in INPUTS.items():
            link = os.path.join(scratch, name.rstrip("/"))
            os.makedirs(os.path.dirname(link), exist_ok=True)
            os.symlink(os.path.join(os.path.abspath(data), target), link)
    with open(os.path.join(scratch, "my.toml"), "w") as f:
        subprocess.run([hpcm, "params", "--defaults"], stdout=f, check=True)
    with open(os.path.join(scratch, "scenario.toml"), "w") as f:
        f.write(SCENARIO_TOML)
    with open(os.path.join(scratch, "sweep.toml"), "w") as f:
        f.write(SWEEP_TOML)
    return have_data


def how_to_run(words, tools):
    """(argv, extra environment) for a documented command, or (None, reason)."""
    env, words = split_env(words)
    if not words:
        return None, "no command"
    if words[0] == "xvfb-run":
        if "hpcm-viewer" not in words:
            return None, "xvfb-run of another program"
        i = words.index("hpcm-viewer")
        if not tools["xvfb-run"] or not tools["viewer"]:
            return None, "no xvfb-run or no hpcm-viewer in this build"
        return ["xvfb-run"] + words[1:i] + [tools["viewer"]] + words[i + 1:], env
    if words[0] == "hpcm":
        return [tools["hpcm"]] + words[1:], env
    if words[0] == "hpcm-viewer":
        if not any(o in words for o in ("--screenshot", "--record", "--bench-drag")):
            return None, "the viewer, interactive (its scripted runs are run)"
        if not tools["xvfb-run"] or not tools["viewer"]:
            return None, "no xvfb-run or no hpcm-viewer in this build"
        return ["xvfb-run", "-a", tools["viewer"]] + words[1:], env
    if words[0] == "/usr/bin/python3" or re.fullmatch(r"python3?", words[0]):
        if "pip" in words or "venv" in words:
            return None, "installs the module (tests/python checks the installs)"
        if not tools["python_path"]:
            return None, "this build has no Python module"
        env["PYTHONPATH"] = tools["python_path"]
        return ["/usr/bin/python3"] + words[1:], env
    if words[0] in NOT_RUN:
        return None, NOT_RUN[words[0]]
    if words[0] == "mkdir":
        return words, env
    if words[0] in ("cmake", "ctest"):
        return None, "builds or tests the project (CI runs it)"
    return None, "a program of the user's own installation (tests/python checks the installs)"


def check_outputs(argv, scratch, stdout_file):
    """What the command names as its outputs must exist and not be empty."""
    problems = []
    for opt in ("--out", "--export", "--record"):
        if opt in argv:
            d = os.path.join(scratch, argv[argv.index(opt) + 1])
            if not os.path.isdir(d) or not os.listdir(d):
                problems.append(f"{opt} {argv[argv.index(opt) + 1]} is missing or empty after the command")
    if "--export" in argv and not os.path.isfile(os.path.join(scratch, argv[argv.index("--export") + 1], "export.json")):
        problems.append("no export.json in the --export folder")
    if "--screenshot" in argv:
        shot = os.path.join(scratch, argv[argv.index("--screenshot") + 1])
        if not os.path.isfile(shot) or os.path.getsize(shot) == 0:
            problems.append(f"--screenshot {shot} is missing or empty")
    if stdout_file and os.path.getsize(os.path.join(scratch, stdout_file)) == 0:
        problems.append(f"{stdout_file} is empty")
    return problems


def markdown_files(items):
    files = []
    for item in items:
        files += sorted(glob.glob(os.path.join(item, "*.md"))) if os.path.isdir(item) else [item]
    return files


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("hpcm")
    ap.add_argument("scratch")
    ap.add_argument("data")
    ap.add_argument("docs", nargs="+")
    ap.add_argument("--viewer", default="")
    ap.add_argument("--python-path", default="")
    ap.add_argument("--source-dir", default="")
    ap.add_argument("--skip", action="append", default=[], help="a Markdown file name to leave out")
    a = ap.parse_args()
    scratch = os.path.abspath(a.scratch)
    shutil.rmtree(scratch, ignore_errors=True)
    os.makedirs(scratch)
    tools = {"hpcm": os.path.abspath(a.hpcm), "viewer": a.viewer if a.viewer and os.path.isfile(a.viewer) else "",
             "python_path": os.path.abspath(a.python_path) if a.python_path else "", "xvfb-run": shutil.which("xvfb-run")}
    have_data = prepare(scratch, a.data, tools["hpcm"])
    failures, ran, not_run = [], 0, 0
    # A command that another document shows word for word (the README repeats docs/cli.md's) is
    # run once: the same argument vector, environment and redirection check the same thing.
    # Within one document a repeated command runs again (it may show a resumed run).
    first_run = {}  # (argv, env, redirection) -> (document, where, status)
    for doc in [d for d in markdown_files(a.docs) if os.path.basename(d) not in a.skip]:
        for n, cmd in commands(doc):
            where = f"{os.path.basename(doc)}:{n}"
            if re.search(r"\[--|\|", cmd):
                print(f"not run {where}: {cmd} (an option synopsis)")
                not_run += 1
                continue
            try:
                words = shlex.split(cmd)
            except ValueError as e:
                print(f"FAIL {where}: {cmd}\n    cannot be parsed as a shell command: {e}")
                failures.append(where)
                continue
            stdout_file = None
            if ">" in words:
                i = words.index(">")
                stdout_file, words = words[i + 1], words[:i]
            argv, env = how_to_run(words, tools)
            if argv is None:
                print(f"not run {where}: {cmd} ({env})")
                not_run += 1
                continue
            argv, reads_input = small(argv)
            argv = in_source_tree(argv, scratch, os.path.abspath(a.source_dir) if a.source_dir else "")
            if reads_input and not have_data:
                print(f"SKIP {where}: {cmd} (no shared data in {a.data})")
                continue
            key = (tuple(argv), tuple(sorted(env.items())), stdout_file)
            if key in first_run and first_run[key][0] != doc:
                _, first, first_status = first_run[key]
                print(f"{first_status} {where}: the same command as {first} (run once)")
                if first_status == "FAIL":
                    failures.append(where)
                continue
            out = open(os.path.join(scratch, stdout_file), "w") if stdout_file else subprocess.PIPE
            full_env = dict(os.environ, HPCM_EXE=tools["hpcm"], HPCM_NO_PROGRESS="1", MPLBACKEND="Agg", **env)
            t0 = time.monotonic()
            p = subprocess.run(argv, cwd=scratch, stdout=out, stderr=subprocess.PIPE, text=True, timeout=600,
                               env=full_env)
            if stdout_file:
                out.close()
            if "--backend" in argv and argv[argv.index("--backend") + 1] == "cuda" and p.returncode != 0 \
                    and "no CUDA device" in p.stderr:
                print(f"not run {where}: {cmd} (no CUDA device here; it said so)")
                not_run += 1
                continue
            ran += 1
            problems = []
            if p.returncode != 0:
                problems.append(f"exit {p.returncode}: {p.stderr.strip()[-600:]}")
            problems += check_outputs(argv, scratch, stdout_file)
            status = "FAIL" if problems else "ok"
            first_run.setdefault(key, (doc, where, status))
            print(f"{status} {where} ({time.monotonic() - t0:.1f} s): {' '.join(shlex.quote(x) for x in argv)}" + "".join("\n    " + x for x in problems),
                  flush=True)
            if problems:
                failures.append(where)
    print(f"{ran} documented commands run, {not_run} not run (reasons above), {len(failures)} failed")
    if ran == 0:
        print("FAIL: no command found or run")
        return 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
