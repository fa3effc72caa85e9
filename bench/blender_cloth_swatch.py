"""Blender's own cloth solver on a flowvid swatch experiment, for bench_cloth.

Run: blender -b --factory-startup -noaudio --python bench/blender_cloth_swatch.py -- \
        --capture ../shared/captures/cloth-cotton-waving-1 --rows 24 --cols 24 --frames 50 --quality 5

Builds the scene in code (no .blend): a width x height grid hung from its
pinned corners, the pins driven by hook empties keyframed at the capture's
pin positions (linear between frames), the cloth modifier set to the preset
values in truth/truth.json (blender_preset_values) with the captures'
time_scale. A short untimed preroll brings the cloth near equilibrium (as
the captures were made); only the capture's frames are timed. Prints one
line "FLOWVID_BLENDER_RESULT {json}".
"""
import argparse
import json
import math
import os
import sys
import time

import bpy


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--capture", required=True)
    p.add_argument("--rows", type=int, default=24)
    p.add_argument("--cols", type=int, default=24)
    p.add_argument("--frames", type=int, default=0, help="0: the capture's frame count")
    p.add_argument("--quality", type=int, default=5)
    p.add_argument("--preroll", type=int, default=80,
                   help="untimed frames before capture frame 1: the pins slide in from the flat width over 24 "
                        "frames and the cloth settles, as the captures were made, so that the timed frames start "
                        "near equilibrium like flowvid's")
    p.add_argument("--slide-frames", type=int, default=24,
                   help="preroll frames over which the pins slide in from the flat width (at most the preroll)")
    p.add_argument("--initial-bow-m", type=float, default=0.0,
                   help="start the flat swatch bowed by this depth (m, along +y, largest at the top edge's middle): "
                        "picks which way the slack between the pins buckles, as a capture's first frame shows")
    p.add_argument("--start-positions", default="",
                   help="optional: raw float64 x, y, z per vertex (r*cols + c) to start from, e.g. a measured first "
                        "frame resampled to this grid; the flat grid stays the rest shape (a basis shape key) and "
                        "the pins hold their first positions through the preroll (no slide)")
    p.add_argument("--preset-from", default="",
                   help="optional: another capture whose truth/truth.json preset values to use (a wrong fabric on "
                        "this capture's experiment)")
    p.add_argument("--mass-of-grid", type=int, default=0,
                   help="scale the preset's per-vertex mass so that the swatch weighs what it does on an N x N grid "
                        "(e.g. 24: the captures' total mass on any mesh); 0: the preset's mass per vertex")
    p.add_argument("--change-ppm", type=float, default=0.0,
                   help="change the preset's bending stiffness and air damping by this many parts in a million "
                        "(a member of a chaos ensemble: how far a change far below any measurement moves the run)")
    p.add_argument("--positions-out", default="", help="optional: write the baked vertex positions (raw float64)")
    return p.parse_args(argv)


