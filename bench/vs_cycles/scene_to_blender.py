"""Builds a Blender/Cycles scene from a Tessera (course JSON) direct-lighting scene.

Runs inside Blender (`blender -b --python ...`). What is matched, and how:
- camera: pinhole, vertical fov, the same eye/forward/up frame (Blender's camera looks down its local -Z with +Y up);
- meshes: the OBJ vertices and faces as they are (no axis conversion, flat shading, the same winding);
- diffuse materials: a Diffuse BSDF (Lambert) with the scene's constant albedo, in scene-linear RGB;
- point light: Tessera's point_light_flux is radiant flux (intensity = flux / (4 pi)); a Cycles point light of
  "power" P watts (radius 0) emits the radiant flux P, so P = flux (POINT_LIGHT_POWER_PER_FLUX = 1, measured: with
  P = pi * flux the converged Cycles image was pi times Tessera's, scale 0.3183);
- area light: an emissive mesh of the same radiance (Emission strength = radiance), made one-sided like Tessera's
  (Cycles' mesh emission is two-sided: the back face gets strength 0 through Geometry > Backfacing);
- Cycles: CPU, 0 bounces (direct light only), no denoising, no adaptive sampling, 1-px box pixel filter, black
  world, fixed thread count, no clamping.
"""
import json
import math
import os

import bpy

POINT_LIGHT_POWER_PER_FLUX = 1.0


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append(tuple(float(x) for x in parts[1:4]))
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                faces.append(tuple(i - 1 if i > 0 else len(verts) + i for i in idx))
    return verts, faces


def _scaled_color(rgb):
    """(color with max 1, strength) so that color * strength == rgb."""
    m = max(rgb)
    if m <= 0.0:
        return (0.0, 0.0, 0.0), 0.0
    return tuple(c / m for c in rgb), m


def _diffuse_material(name, albedo):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*albedo, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _emitter_material(name, radiance):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    color, strength = _scaled_color(radiance)
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (*color, 1.0)
    geometry = nt.nodes.new("ShaderNodeNewGeometry")
    front = nt.nodes.new("ShaderNodeMath")  # 1 - backfacing
    front.operation = "SUBTRACT"
    front.inputs[0].default_value = 1.0
    nt.links.new(geometry.outputs["Backfacing"], front.inputs[1])
    scale = nt.nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = strength
    nt.links.new(front.outputs["Value"], scale.inputs[0])
    nt.links.new(scale.outputs["Value"], emission.inputs["Strength"])
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    return mat


def camera_frame(cam):
    """Tessera's (docs/scene-format.md) camera frame: forward, right, up as tuples."""
    def sub(a, b):
        return tuple(x - y for x, y in zip(a, b))

    def norm(a):
        n = math.sqrt(sum(x * x for x in a))
        return tuple(x / n for x in a)

    def cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

    forward = norm(sub(cam.get("look_at", [0, 0, 0]), cam.get("position", [0, 0, 1])))
    right = norm(cross(forward, cam.get("ref_up", [0, 1, 0])))
    up = cross(right, forward)
    return forward, right, up


def build(scene_path, width, height, threads):
    """Replaces the current Blender scene's content with the Tessera scene; returns the parsed JSON."""
    import mathutils

    with open(scene_path) as f:
        desc = json.load(f)
    folder = os.path.dirname(os.path.abspath(scene_path))
    integ = desc.get("integrator", {})
    if integ.get("type", "intersection_test") != "intersection_test":
        raise ValueError(f"{scene_path}: only the direct-lighting integrator (intersection_test) is converted")
    if "environment_map" in desc:
        raise ValueError(f"{scene_path}: environment maps are not converted")

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    textures = desc.get("textures", {})
    materials = {}
    for name, m in desc.get("materials", {}).items():
        if m.get("type") != "diffuse" or m.get("twosided", False):
            raise ValueError(f"{scene_path}: material {name}: only one-sided diffuse materials are converted")
        tex = textures[m["texture_name"]]
        if tex.get("type") != "constant":
            raise ValueError(f"{scene_path}: texture {m['texture_name']}: only constant textures are converted")
        materials[name] = _diffuse_material(name, tex["color"])

    for i, obj in enumerate(desc.get("objects", [])):
        if obj.get("type") != "mesh":
            raise ValueError(f"{scene_path}: object {i}: only meshes are converted")
        verts, faces = read_obj(os.path.join(folder, obj["path"]))
        mesh = bpy.data.meshes.new(f"mesh{i}")
        mesh.from_pydata(verts, [], faces)
        mesh.update()
        if "light" in obj:
            light = obj["light"]
            if light.get("type") != "area":
                raise ValueError(f"{scene_path}: object {i}: only area lights are converted")
            mesh.materials.append(_emitter_material(f"emitter{i}", light["radiance"]))
        else:
            mesh.materials.append(materials[obj["material_name"]])
        scene.collection.objects.link(bpy.data.objects.new(f"obj{i}", mesh))

    flux = integ.get("point_light_flux", [1.0, 1.0, 1.0])
    if max(flux) > 0.0:
        color, f = _scaled_color(flux)
        ldata = bpy.data.lights.new("point", type="POINT")
        ldata.color = color
        ldata.energy = POINT_LIGHT_POWER_PER_FLUX * f
        ldata.shadow_soft_size = 0.0
        lobj = bpy.data.objects.new("point", ldata)
        lobj.location = integ.get("point_light_position", [0.0, 5.0, 0.0])
        scene.collection.objects.link(lobj)

    cam = desc.get("camera", {})
    forward, right, up = camera_frame(cam)
    cdata = bpy.data.cameras.new("camera")
    cdata.type = "PERSP"
    cdata.sensor_fit = "VERTICAL"
    cdata.angle_y = math.radians(cam.get("fov", 45.0))
    cobj = bpy.data.objects.new("camera", cdata)
    m = mathutils.Matrix.Identity(4)
    for r in range(3):
        m[r][0], m[r][1], m[r][2] = right[r], up[r], -forward[r]
        m[r][3] = cam.get("position", [0, 0, 1])[r]
    cobj.matrix_world = m
    scene.collection.objects.link(cobj)
    scene.camera = cobj

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    scene.world = world

    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.threads_mode = "FIXED"
    r.threads = threads
    r.film_transparent = False
    r.use_persistent_data = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.color_mode = "RGB"
    r.image_settings.exr_codec = "NONE"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0

    c = scene.cycles
    c.device = "CPU"
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.use_preview_denoising = False
    c.max_bounces = 0
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = c.volume_bounces = 0
    c.transparent_max_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.use_animated_seed = False
    scene.view_layers[0].cycles.use_denoising = False
    return desc
