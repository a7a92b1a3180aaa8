# Blender (headless) reads kinesplat's exports and says what it made of them, as one JSON file.
#
#   blender -b --factory-startup -noaudio --python tests/gltf/blender/import_check.py -- \
#       --out REPORT.json [--glb AVATAR.glb] [--bvh MOTION.bvh --bvh-frames 0,5,9]
#       [--render OUT.png --action walk --frame 16 --width 256 --height 384 [--camera CAM.json]
#        [--light FLAT|STUDIO]]
#       [--no-numpy-patch]
#
# The report goes to --out (Blender prints a lot on stdout): for the GLB, what
# bpy.ops.import_scene.gltf made (armatures with their bones, mesh objects with vertex / face
# counts, vertex groups and colour attributes, actions with their frame ranges and key counts, NLA
# tracks, every other object, the importer's own output and the time it took); for the BVH, what
# bpy.ops.import_anim.bvh made (bones, the action's frame range and key count) and, at the given
# BVH frames, each bone's local rotation in the BVH file's own convention (see bvh_rotations);
# optionally a Workbench render of the imported GLB posed by one of its animations.
#
# Debian 12's Blender 3.4.1 with Debian's numpy 1.24.2 (python3-numpy, which the glTF importer
# needs and the blender package does not pull in): the glTF importer
# (io_scene_gltf2/blender/imp/gltf2_blender_mesh.py) creates an array with dtype=np.bool, an alias
# numpy 1.24 removed, so every mesh import fails with "AttributeError: module 'numpy' has no
# attribute 'bool'" (only the armature gets made). Setting numpy.bool = bool (what the alias
# always was) before the import makes it work: checked on 2026-12-03 (--no-numpy-patch
# reproduces the failure). Its BVH importer opens files with mode 'rU', which Python 3.11 refuses:
# see import_bvh.
import json
import math
import os
import sys
import tempfile
import time
import traceback

import bpy
from mathutils import Matrix, Vector


def parse_args(argv):
    args = {"out": None, "glb": None, "bvh": None, "bvh_frames": [], "render": None,
            "action": None, "frame": 0, "width": 256, "height": 384, "numpy_patch": True,
            "light": "FLAT", "camera": None}
    i = 0
    while i < len(argv):
        a = argv[i]
        def value():
            if i + 1 >= len(argv):
                raise SystemExit("import_check.py: %s needs a value" % a)
            return argv[i + 1]
        if a == "--out":
            args["out"] = value(); i += 1
        elif a == "--glb":
            args["glb"] = value(); i += 1
        elif a == "--bvh":
            args["bvh"] = value(); i += 1
        elif a == "--bvh-frames":
            args["bvh_frames"] = [int(x) for x in value().split(",") if x]; i += 1
        elif a == "--render":
            args["render"] = value(); i += 1
        elif a == "--action":
            args["action"] = value(); i += 1
        elif a == "--frame":
            args["frame"] = int(value()); i += 1
        elif a == "--width":
            args["width"] = int(value()); i += 1
        elif a == "--height":
            args["height"] = int(value()); i += 1
        elif a == "--camera":
            args["camera"] = value(); i += 1
        elif a == "--light":
            args["light"] = value(); i += 1
        elif a == "--no-numpy-patch":
            args["numpy_patch"] = False
        else:
            raise SystemExit("import_check.py: unknown argument " + a)
        i += 1
    if not args["out"]:
        raise SystemExit("import_check.py: --out REPORT.json is required")
    return args


class CaptureOutput:
    """Everything written to file descriptors 1 and 2 (Python's prints and Blender's C-level
    reports alike) while inside the block, kept in .text."""

    def __enter__(self):
        sys.stdout.flush()
        sys.stderr.flush()
        self.tmp = tempfile.TemporaryFile(mode="w+b")
        self.saved = (os.dup(1), os.dup(2))
        os.dup2(self.tmp.fileno(), 1)
        os.dup2(self.tmp.fileno(), 2)
        return self

    def __exit__(self, *exc):
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(self.saved[0], 1)
        os.dup2(self.saved[1], 2)
        os.close(self.saved[0])
        os.close(self.saved[1])
        self.tmp.seek(0)
        self.text = self.tmp.read().decode("utf-8", "replace")
        self.tmp.close()
        return False


