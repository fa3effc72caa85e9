"""The Blender stages of `flowvid demo`, headless (the demo runs this; so can you):

    blender -b --factory-startup --python-exit-code 1 --python scripts/demo_blender.py -- \\
        garment --preset cotton.fabric.json --out out/demo/garment [--frames 48] [--save scene.blend]
            [--engine eevee|cycles] [--resolution 640x360]
    blender -b --factory-startup --python-exit-code 1 --python scripts/demo_blender.py -- \\
        video --bank fall.bank.exr --clip data/demo/waterfall --inputs data/demo/waterfall/flowlines.svg \\
        --out out/demo/video [--frames 48]

garment: a skirt around a swaying, turning body, both built here, its cloth set
from the fabric preset by the add-on's mapping, simulated and rendered by
Blender into OUT/frames/####.png and OUT/garment.mp4.
video: a particle system falling in front of the scene camera becomes output
flow lines (one per particle, moving as the camera pans), the clip's bank is
synthesized along them by flowvid and shown on a plane filling the camera's
view, rendered into OUT/frames/####.png and OUT/edit.mp4.
Prints one JSON summary line on stdout; any failure prints
"flowvid demo: error: ..." on stderr and exits 1.
"""
import argparse
import json
import math
import os
import sys
import time


def _arguments(argv):
    parser = argparse.ArgumentParser(prog="blender -b --python scripts/demo_blender.py --")
    stages = parser.add_subparsers(dest="stage", required=True)
    garment = stages.add_parser("garment", help="a skirt with a fabric preset on an animated body")
    garment.add_argument("--preset", required=True, help="*.fabric.json to apply")
    garment.add_argument("--save", help="also save the scene as this .blend (e.g. for scripts/blender_batch.py)")
    video = stages.add_parser("video", help="a particle system's flow lines synthesized from a bank")
    video.add_argument("--bank", required=True, help="particle bank from flowvid track")
    video.add_argument("--clip", required=True, help="the capture (or clip) the bank was tracked from")
    video.add_argument("--inputs", required=True, help="the input flow lines the bank was tracked with")
    for stage in (garment, video):
        stage.add_argument("--out", required=True, help="folder for frames/ and the video")
        stage.add_argument("--frames", type=int, default=48, help="frames to simulate and render (from 1)")
        stage.add_argument("--samples", type=int, default=8 if stage is garment else 1,
                           help="Cycles samples per pixel (video: the plane shows its pixels exactly at 1)")
    garment.add_argument("--engine", choices=("eevee", "cycles"), default="eevee",
                         help="eevee: soft shadows and ambient occlusion, no sampling noise (default); cycles: path "
                              "traced at --samples")
    garment.add_argument("--resolution", default="640x360", help="WxH of the render")
    return parser.parse_args(argv)


def _cycles(scene, width, height, fps, frames, samples):
    scene.render.engine = "CYCLES"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False  # no OpenImageDenoise on every machine
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.fps = fps
    scene.frame_start, scene.frame_end = 1, frames
    scene.view_settings.view_transform = "Standard"


def _eevee(scene, width, height, fps, frames):
    """Rasterised (no sampling noise at any sample count): soft shadows, ambient occlusion and a
    filmic look; headless Blender renders it through its software OpenGL."""
    scene.render.engine = "BLENDER_EEVEE"
    eevee = scene.eevee
    eevee.taa_render_samples = 4
    eevee.use_gtao = True
    eevee.gtao_distance = 0.3
    eevee.use_soft_shadows = True
    eevee.shadow_cube_size = "512"
    eevee.shadow_cascade_size = "1024"
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.fps = fps
    scene.frame_start, scene.frame_end = 1, frames
    scene.view_settings.view_transform = "Filmic"


def _material(name, rgb):
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*rgb, 1.0)
    return material


