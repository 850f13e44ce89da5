#!/usr/bin/env python3
"""Writes Tessera's own Cornell box meshes (scenes/assets/cbox/*.obj).

Walls span x, z in [-1, 1] and y in [0, 2]; the box is open towards +z, where the camera is. Every face is
wound so that its geometric normal (cross(p1 - p0, p2 - p0)) points into the room or out of the boxes: the
course format's diffuse surfaces reflect only on the side their normal faces, and emitters emit only there.
Quads are written as OBJ quads (the loader triangulates them), so shared corners are bitwise identical.
"""
import math
import os

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "assets", "cbox")


def fmt(v):
    return "v {:.6f} {:.6f} {:.6f}".format(*[0.0 if abs(c) < 5e-7 else c for c in v])


def write(name, quads, comment):
    verts, faces = [], []
    for q in quads:
        base = len(verts)
        verts.extend(q)
        faces.append([base + i + 1 for i in range(len(q))])
    with open(os.path.join(OUT, name), "w") as f:
        f.write("# Tessera Cornell box: {}\n".format(comment))
        for v in verts:
            f.write(fmt(v) + "\n")
        for fc in faces:
            f.write("f " + " ".join(str(i) for i in fc) + "\n")


def normal(q):
    a, b, c = q[0], q[1], q[2]
    e1 = [b[i] - a[i] for i in range(3)]
    e2 = [c[i] - a[i] for i in range(3)]
    return [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]


def oriented(q, want):
    """Returns quad q wound so its normal points along `want`."""
    n = normal(q)
    return q if sum(n[i] * want[i] for i in range(3)) > 0 else list(reversed(q))


def box(cx, cz, sx, sy, sz, angle_deg):
    """An upright box standing on the floor: footprint sx x sz rotated by angle about +y, height sy, outward faces
    (no bottom face: it rests on the floor)."""
    a = math.radians(angle_deg)
    ca, sa = math.cos(a), math.sin(a)

    def p(x, y, z):
        return [cx + ca * x + sa * z, y, cz - sa * x + ca * z]

    hx, hz = sx / 2, sz / 2
    c = {(i, j, k): p(i * hx, j * sy, k * hz) for i in (-1, 1) for j in (0, 1) for k in (-1, 1)}
    centre = [cx, sy / 2, cz]
    quads = [
        [c[(-1, 1, -1)], c[(1, 1, -1)], c[(1, 1, 1)], c[(-1, 1, 1)]],  # top
        [c[(-1, 0, 1)], c[(1, 0, 1)], c[(1, 1, 1)], c[(-1, 1, 1)]],    # +z side
        [c[(-1, 0, -1)], c[(1, 0, -1)], c[(1, 1, -1)], c[(-1, 1, -1)]],  # -z side
        [c[(1, 0, -1)], c[(1, 0, 1)], c[(1, 1, 1)], c[(1, 1, -1)]],    # +x side
        [c[(-1, 0, -1)], c[(-1, 0, 1)], c[(-1, 1, 1)], c[(-1, 1, -1)]],  # -x side
    ]
    out = []
    for q in quads:
        mid = [sum(v[i] for v in q) / 4 for i in range(3)]
        out.append(oriented(q, [mid[i] - centre[i] for i in range(3)]))
    return out


def main():
    os.makedirs(OUT, exist_ok=True)
    write("floor.obj", [oriented([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], [0, 1, 0])], "floor, y = 0, faces +y")
    write("ceiling.obj", [oriented([[-1, 2, -1], [1, 2, -1], [1, 2, 1], [-1, 2, 1]], [0, -1, 0])],
          "ceiling, y = 2, faces -y")
    write("back.obj", [oriented([[-1, 0, -1], [1, 0, -1], [1, 2, -1], [-1, 2, -1]], [0, 0, 1])],
          "back wall, z = -1, faces +z")
    write("left.obj", [oriented([[-1, 0, -1], [-1, 0, 1], [-1, 2, 1], [-1, 2, -1]], [1, 0, 0])],
          "left wall, x = -1, faces +x")
    write("right.obj", [oriented([[1, 0, -1], [1, 0, 1], [1, 2, 1], [1, 2, -1]], [-1, 0, 0])],
          "right wall, x = 1, faces -x")
    write("light.obj", [oriented([[-0.25, 1.98, -0.2], [0.25, 1.98, -0.2], [0.25, 1.98, 0.2], [-0.25, 1.98, 0.2]],
                                 [0, -1, 0])], "ceiling light, a 0.5 x 0.4 rectangle at y = 1.98 facing down")
    write("light_large.obj", [oriented([[-0.9, 1.98, -0.9], [0.9, 1.98, -0.9], [0.9, 1.98, 0.9], [-0.9, 1.98, 0.9]],
                                       [0, -1, 0])],
          "large ceiling light (a softbox), a 1.8 x 1.8 rectangle at y = 1.98 facing down, 0.1 from the walls")
    write("short_box.obj", box(-0.35, 0.35, 0.6, 0.6, 0.6, -17), "short box, 0.6 high, rotated -17 degrees")
    write("tall_box.obj", box(0.33, -0.3, 0.6, 1.2, 0.6, 20), "tall box, 1.2 high, rotated 20 degrees")


if __name__ == "__main__":
    main()
