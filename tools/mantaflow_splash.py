"""Bake a Mantaflow liquid headless and export it as PLY frames: the real
liquids that fluidtex's long-run figures (README, *What the patches hold
over a long run*) and `docs/reproduction.md` are measured on.

    blender -b --factory-startup --python-exit-code 1 --python tools/mantaflow_splash.py -- OUTDIR [--scene splash|viscous|dam] [--res 80] [--frames 60]

`--scene splash` (the default) is described below. `--scene viscous` is a
slow viscous liquid: a ball of honey-like liquid (Mantaflow's viscosity
solver on) dropped on the floor of a 1 x 1 x 1 box, which then creeps and
spreads, the kind of input the 2016 and 2021 papers' viscous drops are.
`--scene dam` is a plain dam break in a 2 x 2 x 2 box (a block of water a
third of the box wide, released at rest against the -x wall).

A dam break (a block of water pushed along +x) and a ball thrown at the far
wall, in a closed 2 x 1 x 1.2 box at 24 fps. At the default resolution 80 it
gives 14k-85k triangles per frame with speeds up to about 10 m/s, and bakes
in about two minutes on 2 cores (Blender 3.4).

Writes OUTDIR/cache (the Mantaflow cache, ~280 MB, deletable),
OUTDIR/mesh/fluid.NNNN.ply (binary little-endian, vertex x y z vx vy vz,
triangles), OUTDIR/counts.txt and OUTDIR/velocity_scale.txt. The export uses
the fluidtex add-on's own evaluate_frame / write_ply / fit_velocity_scale,
so the velocities are scaled exactly as *Texture this liquid* scales them
(the cache settings are the ones the add-on test found to carry mesh
velocities: OBJECT mesh cache, UNI data, speed vectors on).
"""
import argparse
import importlib.util
import math
import os
import statistics
import sys
import time
from array import array

sys.dont_write_bytecode = True  # never write __pycache__ into the add-on tree

import bpy

ADDON = os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "blender_addon", "fluidtex_blender", "__init__.py"
)


def load_addon():
    spec = importlib.util.spec_from_file_location("fluidtex_blender_ro", ADDON)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("out")
    p.add_argument("--scene", choices=("splash", "viscous", "dam"), default="splash")
    p.add_argument("--res", type=int, default=80)
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--mesh-scale", type=int, default=1)
    p.add_argument("--skip-bake", action="store_true")
    return p.parse_args(argv)


def box(name, lo, hi):
    """A mesh box with identity object transform (world coords in the mesh)."""
    bpy.ops.mesh.primitive_cube_add(size=2, location=(0, 0, 0))
    ob = bpy.context.object
    ob.name = name
    for v in ob.data.vertices:
        v.co = [lo[k] if v.co[k] < 0 else hi[k] for k in range(3)]
    ob.data.update()
    return ob


def liquid_source(ob, velocity):
    """Makes `ob` a one-off source of liquid (its volume, at frame 1) moving
    at `velocity`, hidden from renders."""
    fm = ob.modifiers.new("Fluid", "FLUID")
    fm.fluid_type = "FLOW"
    fm.flow_settings.flow_type = "LIQUID"
    fm.flow_settings.flow_behavior = "GEOMETRY"
    fm.flow_settings.use_initial_velocity = True
    fm.flow_settings.velocity_coord = velocity
    ob.hide_render = True


def build(a, cache):
    scene = bpy.context.scene
    # remove the factory cube / camera / light
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    scene.frame_start, scene.frame_end = 1, a.frames
    scene.render.fps, scene.render.fps_base = 24, 1.0
    scene.frame_set(1)

    lo, hi = {
        "splash": ((-1.0, -0.5, 0.0), (1.0, 0.5, 1.2)),
        "viscous": ((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0)),
        "dam": ((-1.0, -1.0, 0.0), (1.0, 1.0, 2.0)),
    }[a.scene]
    domain = box(f"{a.scene.capitalize()} domain", lo, hi)
    mod = domain.modifiers.new("Fluid", "FLUID")
    mod.fluid_type = "DOMAIN"
    d = mod.domain_settings
    d.domain_type = "LIQUID"
    d.resolution_max = a.res
    d.use_mesh = True
    d.mesh_scale = a.mesh_scale
    d.use_speed_vectors = True
    d.cache_mesh_format = "OBJECT"   # needed for mesh velocities (Blender 3.4)
    d.cache_data_format = "UNI"
    d.cache_directory = cache
    d.cache_type = "MODULAR"
    d.cache_frame_start, d.cache_frame_end = 1, a.frames
    # all walls closed (default border collisions)

    if a.scene == "viscous":
        # Honey-like: the viscosity solver with a high value, so the ball
        # slumps and creeps instead of splashing.
        d.use_viscosity = True
        d.viscosity_value = 2.0
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.22, location=(-0.1, 0.0, 0.4))
        blob = bpy.context.object
        blob.name = "Blob"
        bpy.ops.object.transform_apply(location=True, rotation=True, scale=True)
        liquid_source(blob, (0.4, 0.1, 0.0))
        return domain
    if a.scene == "dam":
        liquid_source(box("Dam", (-0.97, -0.97, 0.03), (-0.33, 0.97, 1.4)), (0.0, 0.0, 0.0))
        return domain
    # dam: tall block of water against the -x wall
    liquid_source(box("Dam", (-0.97, -0.47, 0.03), (-0.45, 0.47, 1.0)), (1.5, 0.0, 0.0))

    # a ball thrown at the far (+x) wall from mid-air
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.2, location=(0.2, 0.1, 0.8))
    ball = bpy.context.object
    ball.name = "Ball"
    bpy.ops.object.transform_apply(location=True, rotation=True, scale=True)
    liquid_source(ball, (4.0, -1.0, -1.0))
    return domain