def _skirt_mesh(rings=14, segments=40, top_radius_m=0.165, bottom_radius_m=0.34, top_z_m=0.86, length_m=0.42):
    """An open flared tube: ring 0 is the waist (the pin group)."""
    vertices, faces = [], []
    for r in range(rings):
        t = r / (rings - 1)
        radius = top_radius_m + (bottom_radius_m - top_radius_m) * t
        z = top_z_m - length_m * t
        for s in range(segments):
            angle = 2 * math.pi * s / segments
            vertices.append((radius * math.cos(angle), radius * math.sin(angle), z))
    for r in range(rings - 1):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            faces.append((a, b, b + segments, a + segments))
    mesh = bpy.data.meshes.new("Skirt")
    mesh.from_pydata(vertices, [], faces)
    return mesh, list(range(segments))


def garment(options):
    from flowvid_blender import api

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    width, height = (int(v) for v in options.resolution.lower().split("x"))
    if options.engine == "eevee":
        _eevee(scene, width, height, 24, options.frames)
    else:
        _cycles(scene, width, height, 24, options.frames, options.samples)

    bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.15, depth=1.0, location=(0.0, 0.0, 0.5))
    body = bpy.context.object
    body.name = "Body"
    body.data.materials.append(_material("skin", (0.8, 0.6, 0.5)))
    body.modifiers.new("Collision", "COLLISION")
    # Sway sideways and turn: the skirt has to swing and fold to follow.
    half = max(2, options.frames // 2)
    for frame, x_m, turn_deg in ((1, 0.0, 0.0), (half, 0.22, 50.0), (options.frames, -0.05, -20.0)):
        body.location.x = x_m
        body.rotation_euler.z = math.radians(turn_deg)
        body.keyframe_insert("location", frame=frame)
        body.keyframe_insert("rotation_euler", frame=frame)

    mesh, waist = _skirt_mesh()
    skirt = bpy.data.objects.new("Skirt", mesh)
    scene.collection.objects.link(skirt)
    skirt.parent = body
    skirt.matrix_parent_inverse = body.matrix_world.inverted()
    skirt.data.materials.append(_material("cloth", (0.15, 0.3, 0.75)))
    for polygon in mesh.polygons:
        polygon.use_smooth = True
    pins = skirt.vertex_groups.new(name="Waist")
    pins.add(waist, 1.0, "REPLACE")
    cloth = skirt.modifiers.new("Cloth", "CLOTH")
    cloth.settings.vertex_group_mass = "Waist"
    cloth.collision_settings.use_collision = True
    cloth.collision_settings.distance_min = 0.008
    cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, options.frames
    report = api.apply_fabric_preset(skirt, options.preset, scene=scene)

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.location = (0.0, -2.6, 0.75)
    camera.rotation_euler = (math.radians(88.0), 0.0, 0.0)
    camera.data.lens = 40.0  # the figure fills the 16:9 frame's height
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 4.0
    sun.data.angle = math.radians(8.0)  # soft-edged shadows
    sun.rotation_euler = (math.radians(40.0), math.radians(20.0), math.radians(-30.0))
    scene.collection.objects.link(sun)
    # A floor to stand on and catch the shadows, and a sky that lights from all around.
    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.data.materials.append(_material("floor", (0.55, 0.55, 0.52)))
    scene.world = bpy.data.worlds.new("World")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.42, 0.45, 0.5, 1.0)
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6

    if options.save:
        os.makedirs(os.path.dirname(os.path.abspath(options.save)), exist_ok=True)
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(options.save))
    started = time.monotonic()
    frames = api.render_frames(os.path.join(options.out, "frames"), 1, options.frames, scene=scene)
    video = api.encode_video(frames, os.path.join(options.out, "garment.mp4"), scene.render.fps, scene=scene)
    return {"preset": os.path.abspath(options.preset), "mapping": report["source"],
            "not_represented": report["not_represented"], "frames": frames, "video": video,
            "render_seconds": time.monotonic() - started}


