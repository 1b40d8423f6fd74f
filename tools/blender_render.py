"""Render a fluidtex `mesh.F.obj` (with its MTL and colour atlas) in Blender.

An outside check of the outputs: Blender's own OBJ importer reads the mesh,
the UVs and the `map_Kd` texture, and Cycles (CPU) draws them. If the atlas,
the UVs or the material were wrong, the picture shows it (seams, holes,
stretched or mirrored texture), independently of fluidtex's preview renderer.

The camera copies fluidtex's preview camera (render/camera.rs,
`Camera::framing`): it looks along (-0.45, -0.8, -0.4) at the bounding-box
centre with +Y up and a 35 degree vertical field of view, far enough that the
bounding sphere fits with a 5% margin. So `preview.F.png` (left half) and
this render show the object from the same side, the same way up; a mirrored
or rotated texture shows as a difference.

Usage (Blender 3.4, headless):
    blender -b --factory-startup -P tools/blender_render.py -- MESH.obj OUT.png [--size 512] [--samples 24] [--zoom 1] [--box x0,y0,z0,x1,y1,z1]
or tools/blender_render.sh MESH.obj OUT.png [SIZE [SAMPLES [--zoom Z] [--box ...]]].
With --box every frame of a sequence gets the same camera (close-ups of
consecutive frames, to see whether the texture moves with the liquid).

Exits non-zero when the import lacks what fluidtex wrote: no mesh, no UV
layer, or a material without an image texture feeding its base colour.
"""

import argparse
import math
import sys

import bpy
from mathutils import Matrix, Vector

VIEW_DIR = Vector((-0.45, -0.8, -0.4)).normalized()
FOV_Y_DEGREES = 35.0
BACKGROUND = (0.12, 0.12, 0.14)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="blender_render.py")
    p.add_argument("obj", help="mesh.F.obj written by fluidtex")
    p.add_argument("out", help="output PNG")
    p.add_argument("--size", type=int, default=512, help="image width and height [512]")
    p.add_argument("--samples", type=int, default=24, help="Cycles samples per pixel [24]")
    p.add_argument(
        "--zoom",
        type=float,
        default=1.0,
        help="magnify the centre of the view by this factor, for close-ups of seams [1]",
    )
    p.add_argument(
        "--box",
        help="frame this box (x0,y0,z0,x1,y1,z1) instead of the mesh's bounds: the same "
        "camera for every frame of a sequence, so consecutive frames can be compared",
    )
    return p.parse_args(argv)


def parse_box(text):
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 6 or not all(math.isfinite(x) for x in v):
        fail(f"--box {text}: expected six numbers x0,y0,z0,x1,y1,z1")
    return Vector(v[:3]), Vector(v[3:])


def fail(msg):
    print(f"blender_render: error: {msg}", file=sys.stderr)
    sys.exit(1)


def empty_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)


def import_obj(path):
    before = set(bpy.data.objects)
    # forward Y, up Z: Blender's own axes, so the file's coordinates are kept
    # as they are (the default would turn a Y-up file into Z-up).
    bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z")
    meshes = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    if not meshes:
        fail(f"{path}: Blender imported no mesh")
    return meshes


def check_material(obj):
    """The imported material must take its base colour from an image."""
    if not obj.data.uv_layers:
        fail(f"{obj.name}: no UV layer")
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None or not mat.use_nodes:
            continue
        for node in mat.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                links = node.inputs["Base Color"].links
                if links and links[0].from_node.type == "TEX_IMAGE":
                    image = links[0].from_node.image
                    if image is None or image.size[0] == 0:
                        fail(f"{mat.name}: the texture image did not load")
                    print(
                        f"blender_render: material {mat.name}: base colour from "
                        f"{image.filepath} ({image.size[0]}x{image.size[1]})"
                    )
                    # Lambert-like, as the preview: no highlight to hide the texture.
                    node.inputs["Specular"].default_value = 0.0
                    node.inputs["Roughness"].default_value = 1.0
                    return
    fail(f"{obj.name}: no material with an image texture on its base colour")


def bounds(objects):
    lo = Vector((math.inf,) * 3)
    hi = Vector((-math.inf,) * 3)
    for obj in objects:
        for v in obj.data.vertices:
            p = obj.matrix_world @ v.co
            lo = Vector(map(min, lo, p))
            hi = Vector(map(max, hi, p))
    return lo, hi


def add_camera(lo, hi, zoom):
    centre = 0.5 * (lo + hi)
    radius = 0.5 * (hi - lo).length or 1.0
    half = math.radians(0.5 * FOV_Y_DEGREES)
    distance = 1.05 * radius / math.sin(half)
    eye = centre - VIEW_DIR * distance
    up = Vector((0.0, 0.0, 1.0)) if abs(VIEW_DIR.dot(Vector((0, 1, 0)))) > 0.99 else Vector((0, 1, 0))
    right = VIEW_DIR.cross(up).normalized()
    true_up = right.cross(VIEW_DIR)
    # Blender cameras look down their local -Z with +Y up.
    rot = Matrix((right, true_up, -VIEW_DIR)).transposed()
    cam_data = bpy.data.cameras.new("camera")
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle_y = 2.0 * math.atan(math.tan(half) / zoom)
    cam_data.clip_start = max(distance - 2 * radius, 1e-3) * 0.5
    cam_data.clip_end = distance + 2 * radius
    cam = bpy.data.objects.new("camera", cam_data)
    cam.matrix_world = Matrix.Translation(eye) @ rot.to_4x4()
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    # Headlight: a sun shining along the view direction, as the preview's
    # Lambert term, plus a dim world for the unlit share.
    sun_data = bpy.data.lights.new("sun", type="SUN")
    sun_data.energy = 3.0
    sun = bpy.data.objects.new("sun", sun_data)
    sun.matrix_world = Matrix.Translation(eye) @ rot.to_4x4()
    bpy.context.scene.collection.objects.link(sun)


def setup_render(out, size, samples):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    # Direct light only: a headlight sun is noise-free in Cycles, so few
    # samples give a clean picture (and a small PNG).
    scene.cycles.max_bounces = 0
    scene.render.resolution_x = size
    scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 100
    # Blender dithers 8-bit output by default: noise that triples the PNG.
    scene.render.dither_intensity = 0.0
    scene.view_settings.view_transform = "Standard"
    world = scene.world or bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    # The preview's background is a display (sRGB) value; the world colour
    # is linear.
    linear = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in BACKGROUND]
    bg.inputs["Color"].default_value = (*linear, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    # The world is the backdrop only; it lights nothing (no sampling noise).
    world.cycles_visibility.diffuse = False
    world.cycles_visibility.glossy = False
    world.cycles_visibility.transmission = False
    world.cycles_visibility.scatter = False
    scene.render.filepath = out


def main():
    args = parse_args()
    empty_scene()
    meshes = import_obj(args.obj)
    for obj in meshes:
        check_material(obj)
    lo, hi = parse_box(args.box) if args.box else bounds(meshes)
    verts = sum(len(o.data.vertices) for o in meshes)
    faces = sum(len(o.data.polygons) for o in meshes)
    print(f"blender_render: {args.obj}: {verts} vertices, {faces} faces, bbox {tuple(lo)} {tuple(hi)}")
    add_camera(lo, hi, args.zoom)
    setup_render(args.out, args.size, args.samples)
    bpy.ops.render.render(write_still=True)
    print(f"blender_render: wrote {args.out}")


main()