def clear_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def glb_json(path):
    """The GLB's JSON chunk (for the animations' fps and frame counts in their extras)."""
    import struct
    with open(path, "rb") as f:
        head = f.read(20)
        length, kind = struct.unpack("<II", head[12:20])
        if kind != 0x4E4F534A:
            return {}
        return json.loads(f.read(length).decode("utf-8"))


def action_report(action):
    keys = set()
    counts = set()
    for fc in action.fcurves:
        counts.add(len(fc.keyframe_points))
        for k in fc.keyframe_points:
            keys.add(round(k.co[0], 4))
    return {
        "name": action.name,
        "frame_range": [float(action.frame_range[0]), float(action.frame_range[1])],
        "fcurves": len(action.fcurves),
        "key_times": len(keys),  # distinct key times over all its curves
        "keys_per_fcurve": sorted(counts),
        "groups": len(action.groups),
    }


def object_report(ob):
    r = {"name": ob.name, "type": ob.type, "parent": ob.parent.name if ob.parent else None}
    if ob.animation_data:
        ad = ob.animation_data
        r["action"] = ad.action.name if ad.action else None
        r["nla_tracks"] = [{"name": t.name, "mute": t.mute,
                            "strips": [s.action.name for s in t.strips if s.action]}
                           for t in ad.nla_tracks]
    if ob.type == "ARMATURE":
        r["bone_count"] = len(ob.data.bones)
        r["bones"] = [b.name for b in ob.data.bones]
        r["bone_parents"] = {b.name: (b.parent.name if b.parent else None) for b in ob.data.bones}
    elif ob.type == "MESH":
        me = ob.data
        r["mesh_name"] = me.name
        r["vertices"] = len(me.vertices)
        # Vertices at distinct positions (a UV atlas copies vertices on chart borders).
        r["distinct_positions"] = len({(round(v.co.x, 6), round(v.co.y, 6), round(v.co.z, 6))
                                       for v in me.vertices})
        r["edges"] = len(me.edges)
        r["loose_edges"] = sum(1 for e in me.edges if e.is_loose)
        r["polygons"] = len(me.polygons)
        r["vertex_groups"] = len(ob.vertex_groups)
        r["vertex_group_names"] = [g.name for g in ob.vertex_groups]
        r["color_attributes"] = [{"name": c.name, "domain": c.domain, "data_type": c.data_type}
                                 for c in me.color_attributes]
        r["has_color"] = len(me.color_attributes) > 0
        r["attributes"] = sorted(a.name for a in me.attributes)
        r["uv_layers"] = [u.name for u in me.uv_layers]
        r["materials"] = []
        for m in me.materials:
            if m is None:
                continue
            images = []
            if m.use_nodes and m.node_tree:
                images = [n.image.name for n in m.node_tree.nodes
                          if n.type == "TEX_IMAGE" and n.image]
            r["materials"].append({"name": m.name, "images": images})
        r["modifiers"] = [{"type": md.type, "object": getattr(md, "object", None) and md.object.name}
                          for md in ob.modifiers]
        # Vertices that carry a weight in at least one group (the skin reached every vertex?).
        weighted = 0
        for v in me.vertices:
            if any(g.weight > 0 for g in v.groups):
                weighted += 1
        r["weighted_vertices"] = weighted
        bb = [ob.matrix_world @ Vector(c) for c in ob.bound_box]
        r["bbox_min"] = [min(p[i] for p in bb) for i in range(3)]
        r["bbox_max"] = [max(p[i] for p in bb) for i in range(3)]
    return r


