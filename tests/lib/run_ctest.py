#!/usr/bin/env python3
"""Runs one step of the test command through ctest and fails unless every test it selects ran and passed.

ctest counts a skipped test (exit 77, GTEST_SKIP) as passed and exits 0; this runner does not. It lists the tests the
step selects, runs them with a JUnit report, and fails when a test was skipped or not run, when fewer ran than were
listed, or when fewer than --min were selected at all (a label that lost its tests). A skip is accepted only for a test
named in the environment variable TESSERA_ALLOWED_SKIPS (space-separated test names), and never when CI=true.

    run_ctest.py --step NAME --build DIR [--jobs N] [--min N] [--summary FILE] [-- CTEST_FILTER_ARGS...]

CTEST_FILTER_ARGS select the tests (-L, -R, -E, ...). The summary line is printed and, with --summary, appended to
FILE.
"""

import argparse
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET


def allowed_skips():
    names = os.environ.get("TESSERA_ALLOWED_SKIPS", "").split()
    if names and os.environ.get("CI", "").lower() == "true":
        print(f"run_ctest: CI=true, so TESSERA_ALLOWED_SKIPS ({' '.join(names)}) is ignored: every test must run")
        return set()
    return set(names)


def listed_count(build, filters):
    out = subprocess.run(["ctest", "--test-dir", build, "-N", *filters], check=True, capture_output=True, text=True)
    m = re.search(r"^Total Tests: (\d+)$", out.stdout, re.M)
    if not m:
        sys.exit(f"run_ctest: cannot read the test count from 'ctest -N':\n{out.stdout}")
    return int(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--step", required=True)
    ap.add_argument("--build", required=True)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--min", type=int, default=1)
    ap.add_argument("--summary")
    ap.add_argument("filters", nargs="*")
    a = ap.parse_args()

    listed = listed_count(a.build, a.filters)
    junit = os.path.join(a.build, f"junit-{re.sub(r'[^A-Za-z0-9_.-]', '_', a.step)}.xml")
    if os.path.exists(junit):
        os.remove(junit)
    rc = subprocess.run(["ctest", "--test-dir", a.build, "--output-on-failure", "--no-tests=error", "-j", str(a.jobs),
                         "--output-junit", os.path.abspath(junit), *a.filters]).returncode

    problems = []
    ran, skipped, not_run = [], [], []
    if os.path.exists(junit):
        for case in ET.parse(junit).getroot().iter("testcase"):
            name, status = case.get("name"), case.get("status")
            if case.find("skipped") is not None or status in ("notrun", "skipped"):
                skipped.append(name)
            elif status in ("run", "fail"):
                ran.append(name)
            else:
                not_run.append(f"{name} ({status})")
    else:
        problems.append(f"ctest wrote no report ({junit})")

    allowed = allowed_skips()
    refused = [n for n in skipped if n not in allowed]
    if refused:
        problems.append("skipped (a skip is not a pass; allow one with TESSERA_ALLOWED_SKIPS outside CI): "
                        + ", ".join(refused))
    if not_run:
        problems.append("not run: " + ", ".join(not_run))
    if len(ran) + len(skipped) != listed:
        problems.append(f"{listed} tests listed but {len(ran) + len(skipped)} reported")
    if listed < a.min:
        problems.append(f"{listed} tests selected, fewer than the {a.min} this step expects")
    if rc != 0:
        problems.append(f"ctest exited {rc}")

    allowed_note = f" (allowed: {', '.join(n for n in skipped if n in allowed)})" if skipped and not refused else ""
    line = f"{a.step}: {len(ran)} of {listed} tests ran, {len(skipped)} skipped{allowed_note}"
    print(f"== {line}")
    if a.summary:
        with open(a.summary, "a") as f:
            f.write(line + ("" if not problems else " - FAILED") + "\n")
    for p in problems:
        print(f"run_ctest: {a.step}: {p}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
