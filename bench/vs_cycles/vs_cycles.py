"""Tessera against Blender Cycles at equal error (direct lighting and path tracing). Runs inside Blender:

  blender -b --factory-startup --python-exit-code 1 --python bench/vs_cycles/vs_cycles.py -- --tessera build/cli/tessera

run.sh is the usual entry point. For each scene: converged references of both renderers (their agreement up to a
global scale is reported), a ladder of sample counts for both, alternated, with each rung rendered twice with
independent seeds: relMSE against the converged image = mean over surface pixels and RGB of (I1 - I2)^2 / 2 /
(R^2 + 0.01), R the renderer's own reference (the difference of two independent renders carries no reference noise,
so a modest reference suffices), the sample count each needs for each target relMSE (log-log interpolation,
extrapolated along 1/spp past the last rung), and the time per sample of each (best of N, alternated), giving the
equal-error time ratio Tessera / Cycles.
A scene named NAME@path is rendered with its integrator replaced by the path tracer (MIS, max_depth 16,
rr_threshold 0.1), e.g. cbox_env_light@path for the environment-lit box with global illumination.
"""
import argparse
import datetime
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scene_to_blender  # noqa: E402


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="vs_cycles.py")
    p.add_argument("--tessera", required=True, help="the tessera binary")
    p.add_argument("--repo", default=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    p.add_argument("--scenes", default="cbox_no_light,cbox_area_light,cbox_large_light,cbox_gi,cbox_glass,veach_mis,"
                                       "cbox_env_light@path")
    p.add_argument("--res", type=int, default=128)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--ref-spp", type=int, default=1024)
    p.add_argument("--max-spp", type=int, default=256, help="highest rung of the ladder")
    p.add_argument("--time-spp", type=int, nargs=2, default=[16, 128], help="per-sample time = slope between these")
    p.add_argument("--repeats", type=int, default=3, help="best of N for the timing renders")
    p.add_argument("--targets", default="1e-3,1e-4", help="relMSE targets, comma-separated")
    p.add_argument("--out", help="write the report here as well as to stdout")
    return p.parse_args(argv)


# ---------------------------------------------------------------- images

def read_rgb(path):
    img = bpy.data.images.load(path, check_existing=False)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    px = list(img.pixels[:])
    bpy.data.images.remove(img)
    # Blender's rows run bottom-up for both renderers' files alike; keep RGB.
    return w, h, [px[i:i + 3] for i in range(0, len(px), 4)]


def emitter_mask(desc, folder, w, h):
    """True for surface pixels: False for pixels whose footprint may touch an emitter (its projected bounding box,
    grown by one pixel), since those are dominated by rare hits on the emitter's edges."""
    keep = [True] * (w * h)
    cam = desc.get("camera", {})
    forward, right, up = scene_to_blender.camera_frame(cam)
    pos = cam.get("position", [0, 0, 1])
    t = math.tan(math.radians(cam.get("fov", 45.0)) / 2.0)
    for obj in desc.get("objects", []):
        if "light" not in obj:
            continue
        xs, ys, zs = [], [], []
        for v in scene_to_blender.object_points(folder, obj):
            d = [a - b for a, b in zip(v, pos)]
            z = sum(a * b for a, b in zip(d, forward))
            zs.append(z)
            z = max(z, 1e-6)
            xs.append((sum(a * b for a, b in zip(d, right)) / (z * t * w / h) + 1.0) * 0.5 * w)
            ys.append((sum(a * b for a, b in zip(d, up)) / (z * t) + 1.0) * 0.5 * h)  # from the bottom
        if min(zs) <= 0.0:
            continue  # behind the camera
        for y in range(max(0, int(math.floor(min(ys))) - 1), min(h, int(math.floor(max(ys))) + 2)):
            for x in range(max(0, int(math.floor(min(xs))) - 1), min(w, int(math.floor(max(xs))) + 2)):
                keep[y * w + x] = False
    return keep


def rel_mse(img, ref, keep):
    s, n = 0.0, 0
    for p, r, k in zip(img, ref, keep):
        if k:
            for a, b in zip(p, r):
                s += (a - b) ** 2 / (b * b + 0.01)
                n += 1
    return s / n


def rel_var(img1, img2, ref, keep):
    """relMSE of one render against the converged image, from two independent renders: E[(I1 - I2)^2] / 2 is the
    variance of one; R (a reference) only normalises it."""
    s, n = 0.0, 0
    for p, q, r, k in zip(img1, img2, ref, keep):
        if k:
            for a, b, c in zip(p, q, r):
                s += (a - b) ** 2 / (2.0 * (c * c + 0.01))
                n += 1
    return s / n


def global_scale(tess, cyc, keep):
    """Least-squares s with tess ~ s * cycles over surface pixels, and the relMSE left after scaling."""
    num = den = 0.0
    for a, b, k in zip(tess, cyc, keep):
        if k:
            num += sum(x * y for x, y in zip(a, b))
            den += sum(y * y for y in b)
    s = num / den
    return s, rel_mse([[s * y for y in b] for b in cyc], tess, keep)


# ---------------------------------------------------------------- renderers

class Tessera:
    def __init__(self, binary, scene_path, desc, res, threads, tmp):
        desc = json.loads(json.dumps(desc))
        folder = os.path.dirname(os.path.abspath(scene_path))
        desc["film"]["resolution"] = [res, res]
        for obj in desc["objects"]:
            if "path" in obj:
                obj["path"] = os.path.join(folder, obj["path"])
        self.scene = os.path.join(tmp, "tessera_" + os.path.basename(scene_path))
        with open(self.scene, "w") as f:
            json.dump(desc, f)
        self.binary, self.threads, self.folder, self.tmp = binary, threads, folder, tmp

    def render(self, spp, seed, out):
        cmd = [self.binary, "render", self.scene, "-o", out, "--spp", str(spp), "--seed", str(seed), "--threads",
               str(self.threads), "--quiet", "--asset-root", self.folder]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{r.stderr}")
        m = re.search(r"([0-9.]+)s render", r.stderr)
        return float(m.group(1))


class Cycles:
    def __init__(self, scene_path, desc, res, threads):
        self.desc = scene_to_blender.build(scene_path, res, res, threads, desc)
        self.scene = bpy.context.scene

    def render(self, spp, seed, out):
        self.scene.cycles.samples = spp
        self.scene.cycles.seed = seed
        t0 = time.perf_counter()
        bpy.ops.render.render()
        t = time.perf_counter() - t0
        bpy.data.images["Render Result"].save_render(out, scene=self.scene)
        return t


# ---------------------------------------------------------------- the bench

def spp_at(ladder, target):
    """Samples needed for relMSE = target, interpolated in log-log between the ladder's rungs around it
    (extrapolated along 1/spp from the nearest rung when the ladder does not bracket it)."""
    pts = sorted(ladder)
    for (n0, e0), (n1, e1) in zip(pts, pts[1:]):
        if e0 >= target >= e1 and e0 > e1:
            a = math.log(e0 / target) / math.log(e0 / e1)
            return math.exp(math.log(n0) + a * math.log(n1 / n0)), ""
    n, e = min(pts, key=lambda p: abs(math.log(p[1] / target)))
    return n * e / target, " (extrapolated)"


def load_scene(repo, spec):
    """(path, description) of scene spec NAME or NAME@path (its integrator replaced by the MIS path tracer)."""
    name, _, variant = spec.partition("@")
    path = os.path.join(repo, "scenes", name + ".json")
    with open(path) as f:
        desc = json.load(f)
    if variant == "path":
        integ = desc.setdefault("integrator", {})
        integ.update({"type": "path", "profile": "MIS", "max_depth": 16, "rr_threshold": 0.1})
    elif variant:
        raise ValueError(f"{spec}: unknown variant {variant!r} (known: path)")
    folder = os.path.dirname(path)
    for tex in desc.get("textures", {}).values():
        if "path" in tex:
            tex["path"] = os.path.join(folder, tex["path"])
    return path, desc


def run_scene(args, spec, tmp, log):
    path, desc = load_scene(args.repo, spec)
    name = spec.replace("@", "_")
    tess = Tessera(args.tessera, path, desc, args.res, args.threads, tmp)
    cyc = Cycles(path, desc, args.res, args.threads)
    w = h = args.res
    keep = emitter_mask(cyc.desc, tess.folder, w, h)
    out = lambda who, spp, tag: os.path.join(tmp, f"{name}_{who}_{tag}_{spp}.exr")  # noqa: E731

    t0 = time.perf_counter()
    tr = tess.render(args.ref_spp, 1000, out("t", args.ref_spp, "ref"))
    t1 = time.perf_counter()
    cr = cyc.render(args.ref_spp, 1000, out("c", args.ref_spp, "ref"))
    t2 = time.perf_counter()
    log(f"  references: {args.ref_spp} spp, Tessera {tr:.2f} s render ({t1 - t0:.2f} s wall), "
        f"Cycles {cr:.2f} s render ({t2 - t1:.2f} s wall)")
    _, _, tref = read_rgb(out("t", args.ref_spp, "ref"))
    _, _, cref = read_rgb(out("c", args.ref_spp, "ref"))
    scale, resid = global_scale(tref, cref, keep)
    log(f"  references agree up to a global scale Tessera/Cycles = {scale:.4f} (relMSE after scaling {resid:.2e}); "
        f"{sum(keep)} of {w * h} pixels are surfaces")

    ladders = {"t": [], "c": []}
    spp = 1
    while spp <= args.max_spp:
        row = []
        for who, r in (("t", tess), ("c", cyc)):
            imgs = []
            for seed in (1, 2):
                r.render(spp, seed, out(who, spp, f"lad{seed}"))
                imgs.append(read_rgb(out(who, spp, f"lad{seed}"))[2])
            e = rel_var(imgs[0], imgs[1], tref if who == "t" else cref, keep)
            ladders[who].append((spp, e))
            row.append(e)
        log(f"  {spp:5d} spp: relMSE Tessera {row[0]:.3e}  Cycles {row[1]:.3e}")
        if max(row) < min(args.target_list) / 2:
            break
        spp *= 2

    lo, hi = args.time_spp
    best = {"t": {lo: math.inf, hi: math.inf}, "c": {lo: math.inf, hi: math.inf}}
    for rep in range(args.repeats):
        order = (("t", tess), ("c", cyc)) if rep % 2 == 0 else (("c", cyc), ("t", tess))
        for who, r in order:
            for n in (lo, hi):
                best[who][n] = min(best[who][n], r.render(n, 3 + rep, out(who, n, "time")))
    per = {who: (best[who][hi] - best[who][lo]) / (hi - lo) for who in best}
    log(f"  time per sample (slope {lo}..{hi} spp, best of {args.repeats}): Tessera {per['t'] * 1e3:.3f} ms, "
        f"Cycles {per['c'] * 1e3:.3f} ms; {hi} spp renders: Tessera {best['t'][hi]:.2f} s, Cycles {best['c'][hi]:.2f} s")
    rows = []
    for target in args.target_list:
        need = {who: spp_at(ladders[who], target) for who in ladders}
        tt = {who: need[who][0] * per[who] for who in per}
        rows.append({"scene": spec, "target": target, "scale": scale, "resid": resid, "spp_t": need["t"],
                     "spp_c": need["c"], "per_t": per["t"], "per_c": per["c"], "time_t": tt["t"], "time_c": tt["c"]})
    return rows


def git(args, *cmd):
    try:
        return subprocess.run(["git", "-C", args.repo, *cmd], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "?"


def machine():
    model = "?"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} logical CPUs, load average {os.getloadavg()[0]:.1f} at start"


def build_flags(args):
    cache = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(args.tessera))), "CMakeCache.txt")
    flags = {}
    try:
        with open(cache) as f:
            for line in f:
                for key in ("CMAKE_BUILD_TYPE", "CMAKE_CXX_COMPILER", "CMAKE_CXX_FLAGS_RELEASE", "TESSERA_NATIVE"):
                    if line.startswith(key + ":"):
                        flags[key] = line.split("=", 1)[1].strip()
    except OSError:
        return "? (no CMakeCache.txt next to the binary)"
    return ", ".join(f"{k}={v}" for k, v in flags.items())


