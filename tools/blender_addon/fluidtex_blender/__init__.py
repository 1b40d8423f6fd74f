"""fluidtex for Blender: texture a baked liquid, and show the result.

Two operators, in the 3D View's sidebar (N) under *fluidtex*:

* **Texture this liquid** (``fluidtex.texture_liquid``): for every frame of
  the range, exports the active object's *evaluated* mesh (a baked Mantaflow
  liquid domain, or any animated mesh) in world space with its per-vertex
  ``velocity`` attribute to ``WORK/input/fluid.FFFF.ply``, then runs
  ``fluidtex run`` with the panel's options into ``WORK/out``. Progress shows
  in the status bar; a missing or failing ``fluidtex`` is reported in one
  line. Then, unless switched off, imports the result.
* **Import fluidtex result** (``fluidtex.import_result``): one object that
  shows ``mesh.F.obj`` of the current frame, with a material whose Image
  Texture plays ``color.F.png`` as an image sequence in the mesh's atlas UVs,
  extra channels wired in (``displacement`` into the material's displacement,
  ``roughness`` / ``metallic`` into the BSDF, others left as labelled image
  nodes), and a *patch view* toggle that shows ``patches.F.png`` instead.

Why a frame-change handler that swaps mesh data, and not geometry nodes:
every fluidtex frame has a new topology and new UVs, and Blender 3.4's
geometry nodes cannot read a file (no OBJ / PLY import node before 4.x); the
Mesh Sequence Cache modifier reads only Alembic and USD, which Debian's
Blender is built without. A ``frame_change_pre`` handler that assigns the
frame's mesh datablock (read once, then kept) works in every build, in the
viewport and in renders (``blender -b ... -a``), and leaves a plain mesh
object any other add-on or exporter understands.

Pure Python and ``bpy``: Debian's Blender runs the system Python, which has
no numpy, so nothing here needs it.
"""

bl_info = {
    "name": "fluidtex",
    "author": "fluidtex authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D View > Sidebar > fluidtex",
    "description": "Textures that ride a liquid: run fluidtex on a baked liquid and show the result",
    "category": "Animation",
}

import os
import shlex
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from array import array

import bpy
from bpy.app.handlers import persistent
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

METHODS = [
    ("erosion", "Patch erosion", "Patch erosion for deformable lapped textures (default)"),
    ("advect", "Advect", "Patches carried by the flow, no erosion"),
    ("dual-rest", "Dual rest", "Two texture layers reset in turn and cross-faded"),
    ("blend-deformable", "Blend", "Blended deformable patches (baseline)"),
    ("atlas-check", "Atlas check", "World-space checker: shows the atlas and UVs"),
]

# Outputs of `fluidtex run` that are not material channels.
NOT_CHANNELS = {"color", "patches", "switch", "preview", "source", "mesh", "stats"}
MESH_PREFIX = "fluidtex:"
KEEP_MESHES = 32


class FluidtexError(Exception):
    """A problem the user can fix; its text is reported as is."""


# ---------------------------------------------------------------- settings


class FluidtexPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    executable: StringProperty(
        name="fluidtex executable",
        description="Path of the fluidtex program; empty: $FLUIDTEX, then fluidtex on PATH",
        subtype="FILE_PATH",
        default="",
    )

    def draw(self, context):
        self.layout.prop(self, "executable")


