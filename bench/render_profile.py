#!/usr/bin/env python3
"""Where a render's time goes, by part of the renderer: each scene rendered on one thread under
`perf record` (linux-perf), its samples' functions (self time, no call graph) summed into the parts below. What is
not traversal is what stands between a render and its traversal-only rate (bench/integrator_vs_traversal).

    python3 bench/render_profile.py BUILD [--scenes a,b,...] [--spp N (64)] [--freq HZ] [--unmatched K]

Needs `perf` with user-space sampling allowed (perf_event_paranoid <= 2, or root) and a build with symbols (the
release build keeps line tables). A function no part names is counted under "other" and, with --unmatched K, the K
largest are listed so the parts can be kept up to date when functions are renamed.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

SCENES = ["cbox_no_light", "cbox_no_light_refraction", "cbox_area_light", "cbox_env_light", "sky_sun"]

# (part, pattern over the symbol), the first match wins. Kernel samples are "[k]" lines.
PARTS = [
    ("traversal", r"bvh_kernels::|Bvh::intersect|Bvh::occluded|intersect_sphere|Bvh::"),
    ("camera and sample loop", r"add_samples|render_pixel|PixelSampler|Camera::|generate_pixel|laine_karras|sobol|"
                               r"tessera::render\("),
    ("hit points and spawned rays", r"surface_point|Scene::surface|offset_ray_origin|spawn_ray"),
    ("light sampling", r"AreaLight::|SphericalRectangle|bilinear|far_weights|near_weights|PointLight|"
                       r"Environment::sample|Distribution1D|Distribution2D|sample_uniform_cone|portable_acos"),
    ("environment and textures", r"Texture::|Environment::|direction_to_uv|portable_atan2|bilerp"),
    ("shading", r"trace_radiance|trace_path|trace_sample|Bsdf|sample_cosine|Frame::|fresnel|microfacet|"
                r"beckmann|power_heuristic|portable_sincos|refract"),
    ("film and output", r"PixelAccumulator|Imf|exr|Exr|deflate|png|crc32|adler32|Image::"),
    ("start, memory, kernel", r"^\[k\]|_dl_|do_lookup|check_match|malloc|free|memset|memmove|memcpy|mmap|munmap|"
                              r"tbb::|std::|operator new|operator delete|^0x"),
]


def profile(tessera, scene, spp, freq, work):
    data = os.path.join(work, "perf.data")
    subprocess.run(["perf", "record", "-q", "-F", str(freq), "-o", data, "--", tessera, "render", scene, "-o",
                    os.path.join(work, "out.exr"), "--threads", "1", "--spp", str(spp), "-q"],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    report = subprocess.run(["perf", "report", "-i", data, "--no-children", "--sort", "symbol", "--stdio", "-q",
                             "--percent-limit", "0"], check=True, capture_output=True, text=True).stdout
    rows = []
    for line in report.splitlines():
        m = re.match(r"\s*([0-9.]+)%\s+\[(.)\]\s+(.*\S)", line)
        if m:
            kind, name = m.group(2), re.sub(r"(\s+-)+$", "", m.group(3))  # perf's empty columns after it
            rows.append((float(m.group(1)), "[k] " + name if kind == "k" else name))
    return rows


def run_environment(build):
    """The run's commit, machine, build flags and load, as the other benchmarks' result files record them."""
    here = os.path.dirname(os.path.abspath(__file__))
    git = lambda *args: subprocess.run(["git", "-C", here, *args], capture_output=True, text=True).stdout.strip()
    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--untracked-files=no")
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "unknown")
    cache = {}
    try:
        for line in open(os.path.join(build, "CMakeCache.txt")):
            m = re.match(r"(CMAKE_BUILD_TYPE|CMAKE_CXX_FLAGS_RELEASE|TESSERA_NATIVE):[A-Z]+=(.*)", line)
            if m:
                cache[m.group(1)] = m.group(2)
    except OSError:
        pass
    return [("commit", commit + (" (tracked files modified)" if dirty else " (clean tracked tree)")),
            ("machine", f"{cpu}, nproc {os.cpu_count()}"),
            ("build", f"{cache.get('CMAKE_BUILD_TYPE', '?')}, flags \"{cache.get('CMAKE_CXX_FLAGS_RELEASE', '?')}\" "
                      f"-ffp-contract=off, TESSERA_NATIVE={cache.get('TESSERA_NATIVE', '?')}"),
            ("load", " ".join(open("/proc/loadavg").read().split()[:3]) + " (1, 5, 15 min) at the start")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--freq", type=int, default=4000)
    ap.add_argument("--unmatched", type=int, default=0)
    a = ap.parse_args()
    tessera = os.path.join(a.build, "cli", "tessera")
    scenes_dir = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes")
    names = [p for p, _ in PARTS] + ["other"]
    print(f"render_profile: share of each part in a 1-thread render's perf samples (self time, {a.freq} Hz), {a.spp} spp")
    for key, value in run_environment(a.build):
        print(f"{key + ':':9} {value}")
    print()
    print("| scene | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    unmatched = {}
    with tempfile.TemporaryDirectory(prefix="tessera-profile-") as work:
        for s in a.scenes.split(","):
            shares = dict.fromkeys(names, 0.0)
            rows = profile(tessera, os.path.join(scenes_dir, s + ".json"), a.spp, a.freq, work)
            total = sum(p for p, _ in rows) or 1.0
            for pct, name in rows:
                part = next((p for p, rx in PARTS if re.search(rx, name)), "other")
                shares[part] += 100.0 * pct / total
                if part == "other":
                    unmatched[name] = unmatched.get(name, 0.0) + pct
            print(f"| {s} | " + " | ".join(f"{shares[n]:.1f}" for n in names) + " |")
            sys.stdout.flush()
    if a.unmatched:
        print()
        print("largest functions counted under other (percent of their scene, summed over the scenes):")
        for name, pct in sorted(unmatched.items(), key=lambda kv: -kv[1])[:a.unmatched]:
            print(f"  {pct:6.2f}  {name}")


if __name__ == "__main__":
    main()
