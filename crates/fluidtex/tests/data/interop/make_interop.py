"""Writes the interop test meshes with third-party programs (meshio, trimesh).

Run from this directory:  ../../../../../.venv/bin/python make_interop.py
The files it writes are committed; fluidtex's tests/io_interop.rs reads them
and checks the numbers this script prints (with --print).

Scene: an icosphere (trimesh, 2 subdivisions: 162 vertices, 320 triangles)
falling and spinning about z. Positions and velocities are rounded to
multiples of 1/1024 so that every value is exact in float32 and in any
decimal printing, and tests can compare exactly.
"""
import sys

import meshio
import numpy as np
import trimesh

Q = 1024.0


def q(a):
    return (np.round(np.asarray(a, dtype=np.float64) * Q) / Q).astype(np.float32)


def frame(f):
    s = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    omega = 0.5 * f  # spin grows with the frame number
    p = s.vertices + np.array([0.25, -0.125, 1.0 - 0.0625 * f])
    v = np.stack([-omega * s.vertices[:, 1], omega * s.vertices[:, 0], np.full(len(p), -0.25 * f)], axis=1)
    return q(p), q(v), np.asarray(s.faces, dtype=np.int32)


def main():
    printing = "--print" in sys.argv
    for f in (1, 2, 3):
        p, v, tri = frame(f)
        # meshio, ASCII PLY, velocity as vx vy vz.
        m = meshio.Mesh(p, [("triangle", tri)], point_data={"vx": v[:, 0], "vy": v[:, 1], "vz": v[:, 2]})
        meshio.write(f"meshio_ascii.{f:04d}.ply", m, file_format="ply", binary=False)
        # trimesh, binary little-endian PLY, velocity as velocity_x/y/z.
        t = trimesh.Trimesh(vertices=p, faces=tri, process=False)
        for k, axis in enumerate("xyz"):
            t.vertex_attributes[f"velocity_{axis}"] = v[:, k]
        t.export(f"trimesh_binary.{f:04d}.ply", encoding="binary")
        if printing:
            lo, hi = p.min(axis=0), p.max(axis=0)
            print(f"frame {f}: {len(p)} vertices, {len(tri)} triangles, bbox {lo.tolist()} {hi.tolist()}")
            for i in (0, 17, 161):
                print(f"  vertex {i}: p {p[i].tolist()} v {v[i].tolist()}")
    p, v, tri = frame(2)
    # meshio, binary PLY with Houdini-style v_x names and an extra float64
    # attribute (ignored on read).
    m = meshio.Mesh(
        p,
        [("triangle", tri)],
        point_data={"v_x": v[:, 0], "v_y": v[:, 1], "v_z": v[:, 2], "density": np.linspace(0.0, 1.0, len(p))},
    )
    meshio.write("houdini_style.ply", m, file_format="ply", binary=True)
    # A quad grid (meshio, ASCII PLY) to check polygon triangulation.
    n = 4
    gp = np.array([[i * 0.25, j * 0.25, 0.0] for j in range(n + 1) for i in range(n + 1)], dtype=np.float32)
    gq = np.array([[j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i]
                   for j in range(n) for i in range(n)], dtype=np.int32)
    meshio.write("meshio_quads.ply", meshio.Mesh(gp, [("quad", gq)]), file_format="ply", binary=False)
    # trimesh, OBJ (positions only are read).
    trimesh.Trimesh(vertices=p, faces=tri, process=False).export("trimesh.obj")
    # meshio, legacy VTK: binary 4.2 (splashsurf's layout) and ASCII 5.1.
    mv = meshio.Mesh(p, [("triangle", tri)], point_data={"velocity": v, "id": np.arange(len(p), dtype=np.int32)})
    meshio.vtk.write("meshio_binary_42.vtk", mv, fmt_version="4.2", binary=True)
    meshio.vtk.write("meshio_ascii_51.vtk", mv, fmt_version="5.1", binary=False)
    if printing:
        print("versions: meshio", meshio.__version__, "trimesh", trimesh.__version__, "numpy", np.__version__)


if __name__ == "__main__":
    main()
