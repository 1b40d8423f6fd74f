"""Headless end-to-end check of the fluidtex Blender add-on, run by Blender:

    blender -b --factory-startup --python-exit-code 1 -P tools/blender_addon/test_addon.py -- \
        ADDON.zip FLUIDTEX WORK RENDERS [--size 256] [--samples 8]

1. installs ADDON.zip and enables it (set BLENDER_USER_SCRIPTS and
   BLENDER_USER_CONFIG to empty folders so nothing of the user's is touched),
2. checks that a missing fluidtex is refused with a clear message,
3. bakes a tiny Mantaflow liquid (a ball of water thrown sideways in a
   2-unit box, resolution 24, frames 1-4, Speed Vectors on),
4. runs *Texture this liquid* on the domain (velocity scale fitted, and
   once more with the attribute taken as is: the known-bad control for the
   fit), then *Import fluidtex result*,
5. checks the imported object's mesh follows the frame, and renders
   (Cycles, CPU) frames 1 and 4; the same two frames with the image node
   holding the one file color.F.png as a still image (the Rust test
   requires identical pixels: the sequence shows file F at frame F; Blender
   updates an image user's frame only in its UI or its renderer, so the
   renderer is where this can be seen headless); frame 4 in the patch view;
   frame 4 without the material (known-bad control: default grey).

Prints one line `fluidtex-addon-test: {json}` with what it found; the Rust
test (crates/fluidtex-cli/tests/blender_addon.rs) reads it and the renders.
Any failed check raises, so Blender exits non-zero.
"""

import argparse
import json
import os
import sys
import time

import addon_utils
import bpy
from mathutils import Vector

FRAMES = (1, 4)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="test_addon.py")
    p.add_argument("zip")
    p.add_argument("fluidtex")
    p.add_argument("work")
    p.add_argument("renders")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--samples", type=int, default=8)
    return p.parse_args(argv)


def check(cond, what):
    if not cond:
        raise AssertionError(what)


def bake_liquid(cache):
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = FRAMES
    scene.frame_set(1)
    bpy.ops.mesh.primitive_cube_add(size=2, location=(0, 0, 0))
    domain = bpy.context.object
    domain.name = "Liquid domain"
    mod = domain.modifiers.new("Fluid", "FLUID")
    mod.fluid_type = "DOMAIN"
    d = mod.domain_settings
    d.domain_type = "LIQUID"
    d.resolution_max = 24
    d.use_mesh = True
    d.use_speed_vectors = True
    # Measured with Blender 3.4.1: with the default formats (OpenVDB data,
    # BOBJ.gz mesh) the mesh velocities are never written and the
    # 'velocity' attribute stays zero; with these two they are.
    d.cache_mesh_format = "OBJECT"
    d.cache_data_format = "UNI"
    d.cache_directory = cache
    d.cache_type = "MODULAR"
    d.cache_frame_start, d.cache_frame_end = FRAMES
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.45, location=(-0.3, 0, 0.3))
    flow = bpy.context.object
    flow.name = "Liquid source"
    fm = flow.modifiers.new("Fluid", "FLUID")
    fm.fluid_type = "FLOW"
    fm.flow_settings.flow_type = "LIQUID"
    fm.flow_settings.flow_behavior = "GEOMETRY"
    fm.flow_settings.use_initial_velocity = True
    fm.flow_settings.velocity_coord = (2.0, 0.0, 0.0)
    flow.hide_render = True
    bpy.context.view_layer.objects.active = domain
    with bpy.context.temp_override(active_object=domain, object=domain):
        check(bpy.ops.fluid.bake_data() == {"FINISHED"}, "bake data")
        check(bpy.ops.fluid.bake_mesh() == {"FINISHED"}, "bake mesh")
    return domain


