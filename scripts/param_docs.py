#!/usr/bin/python3
"""docs/parameters.md's parameter tables are generated from the parameter table
(src/core/param_table.cpp) by `hpcm params --markdown`. Between each pair of fences

    <!-- BEGIN generated parameter table [section]: ... -->
    <!-- END generated parameter table [section] -->

the page holds exactly that output. Regenerate after changing the table:

    cmake --build build --target hpcm_param_docs

--check (the CTest test) exits 1 naming the first section that differs.
"""
import argparse
import re
import subprocess
import sys

BLOCK = re.compile(r"<!-- BEGIN generated parameter table \[(\w+)\].*?<!-- END generated parameter table \[\1\] -->\n",
                   re.S)


def blocks(text):
    return {m.group(1): m.group(0) for m in BLOCK.finditer(text)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hpcm", required=True, help="the hpcm program")
    ap.add_argument("page", help="docs/parameters.md")
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="exit 1 when a generated block differs")
    mode.add_argument("--write", action="store_true", help="replace the generated blocks in the page")
    a = ap.parse_args()

    run = subprocess.run([a.hpcm, "params", "--markdown"], capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"param_docs: `{a.hpcm} params --markdown` failed (exit {run.returncode}): {run.stderr.strip()}")
    generated = blocks(run.stdout)
    if not generated:
        sys.exit("param_docs: `hpcm params --markdown` printed no table")
    with open(a.page, encoding="utf-8") as f:
        page = f.read()
    in_page = blocks(page)
    missing = [s for s in generated if s not in in_page]
    extra = [s for s in in_page if s not in generated]
    if missing or extra:
        sys.exit(f"param_docs: {a.page}: sections without their generated block: {missing}; blocks of no section: {extra}"
                 " (add or remove the fences by hand, then run with --write)")
    if a.check:
        for section, block in generated.items():
            if in_page[section] != block:
                print(f"FAIL: {a.page}: the generated parameter table [{section}] differs from `hpcm params --markdown`;"
                      " regenerate it with: cmake --build <build> --target hpcm_param_docs")
                for line_page, line_gen in zip(in_page[section].splitlines(), block.splitlines()):
                    if line_page != line_gen:
                        print(f"  page:      {line_page}\n  generated: {line_gen}")
                        break
                sys.exit(1)
        print(f"PASS: {a.page}: {len(generated)} generated parameter tables match")
        return
    page = BLOCK.sub(lambda m: generated[m.group(1)], page)
    with open(a.page, "w", encoding="utf-8") as f:
        f.write(page)
    print(f"{a.page}: {len(generated)} parameter tables written")


if __name__ == "__main__":
    main()
