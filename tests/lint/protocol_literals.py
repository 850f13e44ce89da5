#!/usr/bin/env python3
"""The wire protocol is written once: fails on a route literal ("/v1/...") in the web monitor's scripts or in the
coordinator's sources (tests excluded; protocol/routes.cpp holds the route table), and on a job-state list written in
the monitor (the monitor takes routes and states from /monitor/protocol.js, which the coordinator serves)."""
import pathlib
import re
import sys

root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parents[2])
problems = []

route = re.compile(r"""['"`][^'"`\n]*/v1/""")
for f in sorted((root / "server" / "monitor").glob("*.js")) + sorted((root / "server").glob("*.cpp")):
    if f.name.endswith("_test.cpp") or f.name.startswith("test_"):
        continue
    for n, line in enumerate(f.read_text().splitlines(), 1):
        code = line.strip()
        if code.startswith(("*", "/*", "//")):
            continue  # a comment may name a route
        code = code.split(" // ")[0]
        if route.search(code):
            problems.append(f"{f.relative_to(root)}:{n}: route literal: {line.strip()}")

states = ["queued", "running", "paused", "done", "failed", "cancelled"]
state_list = re.compile(r"\[[^\]]*\]")
for f in sorted((root / "server" / "monitor").glob("*.js")):
    for n, line in enumerate(f.read_text().splitlines(), 1):
        for m in state_list.finditer(line):
            named = [s for s in states if re.search(rf"""['"]{s}['"]""", m.group(0))]
            if len(named) >= 3:
                problems.append(f"{f.relative_to(root)}:{n}: job-state list: {line.strip()}")

for p in problems:
    print(p)
if problems:
    sys.exit(f"{len(problems)} literal(s) of the protocol outside protocol/: take them from the route table")
print("no route literals or job-state lists outside protocol/")