def video(options):
    from flowvid_blender import api

    with open(os.path.join(options.clip, "capture.json")) as handle:
        capture = json.load(handle)
    fps = capture.get("fps", 25)
    bank_info = json.loads(api.run_flowvid_tool("info", options.bank, "--json"))
    width, height = bank_info["clip"]["width_px"], bank_info["clip"]["height_px"]

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    _cycles(scene, width, height, int(round(fps)), options.frames, options.samples)
    scene.cycles.pixel_filter_type = "BOX"  # the plane shows the synthesized pixels as they are
    scene.cycles.filter_width = 0.01

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.data.lens = 35.0
    # A slow pan: every particle's trajectory moves across the image, so the
    # output flow lines change from frame to frame.
    for frame, x_m in ((1, -0.3), (options.frames, 0.3)):
        camera.location = (x_m, -9.0, 0.0)
        camera.rotation_euler = (math.radians(90.0), 0.0, 0.0)
        camera.keyframe_insert("location", frame=frame)

    # A ledge the water pours from: particles leave it sideways and fall.
    emitter_mesh = bpy.data.meshes.new("Ledge")
    # Tilted, so the lines start at different heights and their particles do
    # not line up in rows across the fall.
    emitter_mesh.from_pydata([(-1.6, -0.1, 0.5), (1.6, -0.1, -0.5), (1.6, 0.1, -0.5), (-1.6, 0.1, 0.5)], [],
                             [(0, 1, 2, 3)])
    emitter = bpy.data.objects.new("Ledge", emitter_mesh)
    emitter.location = (0.0, 0.0, 2.0)
    scene.collection.objects.link(emitter)
    emitter.modifiers.new("Particles", "PARTICLE_SYSTEM")
    settings = emitter.particle_systems[0].settings
    settings.count = 14
    settings.frame_start, settings.frame_end = 1, 2
    settings.lifetime = 400
    settings.emit_from = "FACE"
    settings.use_emit_random = True  # seeded: the same scene gives the same particles
    settings.normal_factor = 0.0
    settings.object_align_factor = (0.0, 0.0, 0.6)
    settings.factor_random = 0.4
    settings.effector_weights.gravity = 0.5
    settings.render_type = "NONE"
    emitter.hide_render = True

    out = os.path.abspath(options.out)
    os.makedirs(out, exist_ok=True)
    lines = os.path.join(out, "particles.flowlines.json")
    baked = api.bake_flowlines(emitter, camera, 1, options.frames, lines, inputs=options.inputs, scene=scene)
    # Defaults: an edit's texture fades with its feather where the clip had none.
    first = api.synthesize(options.bank, lines, 1, options.frames, os.path.join(out, "synthesized"),
                           capture=options.clip)
    image = api.load_image_sequence(first, 1, options.frames)
    api.show_on_camera_plane(camera, image, 1, options.frames, scene=scene)
    started = time.monotonic()
    frames = api.render_frames(os.path.join(out, "frames"), 1, options.frames, scene=scene)
    movie = api.encode_video(frames, os.path.join(out, "edit.mp4"), fps, scene=scene)
    return {"flowlines": lines, "lines": baked["lines"], "frames": frames, "video": movie,
            "render_seconds": time.monotonic() - started}


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    try:
        options = _arguments(argv)
    except SystemExit as exit_request:
        sys.stdout.flush()
        os._exit(2 if exit_request.code else 0)
    here = os.path.dirname(os.path.realpath(__file__))  # through symlinks to the checkout
    sys.path.insert(0, os.path.join(os.path.dirname(here), "blender_addon"))
    global bpy
    import bpy

    try:
        summary = garment(options) if options.stage == "garment" else video(options)
    except Exception as error:  # noqa: BLE001 - one line for the user, exit 1
        print("flowvid demo: error: %s" % error, file=sys.stderr)
        sys.stderr.flush()
        os._exit(1)
    print(json.dumps(summary))
    sys.stdout.flush()


main()
