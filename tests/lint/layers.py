#!/usr/bin/env python3
"""The folders' layers, checked on every #include "..." of the sources (tests and benches excluded): no include runs
back up a layer.

- core/ includes nothing of the project outside core/. Inside it: util/ includes only util/; geometry/, sampling/ and
  image/ include util/ and themselves; render/ includes those and itself; scene/ (the loader) sits on top.
- protocol/ includes from core/ only the value headers listed in PROTOCOL_CORE (no renderer, no scene loader).
- worker/, client/, server/ and cli/ never include a layer above them (cli/ is the top; server/ and worker/ never
  include each other; client/ includes neither).
"""
import pathlib
import re
import sys

root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parents[2])

CORE_LAYERS = {"util": 0, "geometry": 1, "sampling": 1, "image": 1, "render": 2, "scene": 3}
PROTOCOL_CORE = {
    "core/image/pixel_window.h", "core/render/render_options.h", "core/render/layers.h", "core/scene/load_options.h",
    "core/geometry/split_method.h", "core/render/light_sampling.h", "core/sampling/adaptive.h",
    "core/util/enum_names.h", "core/util/sha256.h", "core/scene/json_depth.h",
}
# What each top-level folder may include (besides itself).
ALLOWED = {
    "core": set(),
    "failpoint": set(),
    "protocol": {"core"},
    "net": {"core", "protocol"},
    "client": {"core", "protocol", "net"},
    "worker": {"core", "protocol", "net", "client", "failpoint"},
    "server": {"core", "protocol", "net", "failpoint"},
    "cli": {"core", "protocol", "net", "client", "worker", "server", "failpoint"},
}
include = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def is_test(path):
    name = path.name
    return name.endswith("_test.cpp") or name.startswith("test_") or "tests" in path.parts


problems = []
for folder, allowed in ALLOWED.items():
    base = root / folder
    for f in sorted(p for p in base.rglob("*") if p.suffix in (".h", ".cpp", ".inl") and not is_test(p)):
        rel = f.relative_to(root)
        for n, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
            m = include.match(line)
            if not m:
                continue
            target = m.group(1)
            top = target.split("/")[0]
            if top not in ALLOWED or top == folder:
                if folder == "core" and top == "core":
                    src_layer = CORE_LAYERS[rel.parts[1]]
                    dst_layer = CORE_LAYERS.get(target.split("/")[1], 99)
                    same = rel.parts[1] == target.split("/")[1]
                    if not same and dst_layer >= src_layer:
                        problems.append(f"{rel}:{n}: core/{rel.parts[1]}/ includes {target}, "
                                        f"which is not below it")
                continue
            if top not in allowed:
                problems.append(f"{rel}:{n}: {folder}/ includes {target} ({top}/ is not below {folder}/)")
            elif folder == "protocol" and top == "core" and target not in PROTOCOL_CORE:
                problems.append(f"{rel}:{n}: protocol/ includes {target}, not one of core's value headers")

for p in problems:
    print(p)
print(f"layers: {len(problems)} include(s) running back up" if problems else "layers: every include points down")
sys.exit(1 if problems else 0)
