"""Writes the USD fixtures of tests/cli_usd.rs with Pixar's own library.

    python3 -m venv /tmp/usd && /tmp/usd/bin/pip install usd-core
    /tmp/usd/bin/python crates/fluidtex-cli/tests/data/usd/make_usd.py

usd-core 26.x wrote the committed files. The liquid is the library's interop
sphere (crates/fluidtex/tests/data/interop/meshio_ascii.000F.ply, falling
1/16 per frame, with per-vertex velocity), frames 1-3 as time samples of one
Mesh prim /liquid/surface: points, faceVertexCounts, faceVertexIndices and
velocities. Frame 2 drops the last triangle, so the topology is time-sampled
too. falling.usda and falling.usdc hold the same stage as text and binary;
two_meshes.usda adds a second Mesh prim /liquid/splash (one still
triangle) and a Cube /set/box, for --prim.
"""

import os

from pxr import Gf, Usd, UsdGeom, Vt

HERE = os.path.dirname(os.path.abspath(__file__))
INTEROP = os.path.join(HERE, "../../../../fluidtex/tests/data/interop")


def read_ply(path):
    lines = open(path).read().split("\n")
    i, nv, nf, props, cur = 0, 0, 0, [], None
    while lines[i] != "end_header":
        t = lines[i].split()
        if t[:2] == ["element", "vertex"]:
            nv, cur = int(t[2]), "v"
        elif t[:2] == ["element", "face"]:
            nf, cur = int(t[2]), "f"
        elif t and t[0] == "property" and cur == "v":
            props.append(t[-1])
        i += 1
    i += 1
    pts, vel = [], []
    for k in range(nv):
        v = dict(zip(props, map(float, lines[i + k].split())))
        pts.append((v["x"], v["y"], v["z"]))
        vel.append((v["vx"], v["vy"], v["vz"]))
    i += nv
    counts, idx = [], []
    for k in range(nf):
        t = list(map(int, lines[i + k].split()))
        counts.append(t[0])
        idx += t[1 : 1 + t[0]]
    return pts, vel, counts, idx


def write(name, extra):
    stage = Usd.Stage.CreateNew(os.path.join(HERE, name))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    stage.SetTimeCodesPerSecond(24)
    UsdGeom.Xform.Define(stage, "/liquid")
    mesh = UsdGeom.Mesh.Define(stage, "/liquid/surface")
    for f in (1, 2, 3):
        pts, vel, counts, idx = read_ply(os.path.join(INTEROP, f"meshio_ascii.{f:04d}.ply"))
        if f == 2:
            counts, idx = counts[:-1], idx[:-3]
        mesh.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pts]), f)
        mesh.GetVelocitiesAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*v) for v in vel]), f)
        mesh.GetFaceVertexCountsAttr().Set(Vt.IntArray(counts), f)
        mesh.GetFaceVertexIndicesAttr().Set(Vt.IntArray(idx), f)
    if extra:
        splash = UsdGeom.Mesh.Define(stage, "/liquid/splash")
        splash.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 1, 0)]))
        splash.GetFaceVertexCountsAttr().Set(Vt.IntArray([3]))
        splash.GetFaceVertexIndicesAttr().Set(Vt.IntArray([0, 1, 2]))
        UsdGeom.Cube.Define(stage, "/set/box")
    stage.GetRootLayer().Save()


write("falling.usda", False)
write("falling.usdc", False)
write("two_meshes.usda", True)
print("wrote falling.usda, falling.usdc, two_meshes.usda")
