#!/usr/bin/env python3
"""Writes the project's Cornell-box scene files (scenes/cbox_*.json) from one description, so the four variants
differ only where they mean to. The JSON files are committed; edit this script and re-run it to change them."""
import copy
import json
import os

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = os.path.join(HERE, "..")

BASE = {
    "integrator": {"type": "intersection_test", "spp": 32, "max_depth": 16,
                   "point_light_position": [0.0, 1.75, 0.9], "point_light_flux": [0.0, 0.0, 0.0]},
    "film": {"resolution": [512, 512]},
    "camera": {"position": [0.0, 1.0, 6.8], "look_at": [0.0, 1.0, 0.0], "ref_up": [0.0, 1.0, 0.0],
               "fov": 19.5, "focal_length": 1.0},
    "textures": {
        "white": {"type": "constant", "color": [0.73, 0.73, 0.73]},
        "red": {"type": "constant", "color": [0.65, 0.05, 0.05]},
        "green": {"type": "constant", "color": [0.12, 0.45, 0.15]},
    },
    "materials": {
        "white": {"type": "diffuse", "texture_name": "white"},
        "red": {"type": "diffuse", "texture_name": "red"},
        "green": {"type": "diffuse", "texture_name": "green"},
    },
    "objects": [
        {"type": "mesh", "path": "assets/cbox/floor.obj", "material_name": "white"},
        {"type": "mesh", "path": "assets/cbox/ceiling.obj", "material_name": "white"},
        {"type": "mesh", "path": "assets/cbox/back.obj", "material_name": "white"},
        {"type": "mesh", "path": "assets/cbox/left.obj", "material_name": "red"},
        {"type": "mesh", "path": "assets/cbox/right.obj", "material_name": "green"},
        {"type": "mesh", "path": "assets/cbox/short_box.obj", "material_name": "white"},
        {"type": "mesh", "path": "assets/cbox/tall_box.obj", "material_name": "white"},
    ],
}

GLASS_SPHERE = {"type": "sphere", "center": [-0.35, 0.95, 0.35], "radius": 0.35, "material_name": "glass"}


def write(name, scene):
    with open(os.path.join(SCENES, name), "w") as f:
        json.dump(scene, f, indent=2)
        f.write("\n")


def main():
    # 1. Point light under the ceiling.
    s = copy.deepcopy(BASE)
    s["integrator"]["point_light_flux"] = [40.0, 32.0, 24.0]
    write("cbox_no_light.json", s)

    # 2. The same plus a glass sphere resting on the short box.
    s = copy.deepcopy(s)
    s["materials"]["glass"] = {"type": "refraction", "eta": 1.5}
    s["objects"].append(GLASS_SPHERE)
    write("cbox_no_light_refraction.json", s)

    # 3. Rectangular ceiling light, soft shadows.
    s = copy.deepcopy(BASE)
    s["film"]["resolution"] = [256, 256]
    s["integrator"]["spp"] = 128
    s["objects"].append({"type": "mesh", "path": "assets/cbox/light.obj",
                         "light": {"type": "area", "radiance": [40.0, 28.0, 10.0]}})
    write("cbox_area_light.json", s)

    # 3b. The same box under a light covering most of the ceiling: the tops of the walls are within 0.1 of its
    #     edge, where sampling the light by area has 1/d^2 spikes (used by the area-light strategy comparison).
    s = copy.deepcopy(s)
    s["objects"][-1] = {"type": "mesh", "path": "assets/cbox/light_large.obj",
                        "light": {"type": "area", "radiance": [2.5, 1.75, 0.625]}}
    write("cbox_large_light.json", s)

    # 4. Lit by a uniform white environment through the open front.
    s = copy.deepcopy(BASE)
    s["integrator"]["spp"] = 128
    s["textures"]["sky_white"] = {"type": "constant", "color": [1.0, 1.0, 1.0]}
    s["environment_map"] = {"texture_name": "sky_white"}
    write("cbox_env_light.json", s)

    # 5. Outdoors under an HDR sky with a small sun 10^4 times brighter than the zenith (assets/sky.exr, written by
    #    make_sky), the worst case for environment sampling: the sun is a few pixels of the map.
    with open(os.path.join(SCENES, "assets", "ground.obj"), "w") as f:
        f.write("# Tessera: a 40 x 40 ground square at y = 0 facing +y, with uvs repeating every 2 units\n")
        f.write("v -20 0 -20\nv -20 0 20\nv 20 0 20\nv 20 0 -20\n")
        f.write("vt 0 0\nvt 0 20\nvt 20 20\nvt 20 0\nf 1/1 2/2 3/3 4/4\n")
    s = {
        "integrator": {"type": "intersection_test", "spp": 64, "max_depth": 16,
                       "point_light_flux": [0.0, 0.0, 0.0]},
        "film": {"resolution": [640, 360]},
        "camera": {"position": [0.0, 1.6, 7.5], "look_at": [0.0, 0.7, 0.0], "ref_up": [0.0, 1.0, 0.0], "fov": 30.0},
        "textures": {
            "sky": {"type": "image", "path": "assets/sky.exr"},
            "ground": {"type": "constant", "color": [0.5, 0.5, 0.5]},
            "clay": {"type": "constant", "color": [0.8, 0.55, 0.4]},
            "white": {"type": "constant", "color": [0.8, 0.8, 0.8]},
        },
        "materials": {
            "ground": {"type": "diffuse", "texture_name": "ground"},
            "clay": {"type": "diffuse", "texture_name": "clay"},
            "white": {"type": "diffuse", "texture_name": "white"},
            "glass": {"type": "refraction", "eta": 1.5},
        },
        "objects": [
            {"type": "mesh", "path": "assets/ground.obj", "material_name": "ground"},
            {"type": "mesh", "path": "assets/cbox/tall_box.obj", "material_name": "white", "translate": [-1.2, 0.0, -0.6]},
            {"type": "sphere", "center": [0.9, 0.7, 0.2], "radius": 0.7, "material_name": "clay"},
            {"type": "sphere", "center": [-0.2, 0.45, 1.3], "radius": 0.45, "material_name": "glass"},
        ],
        "environment_map": {"texture_name": "sky", "scale": 0.3},
    }
    write("sky_sun.json", s)


if __name__ == "__main__":
    main()