class FluidtexSettings(bpy.types.PropertyGroup):
    method: EnumProperty(name="Method", items=METHODS, default="erosion")
    exemplar: StringProperty(
        name="Exemplar",
        description=(
            "Texture image (PNG, JPEG, EXR), an image sequence that animates (bubbles.####.png), "
            "or builtin:bubbles, builtin:glow, builtin:crust; empty: the built-in pebbles"
        ),
        subtype="FILE_PATH",
        default="",
    )
    exemplar_rate: FloatProperty(
        name="Exemplar rate",
        description=(
            "Animated exemplar (an image sequence or builtin:bubbles): exemplar frames shown per "
            "frame of liquid; each patch starts at its own phase"
        ),
        default=1.0,
        min=-1000.0,
        max=1000.0,
    )
    atlas: IntProperty(name="Atlas size", description="Atlas width = height in texels", default=1024, min=16, max=16384)
    radius: FloatProperty(
        name="Patch radius",
        description="Patch radius in world units; 0: fluidtex chooses (1/25 of the bounding-box diagonal)",
        default=0.0,
        min=0.0,
    )
    use_scene_range: BoolProperty(name="Scene frame range", default=True)
    frame_start: IntProperty(name="Start", default=1, min=0)
    frame_end: IntProperty(name="End", default=250, min=0)
    velocity_auto: BoolProperty(
        name="Fit velocity scale",
        description=(
            "Find the factor that turns the velocity attribute into world units per second "
            "from the motion of the surface between the first frames (Mantaflow's is not in those units)"
        ),
        default=True,
    )
    velocity_scale: FloatProperty(
        name="Velocity scale",
        description="Multiplies the velocity attribute to give world units per second (when not fitted)",
        default=1.0,
    )
    work_dir: StringProperty(
        name="Work folder",
        description="Exported PLY go to WORK/input, fluidtex writes WORK/out",
        subtype="DIR_PATH",
        default="//fluidtex/",
    )
    select_by: StringProperty(
        name="Select by attribute",
        description=(
            "A per-vertex float attribute of the liquid mesh (e.g. temperature); empty: one exemplar. "
            "Each of the two exemplars below then shows its range of it, and what no longer matches erodes away"
        ),
        default="",
    )
    state_exemplar_a: StringProperty(
        name="Exemplar A",
        description="Image path or image sequence (####), or builtin:glow, builtin:crust, builtin:pebbles, builtin:bubbles",
        default="builtin:glow",
    )
    state_range_a: FloatVectorProperty(name="Range A", size=2, default=(0.5, 1.0))
    state_exemplar_b: StringProperty(
        name="Exemplar B",
        description="Image path or image sequence (####), or builtin:glow, builtin:crust, builtin:pebbles, builtin:bubbles",
        default="builtin:crust",
    )
    state_range_b: FloatVectorProperty(name="Range B", size=2, default=(0.0, 0.5))
    mismatch_rate: FloatProperty(
        name="Mismatch rate",
        description="Per second: how fast a patch part whose exemplar no longer matches the attribute goes",
        default=1.0,
        min=0.001,
        max=1000.0,
    )
    import_after: BoolProperty(name="Import the result", default=True)
    result_dir: StringProperty(
        name="Result folder", description="An output folder of fluidtex run", subtype="DIR_PATH", default=""
    )


def update_patch_view(ob, _context):
    set_patch_view(ob, ob.fluidtex_patch_view)


def set_patch_view(ob, on):
    for slot in ob.material_slots:
        mat = slot.material
        if mat and mat.node_tree and "fluidtex patch view" in mat.node_tree.nodes:
            mat.node_tree.nodes["fluidtex patch view"].inputs["Fac"].default_value = 1.0 if on else 0.0


# ------------------------------------------------------------------ export


def executable():
    """The fluidtex program, or a FluidtexError that says how to give it."""
    addon = bpy.context.preferences.addons.get(__package__)
    given = addon.preferences.executable if addon else ""
    given = bpy.path.abspath(given) if given else os.environ.get("FLUIDTEX", "")
    if given:
        if os.path.isfile(given) and os.access(given, os.X_OK):
            return given
        raise FluidtexError(f"fluidtex not found at {given}: fix it in Preferences > Add-ons > fluidtex")
    found = shutil.which("fluidtex")
    if not found:
        raise FluidtexError(
            "fluidtex not found: install it (cargo install --path crates/fluidtex-cli) "
            "or set its path in Preferences > Add-ons > fluidtex"
        )
    return found


def work_folder(settings, ob):
    path = settings.work_dir or "//fluidtex/"
    if path.startswith("//") and not bpy.data.filepath:
        # An unsaved file has no folder for "//": use a temporary one.
        return os.path.join(tempfile.gettempdir(), f"fluidtex-{bpy.path.clean_name(ob.name)}")
    return os.path.normpath(bpy.path.abspath(path))