def setup_render(scene, target, size, samples):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    world = bpy.data.worlds.new("fluidtex test world")
    world.color = (0.05, 0.05, 0.06)
    world.use_nodes = False
    scene.world = world
    lo, hi = bounds(target)
    centre = (lo + hi) / 2
    radius = max((hi - lo).length / 2, 1e-3)
    view = Vector((-0.55, 0.75, -0.6)).normalized()  # looks down at the liquid, +Z up
    cam_data = bpy.data.cameras.new("fluidtex test camera")
    cam_data.angle = 0.6
    cam = bpy.data.objects.new("fluidtex test camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = centre - view * (radius / 0.29)
    cam.rotation_euler = view.to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    sun_data = bpy.data.lights.new("fluidtex test sun", "SUN")
    sun_data.energy = 3.0
    sun = bpy.data.objects.new("fluidtex test sun", sun_data)
    sun.rotation_euler = (0.6, 0.2, 0.3)
    scene.collection.objects.link(sun)


def bounds(ob):
    """World bounding box of `ob` over FRAMES."""
    lo = Vector((1e30,) * 3)
    hi = Vector((-1e30,) * 3)
    for f in FRAMES:
        bpy.context.scene.frame_set(f)
        for c in ob.bound_box:
            w = ob.matrix_world @ Vector(c)
            lo = Vector(map(min, lo, w))
            hi = Vector(map(max, hi, w))
    return lo, hi


def render(scene, frame, path):
    scene.frame_set(frame)
    scene.render.filepath = path
    t = time.time()
    bpy.ops.render.render(write_still=True)
    check(os.path.getsize(path) > 0, f"render {path}")
    return time.time() - t


def main():
    a = parse_args()
    os.makedirs(a.renders, exist_ok=True)
    report = {}
    bpy.ops.wm.read_factory_settings(use_empty=True)

    check(bpy.ops.preferences.addon_install(filepath=a.zip) == {"FINISHED"}, "addon_install")
    addon_utils.enable("fluidtex_blender", default_set=True, handle_error=None)
    import fluidtex_blender as ft

    prefs = bpy.context.preferences.addons["fluidtex_blender"].preferences

    # A missing fluidtex: refused, with a message naming the path.
    prefs.executable = os.path.join(a.work, "no-such-fluidtex")
    try:
        ft.executable()
        check(False, "a missing fluidtex was accepted")
    except ft.FluidtexError as e:
        report["missing_message"] = str(e)
        check("fluidtex not found at" in str(e) and "no-such-fluidtex" in str(e), str(e))
    prefs.executable = a.fluidtex

    t = time.time()
    domain = bake_liquid(os.path.join(a.work, "cache"))
    report["bake_seconds"] = round(time.time() - t, 2)
    scene = bpy.context.scene
    scene.frame_set(2)
    dg = bpy.context.evaluated_depsgraph_get()
    me = domain.evaluated_get(dg).to_mesh()
    speeds = [v.vector.length for v in me.attributes["velocity"].data]
    report["liquid_frame2"] = {"vertices": len(me.vertices), "max_speed": round(max(speeds), 3)}
    domain.evaluated_get(dg).to_mesh_clear()
    check(max(speeds) > 0.1, "Mantaflow wrote no speed vectors")

    s = scene.fluidtex
    s.method = "erosion"
    s.atlas = 256
    s.use_scene_range = True
    s.work_dir = a.work
    s.import_after = False
    # fluidtex failing (here: an exemplar that is not there) cancels the
    # operator with fluidtex's own error line (bpy.ops raises it as a
    # RuntimeError to a script; the Rust test reads it).
    s.exemplar = os.path.join(a.work, "no-such-exemplar.png")
    try:
        with bpy.context.temp_override(active_object=domain, object=domain):
            bpy.ops.fluidtex.texture_liquid()
        check(False, "a failing fluidtex was not reported")
    except RuntimeError as e:
        report["failure_message"] = str(e).strip()
    s.exemplar = ""
    t = time.time()
    with bpy.context.temp_override(active_object=domain, object=domain):
        check(bpy.ops.fluidtex.texture_liquid() == {"FINISHED"}, "Texture this liquid")
    report["texture_seconds"] = round(time.time() - t, 2)
    out = os.path.join(a.work, "out")
    with open(os.path.join(a.work, "velocity_scale.txt")) as f:
        report["velocity_scale"] = float(f.read())
    shares = []
    for f in range(FRAMES[0] + 1, FRAMES[1] + 1):
        with open(os.path.join(out, f"stats.{f:04d}.json")) as st:
            shares.append(json.load(st).get("source_switch_share"))
    report["source_switch_share"] = shares
    # Known-bad control: the attribute taken as world units per second
    # (scale 1) carries the texture too far, so patches switch more.
    s.velocity_auto = False
    s.velocity_scale = 1.0
    s.work_dir = os.path.join(a.work, "unscaled")
    with bpy.context.temp_override(active_object=domain, object=domain):
        check(bpy.ops.fluidtex.texture_liquid() == {"FINISHED"}, "Texture this liquid, unscaled")
    unscaled = []
    for f in range(FRAMES[0] + 1, FRAMES[1] + 1):
        with open(os.path.join(a.work, "unscaled", "out", f"stats.{f:04d}.json")) as st:
            unscaled.append(json.load(st).get("source_switch_share"))
    report["source_switch_share_unscaled"] = unscaled
    s.velocity_auto = True
    s.work_dir = a.work
    for f in range(FRAMES[0], FRAMES[1] + 1):
        for name in (f"mesh.{f:04d}.obj", f"color.{f:04d}.png", f"patches.{f:04d}.png"):
            check(os.path.exists(os.path.join(out, name)), f"{name} missing")

    check(bpy.ops.fluidtex.import_result(directory=out) == {"FINISHED"}, "Import fluidtex result")
    ob = bpy.context.view_layer.objects.active
    check(ob is not None and "fluidtex_dir" in ob, "no imported object")
    mat = ob.active_material
    colour = mat.node_tree.nodes["fluidtex color"]
    follow = {}
    for f in (1, 3, 4):
        scene.frame_set(f)
        follow[f] = {
            "mesh": ob.data.name,
            "triangles": sum(len(p.vertices) - 2 for p in ob.data.polygons),
            "uv_layers": [l.name for l in ob.data.uv_layers],
        }
        check(follow[f]["mesh"].endswith(f":{f:04d}"), f"frame {f}: mesh {follow[f]['mesh']}")
        check(follow[f]["uv_layers"] == ["UVMap"], f"frame {f}: UV layers {follow[f]['uv_layers']}")
    report["follow"] = follow

    # Renders: only the imported result.
    domain.hide_render = True
    setup_render(scene, ob, a.size, a.samples)
    times = {}
    for f in FRAMES:
        times[f"frame{f}"] = render(scene, f, os.path.join(a.renders, f"blender-addon-{f:04d}.png"))
    # The image sequence plays file F at frame F: the same frame rendered
    # with that one file as a still image must give the same pixels.
    sequence = colour.image
    for f in FRAMES:
        still = bpy.data.images.load(os.path.join(out, f"color.{f:04d}.png"))
        colour.image = still
        times[f"still{f}"] = render(scene, f, os.path.join(a.renders, f"still-color-{f:04d}.png"))
        colour.image = sequence
    ob.fluidtex_patch_view = True
    times["patches"] = render(scene, 4, os.path.join(a.renders, "blender-addon-0004-patches.png"))
    ob.fluidtex_patch_view = False
    # Known-bad control: the same frame with no material is default grey.
    scene.frame_set(4)
    saved = list(ob.data.materials)
    ob.data.materials.clear()
    times["control"] = render(scene, 4, os.path.join(a.renders, "control-grey-0004.png"))
    for m in saved:
        ob.data.materials.append(m)
    report["render_seconds"] = {k: round(v, 2) for k, v in times.items()}
    report["state"] = select_by_attribute(a, s)
    report["animated"] = animated_exemplar(a, s)
    print("fluidtex-addon-test: " + json.dumps(report), flush=True)


def grid_at_rest():
    """A 24 x 24 grid with a zero velocity attribute: a liquid at rest."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=24, y_subdivisions=24, size=1.0)
    grid = bpy.context.active_object
    me = grid.data
    vel = me.attributes.new("velocity", "FLOAT_VECTOR", "POINT")
    vel.data.foreach_set("vector", [0.0] * (3 * len(me.vertices)))
    return grid


def select_by_attribute(a, s):
    """Exemplars chosen by a mesh attribute: a grid at rest whose left
    half is hot (temperature 1) and right half cold (0); returns the state
    agreement per frame, and the message of a missing attribute."""
    grid = grid_at_rest()
    me = grid.data
    temp = me.attributes.new("temperature", "FLOAT", "POINT")
    temp.data.foreach_set("value", [1.0 if v.co.x < 0 else 0.0 for v in me.vertices])
    s.use_scene_range = False
    s.frame_start, s.frame_end = 1, 2
    s.velocity_auto = False
    s.velocity_scale = 1.0
    s.work_dir = os.path.join(a.work, "state")
    s.select_by = "age"
    out = {}
    try:
        with bpy.context.temp_override(active_object=grid, object=grid):
            bpy.ops.fluidtex.texture_liquid()
        check(False, "a missing attribute was not reported")
    except RuntimeError as e:
        out["missing_message"] = str(e).strip()
    s.select_by = "temperature"
    with bpy.context.temp_override(active_object=grid, object=grid):
        check(bpy.ops.fluidtex.texture_liquid() == {"FINISHED"}, "Texture by temperature")
    agreement = []
    for f in (1, 2):
        with open(os.path.join(a.work, "state", "out", f"stats.{f:04d}.json")) as st:
            agreement.append(json.load(st).get("state_agreement"))
    out["state_agreement"] = agreement
    s.select_by = ""
    return out


def animated_exemplar(a, s):
    """An animated exemplar through the panel's fields: a grid at rest
    textured with builtin:bubbles at half a frame per frame; returns
    whether the patch view (the sources) stayed put while the colour
    changed, frame to frame, and the command the add-on ran."""
    grid = grid_at_rest()
    s.use_scene_range = False
    s.frame_start, s.frame_end = 1, 3
    s.velocity_auto = False
    s.velocity_scale = 1.0
    s.work_dir = os.path.join(a.work, "animated")
    s.select_by = ""
    s.exemplar = "builtin:bubbles"
    s.exemplar_rate = 0.5
    with bpy.context.temp_override(active_object=grid, object=grid):
        check(bpy.ops.fluidtex.texture_liquid() == {"FINISHED"}, "Texture with bubbles")
    out_dir = os.path.join(a.work, "animated", "out")

    def read(name):
        with open(os.path.join(out_dir, name), "rb") as f:
            return f.read()

    with open(os.path.join(a.work, "animated", "fluidtex.log")) as f:
        said = [line.strip() for line in f if line.startswith("$ ")]
    s.exemplar = ""
    return {
        # Rate 0.5: frames 2 and 3 show different exemplar frames for
        # about half the patches; the sources never move at rest.
        "patches_same": read("patches.0002.png") == read("patches.0003.png"),
        "colour_differs": read("color.0002.png") != read("color.0003.png"),
        "said": said,
    }


try:
    main()
except Exception as e:  # Blender exits 0 on a script error unless told; say why.
    import traceback

    traceback.print_exc()
    print(f"fluidtex-addon-test failed: {e}", flush=True)
    sys.exit(1)