def main():
    args = parse_args()
    with open(os.path.join(args.capture, "capture.json")) as f:
        capture = json.load(f)
    preset = {}
    truth_path = os.path.join(args.preset_from or args.capture, "truth", "truth.json")
    if os.path.exists(truth_path):
        with open(truth_path) as f:
            preset = json.load(f).get("blender_preset_values", {})
    swatch = capture["swatch"]
    fps = float(capture["fps"])
    frames = args.frames or int(capture["frames"]["count"])
    width, height = float(swatch["width_m"]), float(swatch["height_m"])
    rows, cols = args.rows, args.cols

    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    scene = bpy.context.scene
    scene.render.fps = int(round(fps))
    preroll = max(args.preroll, 0)
    slide = min(args.slide_frames, preroll)
    total = preroll + frames
    scene.frame_start = 1
    scene.frame_end = total

    # The swatch, flat and vertical, top edge at the pins' height, quads as a
    # Blender artist would model it. Vertex r*cols + c, row 0 at v = 0.
    pins = swatch["pins"]
    top_z = max(p["positions"][0][2] for p in pins)
    verts = []
    for r in range(rows):
        v = r / (rows - 1)
        for c in range(cols):
            u = c / (cols - 1)
            bow = args.initial_bow_m * math.sin(math.pi * u) * v
            verts.append(((u - 0.5) * width, bow, top_z - (1.0 - v) * height))
    faces = [(r * cols + c, r * cols + c + 1, (r + 1) * cols + c + 1, (r + 1) * cols + c)
             for r in range(rows - 1) for c in range(cols - 1)]
    mesh = bpy.data.meshes.new("swatch")
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    obj = bpy.data.objects.new("swatch", mesh)
    scene.collection.objects.link(obj)
    start = None
    if args.start_positions:
        import struct
        with open(args.start_positions, "rb") as f:
            raw = f.read()
        if len(raw) != 24 * rows * cols:
            sys.exit("--start-positions: expected %d float64 values, found %d" % (3 * rows * cols, len(raw) // 8))
        values = struct.unpack("<%dd" % (3 * rows * cols), raw)
        start = [tuple(values[3 * i:3 * i + 3]) for i in range(rows * cols)]
        # Blender takes the rest shape from the cache's first frame unless
        # rest_shape_key names a key other than the basis: the flat grid is
        # kept as a key of its own so that the start does not become the rest.
        obj.shape_key_add(name="Basis")
        obj.shape_key_add(name="flat")
        moved = obj.shape_key_add(name="start")
        for i, co in enumerate(start):
            moved.data[i].co = co
        moved.value = 1.0
        slide = 0

    group = obj.vertex_groups.new(name="pin")
    for k, pin in enumerate(pins):
        u, v = pin["uv"]
        index = int(round(v * (rows - 1))) * cols + int(round(u * (cols - 1)))
        group.add([index], 1.0, "REPLACE")
        # A hook empty at the origin: the vertex is moved by the empty's
        # translation, keyframed to land on the pin position at every frame.
        empty = bpy.data.objects.new("pin%d" % k, None)
        scene.collection.objects.link(empty)
        hook = obj.modifiers.new("hook%d" % k, "HOOK")
        hook.object = empty
        hook.vertex_indices_set([index])
        rest = start[index] if start else verts[index]
        first = pin["positions"][0]
        if preroll > 0 and slide > 0:
            empty.location = (0.0, 0.0, 0.0)
            empty.keyframe_insert("location", frame=1)
            empty.location = (first[0] - rest[0], first[1] - rest[1], first[2] - rest[2])
            empty.keyframe_insert("location", frame=max(slide, 2))
        for f, p in enumerate(pin["positions"][:frames]):
            empty.location = (p[0] - rest[0], p[1] - rest[1], p[2] - rest[2])
            empty.keyframe_insert("location", frame=preroll + f + 1)
        for fc in empty.animation_data.action.fcurves:
            for kp in fc.keyframe_points:
                kp.interpolation = "LINEAR"

    cloth = obj.modifiers.new("cloth", "CLOTH")
    s = cloth.settings
    s.quality = args.quality
    s.mass = preset.get("mass", 0.3)
    if args.mass_of_grid > 0:
        s.mass *= args.mass_of_grid ** 2 / (rows * cols)
    s.tension_stiffness = preset.get("tension_stiffness", 15.0)
    s.compression_stiffness = preset.get("compression_stiffness", 15.0)
    s.shear_stiffness = preset.get("shear_stiffness", 15.0)
    s.bending_stiffness = preset.get("bending_stiffness", 0.5)
    s.tension_damping = preset.get("tension_damping", 5.0)
    s.compression_damping = preset.get("compression_damping", 5.0)
    s.shear_damping = preset.get("shear_damping", 5.0)
    s.air_damping = preset.get("air_damping", 1.0)
    if args.change_ppm:
        factor = 1.0 + 1e-6 * args.change_ppm
        s.bending_stiffness *= factor
        s.air_damping *= factor
    s.time_scale = math.sqrt(1000.0) / fps  # gravity 9.81 m/s^2 at this fps, as the captures
    s.vertex_group_mass = "pin"
    if start:
        s.rest_shape_key = obj.data.shape_keys.key_blocks["flat"]
    cloth.collision_settings.use_collision = False
    cloth.collision_settings.use_self_collision = False
    cloth.point_cache.frame_start = 1
    cloth.point_cache.frame_end = total

    # Preroll (untimed), then time the capture's frames 2..N (frame 1 is the
    # start state, as in flowvid's run).
    start = time.perf_counter()
    for f in range(1, preroll + 2):
        scene.frame_set(f)
    preroll_seconds = time.perf_counter() - start
    start = time.perf_counter()
    for f in range(preroll + 2, total + 1):
        scene.frame_set(f)
    seconds = time.perf_counter() - start

    if args.positions_out:
        import struct
        depsgraph = bpy.context.evaluated_depsgraph_get()
        with open(args.positions_out, "wb") as out:
            for f in range(preroll + 1, total + 1):
                scene.frame_set(f)
                evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
                for vert in evaluated.data.vertices:
                    out.write(struct.pack("<3d", *vert.co))
    result = {"bake_seconds": seconds, "preroll_seconds": preroll_seconds, "preroll_frames": preroll, "frames": frames, "rows": rows, "cols": cols, "quality": args.quality,
              "blender_version": bpy.app.version_string, "simulated_seconds": (frames - 1) / fps}
    print("FLOWVID_BLENDER_RESULT " + json.dumps(result), flush=True)


main()