def frame_range(settings, scene):
    if settings.use_scene_range:
        return scene.frame_start, scene.frame_end
    if settings.frame_end < settings.frame_start:
        raise FluidtexError(f"frame range {settings.frame_start}-{settings.frame_end} is empty")
    return settings.frame_start, settings.frame_end


def write_ply(path, positions, velocities, triangles, scalar=None):
    """Binary little-endian PLY: x y z vx vy vz per vertex (then the
    float property `scalar` = (name, values), if given), triangles."""
    n = len(positions) // 3
    t = len(triangles) // 3
    per = 7 if scalar else 6
    vertex = array("f", bytes(4 * per * n))
    for k in range(3):
        vertex[k::per] = positions[k::3]
        vertex[3 + k :: per] = velocities[k::3]
    if scalar:
        vertex[6::per] = scalar[1]
    face = struct.Struct("<B3i")
    faces = bytearray(face.size * t)
    for i in range(t):
        face.pack_into(faces, i * face.size, 3, triangles[3 * i], triangles[3 * i + 1], triangles[3 * i + 2])
    if sys.byteorder != "little":
        vertex.byteswap()
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment written by the fluidtex Blender add-on\n"
        f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float vx\nproperty float vy\nproperty float vz\n"
        + (f"property float {scalar[0]}\n" if scalar else "")
        + f"element face {t}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vertex.tobytes())
        f.write(faces)
    os.replace(tmp, path)


def evaluate_frame(ob, depsgraph, frame):
    """The evaluated mesh of `ob` at the current frame in world space:
    (positions, velocities per second of the attribute's own unit,
    triangles) as flat arrays."""
    ob_eval = ob.evaluated_get(depsgraph)
    mesh = ob_eval.to_mesh()
    try:
        n = len(mesh.vertices)
        attr = mesh.attributes.get("velocity")
        if attr is None or attr.domain != "POINT" or attr.data_type != "FLOAT_VECTOR":
            raise FluidtexError(
                f"{ob.name}, frame {frame}: no per-vertex 'velocity' attribute "
                "(Mantaflow: bake the domain with Mesh and Speed Vectors on, mesh file format Object)"
            )
        positions = array("f", bytes(12 * n))
        mesh.vertices.foreach_get("co", positions)
        velocities = array("f", bytes(12 * n))
        attr.data.foreach_get("vector", velocities)
        mesh.calc_loop_triangles()
        triangles = array("i", bytes(12 * len(mesh.loop_triangles)))
        mesh.loop_triangles.foreach_get("vertices", triangles)
    finally:
        ob_eval.to_mesh_clear()
    m = ob.matrix_world
    identity = all(abs(m[r][c] - (1.0 if r == c else 0.0)) < 1e-12 for r in range(4) for c in range(4))
    if not identity:
        from mathutils import Vector

        lin = m.to_3x3()
        for i in range(n):
            j = 3 * i
            positions[j : j + 3] = array("f", m @ Vector(positions[j : j + 3]))
            velocities[j : j + 3] = array("f", lin @ Vector(velocities[j : j + 3]))
    return positions, velocities, triangles


def evaluate_scalar(ob, depsgraph, frame, name):
    """The per-vertex float attribute `name` of `ob`'s evaluated mesh at
    the current frame, as a flat array (integers and booleans converted)."""
    ob_eval = ob.evaluated_get(depsgraph)
    mesh = ob_eval.to_mesh()
    try:
        attr = mesh.attributes.get(name)
        kinds = {"FLOAT": "value", "INT": "value", "BOOLEAN": "value", "INT8": "value"}
        if attr is None or attr.domain != "POINT" or attr.data_type not in kinds:
            have = sorted(
                a.name
                for a in mesh.attributes
                if a.domain == "POINT" and a.data_type in kinds and not a.name.startswith(".")
            )
            raise FluidtexError(
                f"{ob.name}, frame {frame}: no per-vertex number attribute '{name}' to select by "
                f"(it has: {', '.join(have) if have else 'none'})"
            )
        if attr.data_type == "FLOAT":
            values = array("f", bytes(4 * len(mesh.vertices)))
            attr.data.foreach_get("value", values)
        else:
            values = array("f", (float(d.value) for d in attr.data))
        if any(v != v or v in (float("inf"), float("-inf")) for v in values):
            raise FluidtexError(f"{ob.name}, frame {frame}: attribute '{name}' has a value that is not a number")
        return values
    finally:
        ob_eval.to_mesh_clear()


