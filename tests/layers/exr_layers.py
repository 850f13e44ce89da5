#!/usr/bin/python3
"""`tessera render --layers` and `tessera merge` as compositors see them: the channel names (albedo.R/G/B, N.X/Y/Z,
P.X/Y/Z, Z, ids, variance, Cryptomatte) read by OpenImageIO and listed by OpenEXR's `exrheader`, one part per layer
with --multipart, and crops (single- and multi-part) merged back bitwise equal to the whole render in every
channel. Usage: exr_layers.py TESSERA"""
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from layer_scene import ALL_LAYERS, write_scene  # noqa: E402

TESSERA = sys.argv[1]
EXPECTED = ["R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "Z", "P.X", "P.Y", "P.Z",
            "material_id", "object_id", "variance.R", "variance.G", "variance.B", "samples"]
EXPECTED += [f"crypto_{k}0{g}.{c}" for k in ("material", "object") for g in range(3) for c in "RGBA"]
PARTS = {"rgba": ["R", "G", "B"], "albedo": ["albedo.R", "albedo.G", "albedo.B"], "normal": ["N.X", "N.Y", "N.Z"],
         "depth": ["Z"], "position": ["P.X", "P.Y", "P.Z"], "material_id": ["material_id"],
         "object_id": ["object_id"], "variance": ["variance.R", "variance.G", "variance.B", "samples"],
         "crypto_material": [f"crypto_material0{g}.{c}" for g in range(3) for c in "RGBA"],
         "crypto_object": [f"crypto_object0{g}.{c}" for g in range(3) for c in "RGBA"]}


def run(*args):
    subprocess.run([TESSERA, *args], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def channels(path):
    """{channel name: float32 array (height x width)} of every part of an EXR, read with OpenImageIO."""
    inp = oiio.ImageInput.open(path)
    assert inp, oiio.geterror()
    out = {}
    sub = 0
    while inp.seek_subimage(sub, 0):
        spec = inp.spec()
        pixels = inp.read_image(sub, 0, 0, spec.nchannels, oiio.FLOAT)
        for i, name in enumerate(spec.channelnames):
            assert name not in out, f"{path}: channel {name} twice"
            out[name] = np.array(pixels[:, :, i])
        sub += 1
    inp.close()
    return out


def part_names(path):
    inp = oiio.ImageInput.open(path)
    names = []
    sub = 0
    while inp.seek_subimage(sub, 0):
        names.append((inp.spec().getattribute("oiio:subimagename") or inp.spec().getattribute("name"),
                      list(inp.spec().channelnames)))
        sub += 1
    inp.close()
    return names


def same_bits(a, b, what):
    assert set(a) == set(b), f"{what}: channels {sorted(a)} vs {sorted(b)}"
    for name in a:
        x, y = a[name].view(np.uint32), b[name].view(np.uint32)
        assert x.shape == y.shape and np.array_equal(x, y), f"{what}: channel {name} differs"


def main():
    with tempfile.TemporaryDirectory() as tmp:
        scene = write_scene(tmp)
        single = os.path.join(tmp, "single.exr")
        multi = os.path.join(tmp, "multi.exr")
        run("render", scene, "-q", "-o", single, "--layers", ALL_LAYERS)
        run("render", scene, "-q", "-o", multi, "--layers", ALL_LAYERS, "--multipart")

        # One part with every channel, as OpenImageIO and exrheader see it.
        spec = oiio.ImageInput.open(single).spec()
        assert sorted(spec.channelnames) == sorted(EXPECTED), f"channels: {list(spec.channelnames)}"
        header = subprocess.run(["exrheader", single], check=True, capture_output=True, text=True).stdout
        for name in EXPECTED:
            assert f"\n    {name}, 32-bit floating-point" in header, f"exrheader does not list {name}:\n{header}"
        for attr in ("/name", "/hash", "/conversion", "/manifest"):
            assert header.count(attr + " (type string)") == 2, f"exrheader: cryptomatte {attr}:\n{header}"

        # The values make sense: unit-length normals where every sample hit, integral ids, depth within the scene.
        c = channels(single)
        n = np.sqrt(c["N.X"] ** 2 + c["N.Y"] ** 2 + c["N.Z"] ** 2)
        assert np.all(n <= 1.0 + 1e-5), "a normal longer than 1"
        assert np.all(c["material_id"] == np.round(c["material_id"])) and c["material_id"].max() == 3.0
        assert set(np.unique(c["object_id"]).tolist()) <= {1.0, 2.0, 3.0, 5.0}, np.unique(c["object_id"])
        assert np.all((c["Z"] > 0) & (c["Z"] < 10)), "depth out of the scene"
        assert np.all(c["samples"] == 8)
        assert np.all((c["albedo.R"] >= 0) & (c["albedo.R"] <= 0.8 + 1e-6))

        # One part per layer with --multipart, the same bits.
        parts = part_names(multi)
        assert [p[0] for p in parts] == list(PARTS), f"parts: {parts}"
        for name, chans in parts:
            assert sorted(chans) == sorted(PARTS[name]), f"part {name}: {chans}"
        listing = subprocess.run(["exrheader", multi], check=True, capture_output=True, text=True).stdout
        for name in PARTS:
            assert f'name (type string): "{name}"' in listing, f"exrheader does not list part {name}"
        same_bits(c, channels(multi), "multipart")

        # Crops, some single-part and some multi-part, merged (to one part and to parts) equal the whole render.
        crops = [("a.exr", ["0", "0", "20", "32"], []), ("b.exr", ["20", "0", "48", "13"], ["--multipart"]),
                 ("c.exr", ["20", "13", "48", "32"], [])]
        for name, crop, extra in crops:
            run("render", scene, "-q", "-o", os.path.join(tmp, name), "--layers", ALL_LAYERS, "--crop", *crop, *extra)
        tiles = [os.path.join(tmp, name) for name, _, _ in crops]
        run("merge", *tiles, "-o", os.path.join(tmp, "merged.exr"))
        run("merge", *tiles, "-o", os.path.join(tmp, "merged_multi.exr"), "--multipart")
        same_bits(c, channels(os.path.join(tmp, "merged.exr")), "merged")
        same_bits(c, channels(os.path.join(tmp, "merged_multi.exr")), "merged to parts")
        assert [p[0] for p in part_names(os.path.join(tmp, "merged_multi.exr"))] == list(PARTS)

        # Layers never change the colour.
        plain = os.path.join(tmp, "plain.exr")
        run("render", scene, "-q", "-o", plain)
        p = channels(plain)
        same_bits(p, {k: c[k] for k in ("R", "G", "B")}, "colour with and without layers")
    print("PASS")


if __name__ == "__main__":
    main()