def import_glb(path):
    clear_scene()
    before = set(bpy.data.objects)
    t0 = time.monotonic()
    with CaptureOutput() as cap:
        try:
            result = sorted(bpy.ops.import_scene.gltf(filepath=path))
            error = None
        except Exception:
            result = ["EXCEPTION"]
            error = traceback.format_exc()
    seconds = time.monotonic() - t0
    new = [ob for ob in bpy.data.objects if ob not in before]
    lines = [l for l in cap.text.splitlines() if l.strip()]
    rep = {
        "file": path,
        "result": result,
        "error": error,
        "import_seconds": seconds,
        "importer_output": lines[-60:],
        "warnings": [l for l in lines
                     if any(w in l.lower() for w in ("warn", "error", "not supported",
                                                     "unsupported", "extension"))][:40],
        "objects": [object_report(ob) for ob in new],
        "actions": [action_report(a) for a in bpy.data.actions],
    }
    rep["armatures"] = [o for o in rep["objects"] if o["type"] == "ARMATURE"]
    rep["meshes"] = [o for o in rep["objects"] if o["type"] == "MESH"]
    rep["other_objects"] = [{"name": o["name"], "type": o["type"]} for o in rep["objects"]
                            if o["type"] not in ("ARMATURE", "MESH")]
    rep["point_clouds"] = [o["name"] for o in rep["objects"] if o["type"] == "POINTCLOUD"]
    return rep


def bvh_rotations(arm, frames, conv):
    """Each bone's local rotation at each BVH frame in the BVH file's own convention.

    The importer makes bone j's rest matrix B_j from its head -> tail direction and keys the pose
    basis P_j = B_j^-1 R_j B_j, R_j the BVH joint's local rotation (the product of its rotation
    channels), in the file's axes; it then rotates the armature by the axis conversion C (BVH Y up
    to Blender Z up) and applies it to the rest pose. Evaluated by Blender at frame f, a pose
    bone's armature-space matrix is M_j = G_j C B_j with G_j the accumulated rotation of the chain
    (in Blender's axes), so G_j = M_j (C B_j)^-1 = M_j L_j^-1 with L_j the bone's final rest
    matrix_local, and the local rotation in the BVH's axes is C^-1 G_parent^-1 G_j C."""
    scene = bpy.context.scene
    frame_start = int(round(arm.animation_data.action.frame_range[0]))
    out = {}
    cinv = conv.inverted()
    for f in frames:
        # The importer keys BVH frame f (0-based) at frame_start + f.
        scene.frame_set(frame_start + f)
        bpy.context.view_layer.update()
        g = {}
        per_bone = {}
        for pb in arm.pose.bones:
            g[pb.name] = pb.matrix.to_3x3() @ pb.bone.matrix_local.to_3x3().inverted()
        for pb in arm.pose.bones:
            gl = g[pb.name]
            if pb.parent:
                gl = g[pb.parent.name].inverted() @ gl
            r = cinv @ gl @ conv
            q = r.to_quaternion()
            e = r.to_euler("XYZ")  # R = Rz Ry Rx, the channels' order kinesplat writes
            per_bone[pb.name] = {
                "matrix": [list(row) for row in r],
                "quat_wxyz": [q.w, q.x, q.y, q.z],
                "zyx_degrees": [math.degrees(e.z), math.degrees(e.y), math.degrees(e.x)],
                "location": list(pb.matrix.to_translation()),
            }
        out[str(f)] = per_bone
    return out


