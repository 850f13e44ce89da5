#!/usr/bin/env python3
"""Writes the project's scene files (scenes/*.json, and the small meshes they need) from one description, so the
variants differ only where they mean to. The JSON files are committed; edit this script and re-run it to change them."""
import copy
import json
import math
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

    # 6. The box with global illumination: the rectangular ceiling light through the path tracer (MIS), so the
    #    ceiling and the shadowed faces receive light bounced off the walls, with red and green colour bleeding.
    gi = copy.deepcopy(BASE)
    gi["integrator"] = {"type": "path", "profile": "MIS", "spp": 64, "max_depth": 16, "rr_threshold": 0.1,
                        "point_light_flux": [0.0, 0.0, 0.0]}
    gi["film"]["resolution"] = [256, 256]
    gi["objects"].append({"type": "mesh", "path": "assets/cbox/light.obj",
                          "light": {"type": "area", "radiance": [40.0, 28.0, 10.0]}})
    write("cbox_gi.json", gi)

    # 7. A glass sphere (Fresnel reflection and refraction) on the floor of the global-illumination box, beside a
    #    rough gold-coloured metal sphere on the short box.
    s = copy.deepcopy(gi)
    s["materials"]["glass"] = {"type": "glass", "eta": 1.5}
    s["materials"]["gold"] = {"type": "roughconductor", "alpha_x": 0.15, "alpha_y": 0.15,
                              "etaT": [0.143, 0.374, 1.442], "k": [3.983, 2.385, 1.603]}
    s["objects"] = [o for o in s["objects"] if o.get("path") != "assets/cbox/tall_box.obj"]
    s["objects"].append({"type": "sphere", "center": [0.35, 0.4, -0.2], "radius": 0.4, "material_name": "glass"})
    s["objects"].append({"type": "sphere", "center": [-0.35, 0.95, 0.35], "radius": 0.35, "material_name": "gold"})
    write("cbox_glass.json", s)

    # 8. Multiple importance sampling in the spirit of Veach's test scene (own geometry): four metal plates from
    #    near-mirror to rough, each tilted to reflect the row of four spherical lights of equal power but radii from
    #    0.04 to 0.6 towards the camera. Light sampling wins on rough plates and large lights, BSDF sampling on
    #    smooth plates and small lights; MIS combines the two.
    write_veach_scene()


def normalize(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def write_veach_scene():
    camera = [0.0, 2.0, 9.0]
    light_centre = [0.0, 3.6, -2.5]
    plates = [  # (centre, alpha)
        ([0.0, 0.20, 1.6], 0.005),
        ([0.0, 0.60, 0.6], 0.02),
        ([0.0, 1.05, -0.3], 0.06),
        ([0.0, 1.55, -1.1], 0.2),
    ]
    os.makedirs(os.path.join(SCENES, "assets", "veach"), exist_ok=True)
    objects = []
    materials = {"backdrop": {"type": "diffuse", "texture_name": "backdrop"}}
    for i, (c, alpha) in enumerate(plates):
        to_cam = normalize([camera[k] - c[k] for k in range(3)])
        to_light = normalize([light_centre[k] - c[k] for k in range(3)])
        n = normalize([to_cam[k] + to_light[k] for k in range(3)])
        # The plate spans 7 along x and 0.7 along the in-plane direction perpendicular to x.
        ex = [3.5, 0.0, 0.0]
        d = normalize([0.0, n[2], -n[1]])  # perpendicular to x and to n
        ey = [0.35 * d[k] for k in range(3)]
        corners = [[c[k] - ex[k] - ey[k] for k in range(3)], [c[k] + ex[k] - ey[k] for k in range(3)],
                   [c[k] + ex[k] + ey[k] for k in range(3)], [c[k] - ex[k] + ey[k] for k in range(3)]]
        # Wind the face so that its normal is n.
        e1 = [corners[1][k] - corners[0][k] for k in range(3)]
        e2 = [corners[2][k] - corners[0][k] for k in range(3)]
        cr = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
        order = [1, 2, 3, 4] if sum(cr[k] * n[k] for k in range(3)) > 0 else [4, 3, 2, 1]
        path = "assets/veach/plate%d.obj" % i
        with open(os.path.join(SCENES, path), "w") as f:
            f.write("# Tessera: MIS test plate %d (written by scenes/tools/make_scenes.py)\n" % i)
            for v in corners:
                f.write("v %.6f %.6f %.6f\n" % tuple(v))
            f.write("f %d %d %d %d\n" % tuple(order))
        name = "plate%d" % i
        materials[name] = {"type": "roughconductor", "alpha_x": alpha, "alpha_y": alpha,
                           "etaT": [0.2, 0.2, 0.2], "k": [3.6, 3.6, 3.6]}
        objects.append({"type": "mesh", "path": path, "material_name": name})
    objects.append({"type": "mesh", "path": "assets/ground.obj", "material_name": "backdrop",
                    "translate": [0.0, -0.6, 0.0]})
    colours = [[1.0, 0.45, 0.3], [1.0, 0.85, 0.4], [0.45, 1.0, 0.45], [0.4, 0.6, 1.0]]
    for i, r in enumerate([0.04, 0.12, 0.3, 0.6]):
        x = -3.0 + 2.0 * i
        # Equal power: radiance proportional to 1 / r^2.
        radiance = [round(c * 1.5 / (r * r), 4) for c in colours[i]]
        objects.append({"type": "sphere", "center": [x, light_centre[1], light_centre[2]], "radius": r,
                        "light": {"type": "area", "radiance": radiance}})
    s = {
        "integrator": {"type": "path", "profile": "MIS", "spp": 64, "max_depth": 8, "rr_threshold": 0.1,
                       "point_light_flux": [0.0, 0.0, 0.0]},
        "film": {"resolution": [384, 256]},
        "camera": {"position": camera, "look_at": [0.0, 1.4, 0.0], "ref_up": [0.0, 1.0, 0.0], "fov": 36.0},
        "textures": {"backdrop": {"type": "constant", "color": [0.1, 0.1, 0.1]}},
        "materials": materials,
        "objects": objects,
    }
    write("veach_mis.json", s)


if __name__ == "__main__":
    main()
