"""Builds a Blender/Cycles scene from a Tessera (course JSON) scene, direct lighting or path tracing.

Runs inside Blender (`blender -b --python ...`). What is matched, and how:
- camera: pinhole, vertical fov, the same eye/forward/up frame (Blender's camera looks down its local -Z with +Y up);
- meshes: the OBJ vertices and faces as they are (no axis conversion, flat shading, the same winding), with the
  OBJ's texture coordinates as the UV map;
- spheres: Cycles has no analytic sphere; a UV sphere mesh of SPHERE_SEGMENTS x SPHERE_RINGS quads, smooth shaded
  (its area is 0.03% below the sphere's, its silhouette within 0.01% of the radius);
- diffuse materials: a Diffuse BSDF (Lambert) with the scene's albedo, in scene-linear RGB; constant textures as a
  colour, image textures as an Image Texture node (linear interpolation, repeat) at Tessera's lookup coordinates
  (s, t) = scale (u, v) + delta with Blender's rows bottom-up (y = 1 - t), checkerboards by math nodes computing
  Tessera's rule exactly (a = |trunc(2 s)| mod 2, b = |trunc(2 t)| mod 2, color0 where a = b);
- glass: a Glass BSDF, sharp distribution, IOR = eta, colour R (refused when R and T differ: Cycles tints both
  alike); both reflect with probability equal to the dielectric Fresnel reflectance and refract otherwise;
- roughconductor: a Glossy BSDF with the Beckmann distribution, roughness sqrt(alpha) (Cycles squares its roughness
  into the distribution's alpha), isotropic only. Cycles 3.4's Glossy BSDF has no conductor Fresnel term: its colour
  is the conductor's reflectance at normal incidence, ((etaT - etaI)^2 + k^2) / ((etaT + etaI)^2 + k^2) per channel,
  times the texture; the two differ where microfacets are seen at grazing angles (Tessera's Fresnel rises towards 1
  there), so scenes with metals agree to a global scale only approximately (their residual is reported);
- point light: Tessera's point_light_flux is radiant flux (intensity = flux / (4 pi)); a Cycles point light of
  "power" P watts (radius 0) emits the radiant flux P, so P = flux (POINT_LIGHT_POWER_PER_FLUX = 1, measured: with
  P = pi * flux the converged Cycles image was pi times Tessera's, scale 0.3183);
- area light: an emissive mesh (or sphere) of the same radiance (Emission strength = radiance), made one-sided like
  Tessera's (Cycles' mesh emission is two-sided: the back face gets strength 0 through Geometry > Backfacing);
- environment: a constant one as the world's Background colour times scale; an image one as an Image Texture node
  looked up at Tessera's equirectangular coordinates (u = atan2(d.x, -d.z) / (2 pi), v = acos(d.y) / pi, v = 0 the
  top row), computed from the ray direction by math nodes; the world is importance-sampled by Cycles (its default);
- integrator: intersection_test as Cycles with 0 bounces (direct light only); path (profile MIS) as Cycles with
  max_depth bounces of every kind (total, diffuse, glossy, transmission; Cycles always combines light sampling and
  BSDF sampling by MIS), caustics on, no glossy filter, no light threshold, its own Russian roulette;
- Cycles: CPU, no denoising, no adaptive sampling, 1-px box pixel filter, fixed thread count, no clamping.
Refused (a clear error): refraction materials (Cycles' Refraction BSDF does not reflect under total internal
reflection), two-sided diffuse, anisotropic roughconductor, NEE/RW profiles, environment transforms.
"""
import json
import math
import os

import bpy

POINT_LIGHT_POWER_PER_FLUX = 1.0
SPHERE_SEGMENTS, SPHERE_RINGS = 256, 128


