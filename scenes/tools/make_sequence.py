#!/usr/bin/env python3
"""Writes a sequence to render: one scene file per frame of a camera move into the Cornell box (scenes/cbox_gi.json,
global illumination, or another scene with --scene), with the meshes it uses copied beside the frames, so the folder
is self-contained: OUT/frame_0001.json ... OUT/frame_NNNN.json and OUT/assets/. The camera swings from the left to
the right of the box's opening while it moves in, looking at the same point throughout.

usage: make_sequence.py OUT [--frames N] [--resolution PX] [--spp S] [--scene FILE]
"""
import argparse
import copy
import json
import math
import os
import shutil

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = os.path.normpath(os.path.join(HERE, ".."))


def camera(base, t):
    """The camera at t in [0, 1]: an arc of -5 to +5 degrees around the look-at point, moving in from the scene's
    distance to 85% of it, a smooth start and stop (smoothstep in t)."""
    s = t * t * (3.0 - 2.0 * t)
    cam = copy.deepcopy(base)
    look = cam["look_at"]
    dx, dy, dz = (cam["position"][i] - look[i] for i in range(3))
    distance = math.sqrt(dx * dx + dz * dz) * (1.0 - 0.15 * s)
    angle = math.radians(-5.0 + 10.0 * s)
    cam["position"] = [round(look[0] + distance * math.sin(angle), 6), round(look[1] + dy, 6),
                       round(look[2] + distance * math.cos(angle), 6)]
    return cam


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", help="folder to write the frames into (created)")
    ap.add_argument("--frames", type=int, default=24, help="number of frames (default 24)")
    ap.add_argument("--resolution", type=int, default=128, help="image edge in pixels (default 128)")
    ap.add_argument("--spp", type=int, default=16, help="samples per pixel (default 16)")
    ap.add_argument("--scene", default=os.path.join(SCENES, "cbox_gi.json"), help="the scene to move through")
    a = ap.parse_args()
    if a.frames < 1 or a.resolution < 1 or a.spp < 1:
        ap.error("--frames, --resolution and --spp must be positive")
    with open(a.scene) as f:
        scene = json.load(f)
    base_dir = os.path.dirname(os.path.abspath(a.scene))
    os.makedirs(a.out, exist_ok=True)
    # Every mesh the scene names, copied to the same relative path under OUT.
    for o in scene.get("objects", []):
        if o.get("type") == "mesh":
            dest = os.path.join(a.out, o["path"])
            os.makedirs(os.path.dirname(dest), exist_ok=True)
            shutil.copyfile(os.path.join(base_dir, o["path"]), dest)
    scene["film"]["resolution"] = [a.resolution, a.resolution]
    scene["integrator"]["spp"] = a.spp
    digits = max(4, len(str(a.frames)))
    for k in range(a.frames):
        frame = copy.deepcopy(scene)
        frame["camera"] = camera(scene["camera"], k / max(1, a.frames - 1))
        path = os.path.join(a.out, "frame_%0*d.json" % (digits, k + 1))
        with open(path, "w") as f:
            json.dump(frame, f, indent=1)
            f.write("\n")
    print("%d frames in %s (frame_%s.json)" % (a.frames, a.out, "#" * digits))


if __name__ == "__main__":
    main()
