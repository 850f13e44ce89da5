"""The scene the layer tests render: a refracting ball and a diffuse ball on a floor before a wall inside a dome,
every object named, under a point light (direct integrator, fast). Shared by exr_layers.py and cryptomatte_decode.py."""
import json
import os

SCENE = {
    "integrator": {"type": "intersection_test", "spp": 8, "point_light_position": [0, 4, 3],
                   "point_light_flux": [80, 80, 80]},
    "film": {"resolution": [48, 32]},
    "camera": {"position": [0, 1, 5], "look_at": [0, 0.6, 0], "fov": 40},
    "textures": {"grey": {"type": "constant", "color": [0.6, 0.6, 0.6]},
                 "red": {"type": "constant", "color": [0.7, 0.1, 0.1]},
                 "checks": {"type": "checkerboard", "color0": [0.8, 0.8, 0.8], "color1": [0.2, 0.3, 0.5]}},
    "materials": {"floor_mat": {"type": "diffuse", "texture_name": "checks"},
                  "wall_mat": {"type": "diffuse", "texture_name": "grey"},
                  "red_mat": {"type": "diffuse", "texture_name": "red"},
                  "glass_mat": {"type": "refraction", "eta": 1.5}},
    "objects": [
        {"type": "sphere", "name": "floor", "center": [0, -1000, 0], "radius": 1000, "material_name": "floor_mat"},
        {"type": "sphere", "name": "wall", "center": [0, 0, -1003], "radius": 1000, "material_name": "wall_mat"},
        {"type": "sphere", "name": "red_ball", "center": [-0.8, 0.5, 0], "radius": 0.5, "material_name": "red_mat"},
        {"type": "sphere", "name": "glass_ball", "center": [0.8, 0.5, 0.3], "radius": 0.5,
         "material_name": "glass_mat"},
        # Around everything, so that no ray (through the glass ball either) leaves the scene.
        {"type": "sphere", "name": "dome", "center": [0, 0, 0], "radius": 50, "material_name": "wall_mat"},
    ],
}

ALL_LAYERS = "albedo,normal,depth,position,material_id,object_id,variance,crypto_material,crypto_object"


def write_scene(folder):
    path = os.path.join(folder, "layers.json")
    with open(path, "w") as f:
        json.dump(SCENE, f)
    return path