def exemplar_path(path):
    """An exemplar as fluidtex reads it: built-ins by name, files absolute."""
    return path if path.startswith("builtin:") else bpy.path.abspath(path)


def is_animated(path):
    """Whether fluidtex reads `path` as an animated exemplar: a frame token
    (#, $F or %d) or the built-in bubbles."""
    return path == "builtin:bubbles" or any(t in path for t in ("#", "$F", "%0", "%d"))


def exemplar_args(settings):
    """fluidtex's exemplar flags: by attribute, or the one exemplar; with
    the rate when one of them is animated (fluidtex refuses it otherwise)."""
    if settings.select_by:
        args = state_args(settings)
        paths = [settings.state_exemplar_a, settings.state_exemplar_b]
    elif settings.exemplar:
        args = ["--exemplar", exemplar_path(settings.exemplar)]
        paths = [settings.exemplar]
    else:
        return []
    if any(is_animated(p) for p in paths):
        args += ["--exemplar-rate", f"{settings.exemplar_rate:g}"]
    return args


def state_args(settings):
    """fluidtex's flags of the selection by attribute (empty when off)."""
    if not settings.select_by:
        return []

    def exemplar(path, r):
        path = exemplar_path(path)
        if not (r[0] <= r[1]):
            raise FluidtexError(f"{path}: range {r[0]:g} to {r[1]:g} has its low end above its high end")
        return f"{path}@{r[0]:g}:{r[1]:g}"

    return [
        "--select-by", settings.select_by,
        "--exemplar", exemplar(settings.state_exemplar_a, settings.state_range_a),
        "--exemplar", exemplar(settings.state_exemplar_b, settings.state_range_b),
        "--mismatch-rate", f"{settings.mismatch_rate:g}",
    ]  # fmt: skip