def main():
    a = args()
    out = os.path.abspath(a.out)
    cache = os.path.join(out, "cache")
    mesh_dir = os.path.join(out, "mesh")
    os.makedirs(mesh_dir, exist_ok=True)
    addon = load_addon()
    domain = build(a, cache)
    scene = bpy.context.scene
    bpy.context.view_layer.objects.active = domain
    t0 = time.time()
    if not a.skip_bake:
        with bpy.context.temp_override(active_object=domain, object=domain):
            r = bpy.ops.fluid.bake_data()
            assert r == {"FINISHED"}, r
            t1 = time.time()
            print(f"bake_splash: data baked in {t1 - t0:.1f} s", flush=True)
            r = bpy.ops.fluid.bake_mesh()
            assert r == {"FINISHED"}, r
        t2 = time.time()
        print(f"bake_splash: mesh baked in {t2 - t1:.1f} s (total {t2 - t0:.1f} s)", flush=True)
    t2 = time.time()

    fps = scene.render.fps / scene.render.fps_base
    frames = list(range(1, a.frames + 1))
    data = {}
    for f in frames:
        scene.frame_set(f)
        data[f] = addon.evaluate_frame(domain, bpy.context.evaluated_depsgraph_get(), f)

    # the add-on's fit: first 4 frames; cross-check on later windows
    fits = {}
    for start in (1, 10, 20, 30, 45):
        if start + 3 > a.frames:
            continue
        win = [data[f] for f in range(start, start + 4)]
        fits[start] = addon.fit_velocity_scale(win, fps)
        print(f"bake_splash: fit on frames {start}-{start + 3}: {fits[start]}", flush=True)
    pooled = addon.fit_velocity_scale([data[f] for f in frames], fps, samples=300)
    print(f"bake_splash: fit on all frames (cross-check only): {pooled}", flush=True)
    fit = fits[1]  # what the add-on uses: the first 4 frames
    scale = fit[0] if fit else 1.0
    with open(os.path.join(out, "velocity_scale.txt"), "w") as fh:
        fh.write(f"{scale}\n")
        for s, ft in fits.items():
            fh.write(f"# fit frames {s}-{s + 3}: {ft}\n")
        fh.write(f"# fit all frames: {pooled}\n")

    lines = ["# frame vertices triangles max_speed(units/s) mean_speed raw_max_attr"]
    for f in frames:
        pos, vel, tri = data[f]
        raw = max((math.sqrt(vel[i] ** 2 + vel[i + 1] ** 2 + vel[i + 2] ** 2) for i in range(0, len(vel), 3)), default=0.0)
        if scale != 1.0:
            vel = array("f", (x * scale for x in vel))
        speeds = [math.sqrt(vel[i] ** 2 + vel[i + 1] ** 2 + vel[i + 2] ** 2) for i in range(0, len(vel), 3)]
        addon.write_ply(os.path.join(mesh_dir, f"fluid.{f:04d}.ply"), pos, vel, tri)
        n, t = len(pos) // 3, len(tri) // 3
        mx = max(speeds, default=0.0)
        mean = sum(speeds) / len(speeds) if speeds else 0.0
        lines.append(f"{f} {n} {t} {mx:.4f} {mean:.4f} {raw:.4f}")
    with open(os.path.join(out, "counts.txt"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    tris = [len(data[f][2]) // 3 for f in frames]
    print(f"bake_splash: exported {len(frames)} frames in {time.time() - t2:.1f} s; scale {scale:g}; "
          f"triangles min {min(tris)} median {statistics.median(tris)} max {max(tris)}", flush=True)


main()