def read_obj(path):
    """Vertices, faces (vertex indices) and per-face texture coordinate indices (None without vt) of an OBJ file,
    and its texture coordinates."""
    verts, faces, uvs, face_uvs = [], [], [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append(tuple(float(x) for x in parts[1:4]))
            elif parts[0] == "vt":
                uvs.append((float(parts[1]), float(parts[2]) if len(parts) > 2 else 0.0))
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                faces.append(tuple(i - 1 if i > 0 else len(verts) + i for i in idx))
                tidx = [p.split("/")[1] if len(p.split("/")) > 1 and p.split("/")[1] else None for p in parts[1:]]
                face_uvs.append(None if None in tidx else
                                tuple(int(t) - 1 if int(t) > 0 else len(uvs) + int(t) for t in tidx))
    return verts, faces, uvs, face_uvs


def _scaled_color(rgb):
    """(color with max 1, strength) so that color * strength == rgb."""
    m = max(rgb)
    if m <= 0.0:
        return (0.0, 0.0, 0.0), 0.0
    return tuple(c / m for c in rgb), m


def _math(nt, op, a=None, b=None):
    """A Math node computing op(a, b); a and b are sockets or numbers."""
    n = nt.nodes.new("ShaderNodeMath")
    n.operation = op
    for i, v in enumerate((a, b)):
        if v is None:
            continue
        if isinstance(v, (int, float)):
            n.inputs[i].default_value = v
        else:
            nt.links.new(v, n.inputs[i])
    return n.outputs["Value"]


def _image_lookup(nt, image_path, s, t):
    """Colour socket of the image at Tessera's lookup coordinates (s, t) (t = 0 the top row; bilinear, repeating)."""
    img = bpy.data.images.load(image_path, check_existing=True)
    img.colorspace_settings.name = "Non-Color"
    node = nt.nodes.new("ShaderNodeTexImage")
    node.image = img
    node.interpolation = "Linear"
    node.extension = "REPEAT"
    xyz = nt.nodes.new("ShaderNodeCombineXYZ")
    nt.links.new(s, xyz.inputs["X"])
    nt.links.new(_math(nt, "SUBTRACT", 1.0, t), xyz.inputs["Y"])
    nt.links.new(xyz.outputs["Vector"], node.inputs["Vector"])
    return node.outputs["Color"]


def _texture_color(nt, scene_path, folder, textures, name):
    """A colour socket (or an RGB tuple for a constant texture) for texture `name` at the surface's UV."""
    tex = textures[name]
    kind = tex.get("type")
    if kind == "constant":
        return tuple(tex["color"])
    if kind not in ("image", "checkerboard"):
        raise ValueError(f"{scene_path}: texture {name}: type {kind!r} is not converted")
    gen = tex.get("tex_coordinate_generator", {})
    scale, delta = gen.get("scale", [1.0, 1.0]), gen.get("delta", [0.0, 0.0])
    coord = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], sep.inputs["Vector"])
    s = _math(nt, "MULTIPLY_ADD", sep.outputs["X"], scale[0])
    s.node.inputs[2].default_value = delta[0]
    t = _math(nt, "MULTIPLY_ADD", sep.outputs["Y"], scale[1])
    t.node.inputs[2].default_value = delta[1]
    if kind == "image":
        return _image_lookup(nt, os.path.join(folder, tex["path"]), s, t)
    parity = [_math(nt, "MODULO", _math(nt, "ABSOLUTE", _math(nt, "TRUNC", _math(nt, "MULTIPLY", c, 2.0))), 2.0)
              for c in (s, t)]
    same = _math(nt, "COMPARE", parity[0], parity[1])
    same.node.inputs[2].default_value = 0.5
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.inputs["Color1"].default_value = (*tex.get("color1", [0.2, 0.2, 0.2]), 1.0)
    mix.inputs["Color2"].default_value = (*tex.get("color0", [0.4, 0.4, 0.4]), 1.0)
    nt.links.new(same, mix.inputs["Fac"])
    return mix.outputs["Color"]


def _set_color(nt, socket, color):
    if isinstance(color, tuple):
        socket.default_value = (*color, 1.0)
    else:
        nt.links.new(color, socket)


def _new_material(name):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    return mat, nt