def fit_velocity_scale(frames, fps, samples=1000):
    """The factor s that best carries each frame's surface onto the next:
    vertices of frame k moved by s * velocity / fps land on the surface of
    frame k + 1 (mean distance, Blender's BVH). Only the normal part of the
    motion is seen by this, which is enough to find a unit. `frames` is a
    list of (positions, velocities, triangles) of consecutive frames.
    Returns (s, mean distance at s, mean distance at s = 0) or None when
    the surface does not move measurably."""
    from mathutils import Vector
    from mathutils.bvhtree import BVHTree

    candidates = [0.02 * 1.1**k for k in range(85)]  # 0.02 .. about 68
    error = [0.0] * len(candidates)
    still = 0.0
    count = 0
    for (pa, va, _ta), (pb, _vb, tb) in zip(frames, frames[1:]):
        nb = len(pb) // 3
        if nb == 0 or len(pa) == 0:
            continue
        verts = [tuple(pb[3 * i : 3 * i + 3]) for i in range(nb)]
        polys = [tuple(tb[3 * i : 3 * i + 3]) for i in range(len(tb) // 3)]
        tree = BVHTree.FromPolygons(verts, polys)
        na = len(pa) // 3
        step = max(1, na // samples)
        for i in range(0, na, step):
            p = Vector(pa[3 * i : 3 * i + 3])
            v = Vector(va[3 * i : 3 * i + 3]) / fps
            hit = tree.find_nearest(p)
            still += hit[3] if hit[0] is not None else 0.0
            for k, s in enumerate(candidates):
                hit = tree.find_nearest(p + v * s)
                error[k] += hit[3] if hit[0] is not None else 1e30
            count += 1
    if count == 0:
        return None
    best = min(range(len(candidates)), key=lambda k: error[k])
    # A fit only counts when moving the points explains the next frame
    # clearly better than leaving them in place.
    if error[best] > 0.8 * still:
        return None
    return candidates[best], error[best] / count, still / count


def texture_job(context, ob, settings):
    """The work of *Texture this liquid*, one step per `yield`:
    (fraction done, status text). Raises FluidtexError."""
    exe = executable()
    scene = context.scene
    first, last = frame_range(settings, scene)
    work = work_folder(settings, ob)
    inputs = os.path.join(work, "input")
    out = os.path.join(work, "out")
    os.makedirs(inputs, exist_ok=True)
    os.makedirs(out, exist_ok=True)
    frames = list(range(first, last + 1))
    total = 2 * len(frames)
    keep = scene.frame_current
    fps = scene.render.fps / scene.render.fps_base
    scale = settings.velocity_scale
    try:
        if settings.velocity_auto and len(frames) > 1:
            sample = []
            for f in frames[:4]:
                scene.frame_set(f)
                sample.append(evaluate_frame(ob, context.evaluated_depsgraph_get(), f))
            yield 0.0, "fluidtex: fitting the velocity scale"
            fit = fit_velocity_scale(sample, fps)
            if fit is None:
                print(f"fluidtex: velocity scale not fitted (no measurable motion), using {scale:g}")
            else:
                scale, moved, still = fit
                print(
                    f"fluidtex: velocity scale {scale:.3g} fitted on frames {frames[0]}-{frames[min(3, len(frames) - 1)]} "
                    f"(mean distance to the next surface {still:.4g} in place, {moved:.4g} carried)"
                )
        for k, f in enumerate(frames):
            scene.frame_set(f)
            depsgraph = context.evaluated_depsgraph_get()
            positions, velocities, triangles = evaluate_frame(ob, depsgraph, f)
            if scale != 1.0:
                velocities = array("f", (x * scale for x in velocities))
            scalar = None
            if settings.select_by:
                scalar = (settings.select_by, evaluate_scalar(ob, depsgraph, f, settings.select_by))
            write_ply(os.path.join(inputs, f"fluid.{f:04d}.ply"), positions, velocities, triangles, scalar)
            yield (k + 1) / total, f"fluidtex: exported frame {f} ({k + 1}/{len(frames)})"
    finally:
        scene.frame_set(keep)
    with open(os.path.join(work, "velocity_scale.txt"), "w") as note:
        note.write(f"{scale}\n")

    args = [
        exe, "run",
        "--mesh", os.path.join(inputs, "fluid.####.ply"),
        "--frames", f"{first}-{last}",
        "--out", out,
        "--method", settings.method,
        "--atlas", str(settings.atlas),
        "--fps", str(fps),
        "--quiet",
    ]  # fmt: skip
    args += exemplar_args(settings)
    if settings.radius > 0:
        args += ["--radius", str(settings.radius)]
    log_path = os.path.join(work, "fluidtex.log")
    started = time.time()
    with open(log_path, "w") as log:
        # The command first: the log then says what was run, to rerun it by hand.
        log.write("$ " + shlex.join(args) + "\n")
        log.flush()
        proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        while proc.poll() is None:
            done = finished_frames(out, started)
            yield (len(frames) + done) / total, f"fluidtex: textured {done}/{len(frames)} frames"
            time.sleep(0.1)
    if proc.returncode != 0:
        with open(log_path) as log:
            lines = [l.strip() for l in log if l.strip()]
        last_line = lines[-1] if lines else "(no output)"
        raise FluidtexError(f"fluidtex failed (exit {proc.returncode}): {last_line} [log: {log_path}]")
    yield 1.0, f"fluidtex: {len(frames)} frames textured in {out}"


def finished_frames(out, since):
    n = 0
    for name in os.listdir(out):
        if name.startswith("stats.") and name.endswith(".json"):
            try:
                if os.path.getmtime(os.path.join(out, name)) >= since - 1:
                    n += 1
            except OSError:
                pass
    return n


class FLUIDTEX_OT_texture_liquid(bpy.types.Operator):
    """Export the active liquid with its velocity, run fluidtex on it, import the result"""

    bl_idname = "fluidtex.texture_liquid"
    bl_label = "Texture this liquid"
    bl_options = {"REGISTER"}

    _timer = None
    _job = None

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def execute(self, context):
        # Scripts and `blender -b`: no event loop, so the whole job here.
        try:
            text = ""
            for _fraction, text in texture_job(context, context.active_object, context.scene.fluidtex):
                pass
        except FluidtexError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, text)
        return self.finish(context)

    def invoke(self, context, _event):
        try:
            self._job = texture_job(context, context.active_object, context.scene.fluidtex)
        except FluidtexError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 1000)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self.cleanup(context)
            self.report({"WARNING"}, "fluidtex: cancelled (a running fluidtex keeps going)")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            fraction, text = next(self._job)
        except StopIteration:
            self.cleanup(context)
            return self.finish(context)
        except FluidtexError as e:
            self.cleanup(context)
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        context.window_manager.progress_update(int(1000 * fraction))
        if context.workspace:
            context.workspace.status_text_set(text)
        return {"RUNNING_MODAL"}

    def cleanup(self, context):
        wm = context.window_manager
        if self._timer:
            wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace:
            context.workspace.status_text_set(None)

    def finish(self, context):
        settings = context.scene.fluidtex
        out = os.path.join(work_folder(settings, context.active_object), "out")
        settings.result_dir = out
        if settings.import_after:
            try:
                import_result(context, out)
            except FluidtexError as e:
                self.report({"ERROR"}, str(e))
                return {"CANCELLED"}
        return {"FINISHED"}


# ------------------------------------------------------------------ import


def scan_result(folder):
    """{frame: file-number text} of mesh.F.obj, and the channel names."""
    try:
        names = os.listdir(folder)
    except OSError as e:
        raise FluidtexError(f"{folder}: {e.strerror}") from None
    frames = {}
    channels = set()
    for name in names:
        parts = name.split(".")
        if len(parts) != 3:
            continue
        stem, num, ext = parts
        try:
            f = int(num)
        except ValueError:
            continue
        if stem == "mesh" and ext == "obj":
            frames[f] = num
        elif ext in ("png", "exr") and stem not in NOT_CHANNELS:
            channels.add((stem, ext))
    if not frames:
        raise FluidtexError(f"{folder}: no mesh.F.obj here; give the output folder of fluidtex run")
    return frames, sorted(channels)


def read_obj(path):
    """Positions, faces, per-corner UVs and normals of a fluidtex OBJ."""
    v, vt, vn = [], [], []
    faces, uvs, normals = [], [], []
    try:
        with open(path) as f:
            for line_no, line in enumerate(f, 1):
                if line.startswith("v "):
                    v.append(tuple(map(float, line.split()[1:4])))
                elif line.startswith("vt "):
                    vt.append(tuple(map(float, line.split()[1:3])))
                elif line.startswith("vn "):
                    vn.append(tuple(map(float, line.split()[1:4])))
                elif line.startswith("f "):
                    face = []
                    for corner in line.split()[1:]:
                        idx = corner.split("/")
                        face.append(int(idx[0]) - 1)
                        if len(idx) > 1 and idx[1]:
                            uvs.append(vt[int(idx[1]) - 1])
                        if len(idx) > 2 and idx[2]:
                            normals.append(vn[int(idx[2]) - 1])
                    faces.append(face)
    except (OSError, ValueError, IndexError) as e:
        where = f"line {line_no}" if "line_no" in locals() else "open"
        raise FluidtexError(f"{path}: {where}: {e}") from None
    return v, faces, uvs, normals


def load_mesh(ob, folder, num, material):
    name = f"{MESH_PREFIX}{ob.name}:{num}"
    mesh = bpy.data.meshes.get(name)
    if mesh is not None:
        return mesh
    path = os.path.join(folder, f"mesh.{num}.obj")
    verts, faces, uvs, normals = read_obj(path)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    corners = sum(len(f) for f in faces)
    if len(uvs) == corners:
        layer = mesh.uv_layers.new(name="UVMap")
        layer.data.foreach_set("uv", [c for uv in uvs for c in uv])
    mesh.polygons.foreach_set("use_smooth", [True] * len(mesh.polygons))
    if len(normals) == corners and corners > 0:
        # The OBJ's normals: smooth across the atlas seams, where the
        # vertices are split for the UVs.
        if hasattr(mesh, "use_auto_smooth"):
            mesh.use_auto_smooth = True
        mesh.normals_split_custom_set(normals)
    mesh.materials.append(material)
    mesh.update()
    return mesh


def file_for_frame(frames, frame):
    """The mesh shown at scene frame `frame`: that frame's, else the last
    one before it, else the first."""
    before = [f for f in frames if f <= frame]
    return frames[max(before)] if before else frames[min(frames)]


def show_frame(ob, frame):
    folder = ob.get("fluidtex_dir")
    if not folder or ob.type != "MESH":
        return
    frames = {int(k): v for k, v in ob["fluidtex_frames"].items()}
    num = file_for_frame(frames, frame)
    if ob.data.name == f"{MESH_PREFIX}{ob.name}:{num}":
        return
    material = bpy.data.materials.get(ob.get("fluidtex_material", ""))
    mesh = load_mesh(ob, folder, num, material)
    old = ob.data
    ob.data = mesh
    if old.users == 0 and old.name.startswith(MESH_PREFIX):
        meshes = [m for m in bpy.data.meshes if m.name.startswith(MESH_PREFIX) and m.users == 0]
        if len(meshes) > KEEP_MESHES:
            for m in meshes:
                bpy.data.meshes.remove(m)


@persistent
def on_frame_change(scene, _depsgraph=None):
    for ob in scene.objects:
        if "fluidtex_dir" in ob:
            try:
                show_frame(ob, scene.frame_current)
            except FluidtexError as e:
                print(f"fluidtex: {e}", file=sys.stderr)


def sequence_node(nodes, folder, stem, num, first, last, ext, colour, label):
    path = os.path.join(folder, f"{stem}.{num}.{ext}")
    image = bpy.data.images.load(path, check_existing=True)
    image.source = "SEQUENCE"
    if not colour:
        image.colorspace_settings.name = "Non-Color"
    node = nodes.new("ShaderNodeTexImage")
    node.image = image
    node.label = label
    node.name = label
    # Scene frame F shows file F: Blender plays file (F - start + 1 + offset).
    node.image_user.frame_start = first
    node.image_user.frame_offset = first - 1
    node.image_user.frame_duration = last - first + 1
    node.image_user.use_auto_refresh = True
    return node


def build_material(name, folder, frames, channels):
    first, last = min(frames), max(frames)
    num = frames[first]
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes.get("Principled BSDF")
    out = nodes.get("Material Output")
    uv = nodes.new("ShaderNodeUVMap")
    uv.uv_map = "UVMap"
    colour = sequence_node(nodes, folder, "color", num, first, last, "png", True, "fluidtex color")
    links.new(uv.outputs["UV"], colour.inputs["Vector"])
    mix = nodes.new("ShaderNodeMixRGB")
    mix.name = mix.label = "fluidtex patch view"
    mix.inputs["Fac"].default_value = 0.0
    links.new(colour.outputs["Color"], mix.inputs["Color1"])
    links.new(colour.outputs["Color"], mix.inputs["Color2"])
    if os.path.exists(os.path.join(folder, f"patches.{num}.png")):
        patches = sequence_node(nodes, folder, "patches", num, first, last, "png", True, "fluidtex patches")
        patches.interpolation = "Closest"
        links.new(uv.outputs["UV"], patches.inputs["Vector"])
        links.new(patches.outputs["Color"], mix.inputs["Color2"])
    links.new(mix.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.6
    for stem, ext in channels:
        if not os.path.exists(os.path.join(folder, f"{stem}.{num}.{ext}")):
            continue
        node = sequence_node(nodes, folder, stem, num, first, last, ext, False, f"fluidtex {stem}")
        links.new(uv.outputs["UV"], node.inputs["Vector"])
        socket = stem.replace("_", " ").title()
        if stem == "displacement":
            disp = nodes.new("ShaderNodeDisplacement")
            disp.inputs["Scale"].default_value = 0.05
            links.new(node.outputs["Color"], disp.inputs["Height"])
            links.new(disp.outputs["Displacement"], out.inputs["Displacement"])
        elif socket in bsdf.inputs and bsdf.inputs[socket].type == "VALUE":
            links.new(node.outputs["Color"], bsdf.inputs[socket])
    return mat


def import_result(context, folder):
    folder = os.path.normpath(bpy.path.abspath(folder))
    frames, channels = scan_result(folder)
    base = os.path.basename(os.path.dirname(folder)) if os.path.basename(folder) == "out" else os.path.basename(folder)
    name = f"fluidtex {base}"
    material = build_material(name, folder, frames, channels)
    mesh = bpy.data.meshes.new(f"{name} (empty)")
    ob = bpy.data.objects.new(name, mesh)
    context.scene.collection.objects.link(ob)
    ob["fluidtex_dir"] = folder
    ob["fluidtex_frames"] = {str(f): n for f, n in frames.items()}
    ob["fluidtex_material"] = material.name
    show_frame(ob, context.scene.frame_current)
    if mesh.users == 0:
        bpy.data.meshes.remove(mesh)
    for other in context.view_layer.objects.selected:
        other.select_set(False)
    ob.select_set(True)
    context.view_layer.objects.active = ob
    return ob


class FLUIDTEX_OT_import_result(bpy.types.Operator):
    """Show a fluidtex output folder: one object with mesh.F.obj of the current frame and its atlas"""

    bl_idname = "fluidtex.import_result"
    bl_label = "Import fluidtex result"
    bl_options = {"REGISTER", "UNDO"}

    directory: StringProperty(name="Result folder", subtype="DIR_PATH")

    def invoke(self, context, _event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        folder = self.directory or context.scene.fluidtex.result_dir
        if not folder:
            self.report({"ERROR"}, "no result folder given")
            return {"CANCELLED"}
        try:
            ob = import_result(context, folder)
        except FluidtexError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"fluidtex: {ob.name}: {len(ob['fluidtex_frames'])} frames from {folder}")
        return {"FINISHED"}


# -------------------------------------------------------------------- panel


class FLUIDTEX_PT_panel(bpy.types.Panel):
    bl_label = "fluidtex"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "fluidtex"

    def draw(self, context):
        layout = self.layout
        s = context.scene.fluidtex
        col = layout.column()
        col.prop(s, "method")
        col.prop(s, "exemplar")
        if is_animated(s.exemplar) or (
            s.select_by and (is_animated(s.state_exemplar_a) or is_animated(s.state_exemplar_b))
        ):
            col.prop(s, "exemplar_rate")
        col.prop(s, "select_by")
        if s.select_by:
            box = col.box()
            box.prop(s, "state_exemplar_a")
            box.prop(s, "state_range_a")
            box.prop(s, "state_exemplar_b")
            box.prop(s, "state_range_b")
            box.prop(s, "mismatch_rate")
        col.prop(s, "atlas")
        col.prop(s, "radius")
        col.prop(s, "velocity_auto")
        if not s.velocity_auto:
            col.prop(s, "velocity_scale")
        col.prop(s, "use_scene_range")
        if not s.use_scene_range:
            row = col.row(align=True)
            row.prop(s, "frame_start")
            row.prop(s, "frame_end")
        col.prop(s, "work_dir")
        col.prop(s, "import_after")
        col.operator(FLUIDTEX_OT_texture_liquid.bl_idname, icon="TEXTURE")
        layout.separator()
        layout.operator(FLUIDTEX_OT_import_result.bl_idname, icon="IMPORT")
        ob = context.active_object
        if ob is not None and "fluidtex_dir" in ob:
            layout.prop(ob, "fluidtex_patch_view")


CLASSES = (
    FluidtexPreferences,
    FluidtexSettings,
    FLUIDTEX_OT_texture_liquid,
    FLUIDTEX_OT_import_result,
    FLUIDTEX_PT_panel,
)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.fluidtex = PointerProperty(type=FluidtexSettings)
    bpy.types.Object.fluidtex_patch_view = BoolProperty(
        name="Patch view",
        description="Show one colour per patch (patches.F.png) instead of the texture",
        default=False,
        update=update_patch_view,
    )
    if on_frame_change not in bpy.app.handlers.frame_change_pre:
        bpy.app.handlers.frame_change_pre.append(on_frame_change)


def unregister():
    if on_frame_change in bpy.app.handlers.frame_change_pre:
        bpy.app.handlers.frame_change_pre.remove(on_frame_change)
    del bpy.types.Object.fluidtex_patch_view
    del bpy.types.Scene.fluidtex
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