def main():
    args = parse_args()
    args.target_list = [float(t) for t in args.targets.split(",")]
    lines = []

    def log(s):
        print(s, flush=True)
        lines.append(s)

    dirty = " (with uncommitted changes)" if git(args, "status", "--porcelain", "--untracked-files=no", "--", ".", ":!bench/results") else ""
    log("vs_cycles: Tessera against Blender Cycles at equal error (direct lighting and path tracing)")
    log(f"date: {datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC")
    log(f"commit: {git(args, 'rev-parse', '--short', 'HEAD')}{dirty}")
    log(f"machine: {machine()}; shared with other jobs, so the renderers alternate and times are best of "
        f"{args.repeats}")
    log(f"tessera build: {build_flags(args)}")
    log(f"blender: {bpy.app.version_string} (Cycles, CPU device), Python {platform.python_version()}")
    log(f"settings: {args.res}x{args.res} px, {args.threads} threads both, references {args.ref_spp} spp "
        f"(seed 1000), ladder 1, 2, 4 ... {args.max_spp} spp rendered twice (seeds 1, 2), target relMSE "
        f"{args.targets} over surface pixels (relMSE against the converged image = mean (I1-I2)^2/2/(R^2+0.01) over "
        f"pixels and RGB, R = the renderer's own reference; past the last rung extrapolated along 1/spp)")
    log(f"point light: Cycles power = {scene_to_blender.POINT_LIGHT_POWER_PER_FLUX:.5f} x Tessera's radiant flux")
    results = []
    with tempfile.TemporaryDirectory(prefix="vs_cycles_") as tmp:
        for name in args.scenes.split(","):
            log(f"{name}:")
            results += run_scene(args, name, tmp, log)
    log("")
    log("| scene | ref scale T/C | target relMSE | spp T | C | ms/sample T | C | time T (s) | C (s) | time ratio T/C |")
    log("|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        log(f"| {r['scene']} | {r['scale']:.4f} | {r['target']:g} | {r['spp_t'][0]:.1f}{r['spp_t'][1]} | "
            f"{r['spp_c'][0]:.1f}"
            f"{r['spp_c'][1]} | {r['per_t'] * 1e3:.3f} | {r['per_c'] * 1e3:.3f} | {r['time_t']:.3f} | "
            f"{r['time_c']:.3f} | {r['time_t'] / r['time_c']:.2f} |")
    if args.out:
        with open(args.out, "w") as f:
            f.write("\n".join(lines) + "\n")


main()