def import_bvh(path, frames):
    clear_scene()
    from bpy_extras.io_utils import axis_conversion
    # The operator's defaults: forward -Z, up Y (a Y-up file), NATIVE rotation mode (each bone
    # keeps its channels' Euler order), frame_start 1, no fps scaling.
    conv = axis_conversion(from_forward="-Z", from_up="Y").to_3x3()
    # Blender 3.4.1's BVH importer opens the file with mode 'rU'; Python 3.11 (Debian 12's, which
    # Debian's Blender runs on) removed the 'U' flag ("ValueError: invalid mode: 'rU'"). Text mode
    # already reads every newline convention, so the importer module gets an open() without it.
    import builtins
    import io_anim_bvh.import_bvh as importer
    importer.open = lambda file, mode="r", *a, **k: builtins.open(file, mode.replace("U", ""),
                                                                  *a, **k)
    t0 = time.monotonic()
    with CaptureOutput() as cap:
        try:
            result = sorted(bpy.ops.import_anim.bvh(filepath=path))
            error = None
        except Exception:
            result = ["EXCEPTION"]
            error = traceback.format_exc()
    seconds = time.monotonic() - t0
    rep = {"file": path, "result": result, "error": error, "import_seconds": seconds,
           "importer_output": [l for l in cap.text.splitlines() if l.strip()][-30:],
           "axis_conversion": [list(r) for r in conv]}
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    if not arms:
        return rep
    arm = arms[0]
    rep["armature"] = arm.name
    rep["bone_count"] = len(arm.data.bones)
    rep["bones"] = [b.name for b in arm.data.bones]
    rep["rotation_modes"] = sorted(set(pb.rotation_mode for pb in arm.pose.bones))
    # How far Blender's bone rest matrices are from orthonormal (float32 in its bone
    # construction); the importer's conjugation B^-1 R B carries this into the pose.
    worst = 0.0
    for b in arm.data.bones:
        m = b.matrix_local.to_3x3()
        e = m.transposed() @ m
        worst = max([worst] + [abs(e[i][k] - (1.0 if i == k else 0.0))
                               for i in range(3) for k in range(3)])
    rep["rest_orthonormality_error"] = worst
    act = arm.animation_data.action if arm.animation_data else None
    if act:
        rep["action"] = action_report(act)
        rep["frames"] = rep["action"]["key_times"]
        rep["rotations"] = bvh_rotations(arm, frames, conv)
    return rep


def set_project_camera(cam, path, width, height):
    """The project's camera JSON (core/camera.hpp: OpenCV pinhole, x right, y down, z forward,
    X_cam = R X_world + t, in kinesplat's = glTF's Y-up world) as a Blender camera. Blender's
    world is the importer's: (x, y, z) glTF -> (x, -z, y). A Blender camera looks down its -Z
    with +Y up, so its axes are OpenCV's x, -y and -z."""
    with open(path) as f:
        c = json.load(f)
    to_blender = Matrix(((1, 0, 0), (0, 0, -1), (0, 1, 0)))
    R = Matrix(c["R"])
    t = Vector(c["t"])
    centre = -(R.transposed() @ t)
    rows = [Vector(R[0]), -Vector(R[1]), -Vector(R[2])]
    axes = Matrix([to_blender @ r for r in rows]).transposed()  # columns: the camera's axes
    cam.matrix_world = Matrix.Translation(to_blender @ centre) @ axes.to_4x4()
    d = cam.data
    d.type = "PERSP"
    d.sensor_fit = "VERTICAL"
    d.angle_y = 2 * math.atan(0.5 * c["height"] / c["fy"])
    # Principal point off the centre: Blender's shift is in units of the larger image side.
    big = max(c["width"], c["height"])
    d.shift_x = (0.5 * c["width"] - c["cx"]) / big
    d.shift_y = (c["cy"] - 0.5 * c["height"]) / big
    if c["width"] != width or c["height"] != height:
        raise RuntimeError("the camera is %dx%d, the render %dx%d" % (c["width"], c["height"],
                                                                      width, height))