def _material(scene_path, folder, textures, name, m):
    kind = m.get("type")
    mat, nt = _new_material(name)
    if kind == "diffuse":
        if m.get("twosided", False):
            raise ValueError(f"{scene_path}: material {name}: two-sided diffuse is not converted")
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        _set_color(nt, bsdf.inputs["Color"], _texture_color(nt, scene_path, folder, textures, m["texture_name"]))
        bsdf.inputs["Roughness"].default_value = 0.0
    elif kind == "glass":
        r, t = m.get("R", [1.0, 1.0, 1.0]), m.get("T", [1.0, 1.0, 1.0])
        if list(r) != list(t):
            raise ValueError(f"{scene_path}: material {name}: glass with R != T is not converted")
        bsdf = nt.nodes.new("ShaderNodeBsdfGlass")
        bsdf.distribution = "SHARP"
        bsdf.inputs["Color"].default_value = (*r, 1.0)
        bsdf.inputs["IOR"].default_value = m.get("eta", 1.5)
    elif kind == "roughconductor":
        ax, ay = m.get("alpha_x", 0.1), m.get("alpha_y", 0.1)
        if ax != ay:
            raise ValueError(f"{scene_path}: material {name}: anisotropic roughconductor is not converted")
        eta_i = m.get("etaI", [1.0, 1.0, 1.0])
        f0 = tuple(((n - e) ** 2 + k * k) / ((n + e) ** 2 + k * k)
                   for n, k, e in zip(m.get("etaT", [1.0, 1.0, 1.0]), m.get("k", [1.0, 1.0, 1.0]), eta_i))
        bsdf = nt.nodes.new("ShaderNodeBsdfGlossy")
        bsdf.distribution = "BECKMANN"
        bsdf.inputs["Roughness"].default_value = math.sqrt(ax)
        if "texture_name" in m:
            tint = _texture_color(nt, scene_path, folder, textures, m["texture_name"])
            if isinstance(tint, tuple):
                bsdf.inputs["Color"].default_value = (*(a * b for a, b in zip(f0, tint)), 1.0)
            else:
                mul = nt.nodes.new("ShaderNodeMixRGB")
                mul.blend_type = "MULTIPLY"
                mul.inputs["Fac"].default_value = 1.0
                mul.inputs["Color1"].default_value = (*f0, 1.0)
                nt.links.new(tint, mul.inputs["Color2"])
                nt.links.new(mul.outputs["Color"], bsdf.inputs["Color"])
        else:
            bsdf.inputs["Color"].default_value = (*f0, 1.0)
    else:
        raise ValueError(f"{scene_path}: material {name}: type {kind!r} is not converted")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _emitter_material(name, radiance):
    mat, nt = _new_material(name)
    color, strength = _scaled_color(radiance)
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (*color, 1.0)
    geometry = nt.nodes.new("ShaderNodeNewGeometry")
    front = _math(nt, "SUBTRACT", 1.0, geometry.outputs["Backfacing"])
    nt.links.new(_math(nt, "MULTIPLY", front, strength), emission.inputs["Strength"])
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    return mat


def _world(scene_path, folder, desc):
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    nt = world.node_tree
    bg = nt.nodes["Background"]
    env = desc.get("environment_map")
    if env is None:
        bg.inputs["Strength"].default_value = 0.0
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        return world
    if "transform" in env:
        raise ValueError(f"{scene_path}: environment_map.transform is not converted")
    bg.inputs["Strength"].default_value = env.get("scale", 1.0)
    tex = desc["textures"][env["texture_name"]]
    if tex.get("type") == "constant":
        bg.inputs["Color"].default_value = (*tex["color"], 1.0)
        return world
    if tex.get("type") != "image":
        raise ValueError(f"{scene_path}: environment texture {env['texture_name']} is not converted")
    coord = nt.nodes.new("ShaderNodeTexCoord")
    d = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["Generated"], d.inputs["Vector"])  # the world's view direction, normalised
    phi = _math(nt, "ARCTAN2", d.outputs["X"], _math(nt, "MULTIPLY", d.outputs["Z"], -1.0))
    u = _math(nt, "DIVIDE", phi, 2.0 * math.pi)  # in (-0.5, 0.5]; the repeating lookup wraps it into [0, 1)
    v = _math(nt, "DIVIDE", _math(nt, "ARCCOSINE", d.outputs["Y"]), math.pi)
    nt.links.new(_image_lookup(nt, os.path.join(folder, tex["path"]), u, v), bg.inputs["Color"])
    return world


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


