#!/usr/bin/python3
"""Cryptomatte decoded independently of Tessera's code, from the public specification: the manifest and the
cryptomatte/<key>/ attributes read with OpenImageIO, each name's id recomputed here (MurmurHash3_x86_32, seed 0,
exponent nudged, bits as float32), and the mattes summed from the rank/coverage channel pairs. Checks that every
named material's matte is 1 exactly where the render's own material_id layer names that material at pixels all of
whose samples reached it, that the object mattes agree with object_id likewise, and that the coverages of every
pixel sum to 1 within 1e-6 (the scene has no background). Usage: cryptomatte_decode.py TESSERA"""
import json
import os
import struct
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from layer_scene import SCENE, write_scene  # noqa: E402

TESSERA = sys.argv[1]


def murmur3_32(data: bytes, seed: int = 0) -> int:
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed
    rounded = len(data) & ~3
    for i in range(0, rounded, 4):
        k = int.from_bytes(data[i:i + 4], "little")
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    k = 0
    tail = data[rounded:]
    if len(tail) >= 3:
        k ^= tail[2] << 16
    if len(tail) >= 2:
        k ^= tail[1] << 8
    if len(tail) >= 1:
        k ^= tail[0]
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    h ^= h >> 16
    return h


def crypto_id(name: str) -> int:
    h = murmur3_32(name.encode())
    exponent = (h >> 23) & 0xFF
    if exponent in (0, 255):
        h ^= 1 << 23
    return h


def as_float(i: int) -> float:
    return struct.unpack("<f", struct.pack("<I", i))[0]


def decode(path, layer):
    """(manifest {name: id}, [(id channel, coverage channel)] by rank) of Cryptomatte layer `layer` in `path`."""
    inp = oiio.ImageInput.open(path)
    assert inp, oiio.geterror()
    spec = inp.spec()
    key = f"{murmur3_32(layer.encode()):08x}"[:7]
    prefix = f"cryptomatte/{key}/"
    assert spec.getattribute(prefix + "name") == layer, f"no {prefix}name for {layer}"
    assert spec.getattribute(prefix + "hash") == "MurmurHash3_32"
    assert spec.getattribute(prefix + "conversion") == "uint32_to_float32"
    manifest = json.loads(spec.getattribute(prefix + "manifest"))
    pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
    inp.close()
    names = list(spec.channelnames)
    ranks = []
    group = 0
    while f"{layer}{group:02d}.R" in names:
        for idc, covc in (("R", "G"), ("B", "A")):
            ranks.append((np.array(pixels[:, :, names.index(f"{layer}{group:02d}.{idc}")]),
                          np.array(pixels[:, :, names.index(f"{layer}{group:02d}.{covc}")])))
        group += 1
    assert len(ranks) >= 6, f"{layer}: {len(ranks)} ranks"
    return manifest, ranks, pixels, names


def matte(ranks, name):
    want = np.float32(as_float(crypto_id(name))).view(np.uint32)
    m = np.zeros(ranks[0][0].shape, dtype=np.float64)
    for ids, cov in ranks:
        m += np.where(ids.astype(np.float32).view(np.uint32) == want, cov, 0.0)
    return m


def check(path, layer, names, id_channel, numbering):
    manifest, ranks, pixels, channels = decode(path, layer)
    assert set(manifest) == set(names), f"{layer} manifest names {sorted(manifest)} vs {sorted(names)}"
    for name, hexid in manifest.items():
        assert int(hexid, 16) == crypto_id(name), f"{layer}: manifest id of {name} is {hexid}"
    ids = np.array(pixels[:, :, channels.index(id_channel)])
    total = sum(cov.astype(np.float64) for _, cov in ranks)
    assert np.all(np.abs(total - 1.0) <= 1e-6), f"{layer}: coverage sums {total.min()}..{total.max()}"
    full_pixels = 0
    for name in names:
        m = matte(ranks, name)
        full = m == 1.0
        full_pixels += int(full.sum())
        assert np.all(ids[full] == numbering[name]), f"{layer}: {name}'s full matte disagrees with {id_channel}"
        # Where the id layer names it and its matte is not full, other names share the pixel.
        assert np.all(m[(ids == numbering[name]) & ~full] < 1.0)
    assert full_pixels > 0.8 * ids.size, f"{layer}: only {full_pixels} of {ids.size} pixels fully covered"
    return full_pixels


def main():
    with tempfile.TemporaryDirectory() as tmp:
        scene = write_scene(tmp)
        out = os.path.join(tmp, "crypto.exr")
        subprocess.run([TESSERA, "render", scene, "-q", "-o", out, "--spp", "16",
                        "--layers", "material_id,object_id,crypto_material,crypto_object"], check=True)
        # Materials are numbered from 1 in the order objects first name them; objects by their index + 1.
        material_numbering = {}
        for o in SCENE["objects"]:
            material_numbering.setdefault(o["material_name"], len(material_numbering) + 1)
        object_numbering = {o["name"]: i + 1 for i, o in enumerate(SCENE["objects"])}
        fm = check(out, "crypto_material", list(material_numbering), "material_id", material_numbering)
        fo = check(out, "crypto_object", list(object_numbering), "object_id", object_numbering)
        print(f"PASS: {fm} pixels of full material coverage, {fo} of full object coverage")


if __name__ == "__main__":
    main()