def render_glb(args, glb_report):
    """The imported GLB posed by one of its animations at one of the motion's frames, rendered by
    Workbench with flat lighting and the mesh's own colours (its colour attribute, or its texture
    where the material has one), from the front: the body faces glTF's +Z, which the importer
    turns into Blender's -Y (glTF Y up -> Blender Z up). The camera: --camera (the project's
    camera JSON, so that kinesplat animate --camera can render the same view) or an orthographic
    one framing the posed mesh."""
    scene = bpy.context.scene
    arm = next(o for o in bpy.data.objects if o.type == "ARMATURE")
    gltf = glb_json(args["glb"])
    anim = next((a for a in gltf.get("animations", []) if a.get("name") == args["action"]), None)
    if anim is None:
        raise RuntimeError("the GLB has no animation called %r" % args["action"])
    fps = float(anim.get("extras", {}).get("fps", 30.0))
    # The importer keys glTF time t at Blender frame t * scene fps (from frame 0).
    track = next(t for t in arm.animation_data.nla_tracks if t.name == args["action"])
    arm.animation_data.action = track.strips[0].action
    bframe = args["frame"] / fps * scene.render.fps
    whole = int(math.floor(bframe))
    scene.frame_set(whole, subframe=bframe - whole)
    bpy.context.view_layer.update()

    mesh = None
    for o in bpy.data.objects:
        if o.type == "MESH":
            if o.data.polygons and (mesh is None or len(o.data.vertices) > len(mesh.data.vertices)):
                mesh = o
    # Only the surface mesh: hide the point primitive (Workbench draws no loose vertices anyway).
    for o in bpy.data.objects:
        if o.type == "MESH" and o is not mesh:
            o.hide_render = True
    deps = bpy.context.evaluated_depsgraph_get()
    ev = mesh.evaluated_get(deps)
    pts = [ev.matrix_world @ v.co for v in ev.data.vertices]
    lo = Vector([min(p[i] for p in pts) for i in range(3)])
    hi = Vector([max(p[i] for p in pts) for i in range(3)])
    centre = (lo + hi) / 2

    cam_data = bpy.data.cameras.new("front")
    cam = bpy.data.objects.new("front", cam_data)
    scene.collection.objects.link(cam)
    if args["camera"]:
        set_project_camera(cam, args["camera"], args["width"], args["height"])
    else:
        # Orthographic, the posed mesh's box filling 91% of the image's height or width.
        cam_data.type = "ORTHO"
        aspect = args["width"] / args["height"]
        height = (hi.z - lo.z) * 1.1
        width = max(hi.x - lo.x, 0.5) * 1.1
        cam_data.ortho_scale = (max(height * aspect, width) if aspect >= 1
                                else max(height, width / aspect))
        cam.location = (centre.x, lo.y - 5.0, centre.z)
        cam.rotation_euler = (math.radians(90), 0, 0)  # looks along +Y, Z up
    scene.camera = cam

    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = args["width"]
    scene.render.resolution_y = args["height"]
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Standard"
    sh = scene.display.shading
    sh.light = args["light"]
    has_texture = any(m["images"] for m in
                      next(r for r in glb_report["meshes"] if r["name"] == mesh.name)["materials"])
    sh.color_type = "TEXTURE" if has_texture else "VERTEX"
    world = bpy.data.worlds.new("w") if scene.world is None else scene.world
    scene.world = world
    world.color = (0, 0, 0)
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = args["render"]
    t0 = time.monotonic()
    with CaptureOutput():
        bpy.ops.render.render(write_still=True)
    return {"file": args["render"], "seconds": time.monotonic() - t0, "engine": "BLENDER_WORKBENCH",
            "light": args["light"], "color_type": sh.color_type, "action": arm.animation_data.action.name,
            "motion_frame": args["frame"], "motion_fps": fps, "blender_frame": bframe,
            "mesh": mesh.name, "bbox_min": list(lo), "bbox_max": list(hi),
            "ortho_scale": cam_data.ortho_scale}


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    args = parse_args(argv)
    report = {"blender_version": bpy.app.version_string}
    try:
        import numpy
    except ImportError as e:  # the glTF importer needs it (Debian: python3-numpy)
        report["numpy_error"] = str(e)
        numpy = None
    if numpy is not None:
        report["numpy_version"] = numpy.__version__
        report["numpy_had_bool"] = "bool" in numpy.__dict__
        if args["numpy_patch"] and "bool" not in numpy.__dict__:
            numpy.bool = bool  # the alias numpy 1.24 removed; Blender 3.4.1's importer uses it
        report["numpy_patched"] = args["numpy_patch"] and not report["numpy_had_bool"]
    try:
        if args["glb"]:
            report["glb"] = import_glb(args["glb"])
            if args["render"]:
                report["render"] = render_glb(args, report["glb"])
        if args["bvh"]:
            report["bvh"] = import_bvh(args["bvh"], args["bvh_frames"])
    except Exception:
        report["error"] = traceback.format_exc()
    with open(args["out"] + ".tmp", "w") as f:
        json.dump(report, f, indent=1)
    os.replace(args["out"] + ".tmp", args["out"])


main()