def object_points(folder, obj):
    """Points whose projections bound the object's image: a mesh's vertices (with translate), a sphere's bounding
    box corners."""
    if obj.get("type") == "sphere":
        c, r = obj.get("center", [0.0, 0.0, 0.0]), obj.get("radius", 1.0)
        return [(c[0] + sx * r, c[1] + sy * r, c[2] + sz * r) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    verts = read_obj(os.path.join(folder, obj["path"]))[0]
    t = obj.get("translate", [0.0, 0.0, 0.0])
    return [tuple(a + b for a, b in zip(v, t)) for v in verts]


def _sphere_mesh(name, center, radius):
    verts, faces = [], []
    for j in range(1, SPHERE_RINGS):
        theta = math.pi * j / SPHERE_RINGS
        for i in range(SPHERE_SEGMENTS):
            phi = 2.0 * math.pi * i / SPHERE_SEGMENTS
            verts.append((center[0] + radius * math.sin(theta) * math.sin(phi), center[1] + radius * math.cos(theta),
                          center[2] - radius * math.sin(theta) * math.cos(phi)))
    top, bottom = len(verts), len(verts) + 1
    verts += [(center[0], center[1] + radius, center[2]), (center[0], center[1] - radius, center[2])]
    ring = lambda j, i: j * SPHERE_SEGMENTS + i % SPHERE_SEGMENTS  # noqa: E731
    for i in range(SPHERE_SEGMENTS):  # counter-clockwise seen from outside
        faces.append((top, ring(0, i + 1), ring(0, i)))
        for j in range(SPHERE_RINGS - 2):
            faces.append((ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), ring(j + 1, i)))
        faces.append((bottom, ring(SPHERE_RINGS - 2, i), ring(SPHERE_RINGS - 2, i + 1)))
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    for p in mesh.polygons:
        p.use_smooth = True
    return mesh


def _obj_mesh(name, path, obj, scene_path, i):
    if "transform" in obj:
        raise ValueError(f"{scene_path}: object {i}: transform is not converted")
    verts, faces, uvs, face_uvs = read_obj(path)
    t = obj.get("translate", [0.0, 0.0, 0.0])
    verts = [tuple(a + b for a, b in zip(v, t)) for v in verts]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    if uvs:
        layer = mesh.uv_layers.new(name="UVMap")
        for poly, fuv in zip(mesh.polygons, face_uvs):
            for k, li in enumerate(poly.loop_indices):
                layer.data[li].uv = uvs[fuv[k]] if fuv else (0.0, 0.0)
    return mesh


def build(scene_path, width, height, threads, desc=None):
    """Replaces the current Blender scene's content with the Tessera scene (desc: its parsed JSON, read from
    scene_path when None; assets are relative to scene_path's folder); returns the description."""
    import mathutils

    if desc is None:
        with open(scene_path) as f:
            desc = json.load(f)
    folder = os.path.dirname(os.path.abspath(scene_path))
    integ = desc.get("integrator", {})
    kind = integ.get("type", "intersection_test")
    if kind in ("path", "bdpt"):
        if integ.get("profile", "MIS") not in ("MIS", "MultipleImportanceSampling"):
            raise ValueError(f"{scene_path}: only the path tracer's MIS profile is converted (Cycles always uses MIS)")
        bounces = integ.get("max_depth", 16)
    elif kind in ("intersection_test", "direct"):
        bounces = 0
    else:
        raise ValueError(f"{scene_path}: integrator {kind!r} is not converted")

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    textures = desc.get("textures", {})
    materials = {}
    for name, m in desc.get("materials", {}).items():
        if kind in ("intersection_test", "direct") and m.get("type") != "diffuse":
            raise ValueError(f"{scene_path}: material {name}: only diffuse materials are converted for direct light")
        materials[name] = _material(scene_path, folder, textures, name, m)

    for i, obj in enumerate(desc.get("objects", [])):
        if obj.get("type") == "sphere":
            mesh = _sphere_mesh(f"mesh{i}", obj.get("center", [0.0, 0.0, 0.0]), obj.get("radius", 1.0))
        elif obj.get("type") == "mesh":
            mesh = _obj_mesh(f"mesh{i}", os.path.join(folder, obj["path"]), obj, scene_path, i)
        else:
            raise ValueError(f"{scene_path}: object {i}: type {obj.get('type')!r} is not converted")
        if "light" in obj:
            light = obj["light"]
            if light.get("type", "area") != "area":
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

    scene.world = _world(scene_path, folder, desc)

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
    c.max_bounces = bounces
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.volume_bounces = 0
    c.transparent_max_bounces = 0
    c.caustics_reflective = c.caustics_refractive = True
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.use_animated_seed = False
    scene.view_layers[0].cycles.use_denoising = False
    return desc
