"""End to end: a scene built in code -> particle flow lines -> flowvid track/edit -> image sequence on a
camera-facing plane -> 5 frames rendered by Cycles, checked against the synthesized frames and the
particles' positions."""
import json
import math
import os
import shutil
import struct
import sys
import tempfile
import zlib

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "blender_addon"))

WIDTH, HEIGHT = 160, 120


def write_png(path, width, height, rgb_rows):
    """Minimal 8-bit RGB PNG writer (no dependency): rgb_rows[y] is bytes of 3*width."""
    raw = b"".join(b"\x00" + row for row in rgb_rows)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    with open(path, "wb") as handle:
        handle.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def synthetic_clip(folder, frames=40, speed_px=3):
    """A colourful texture falling down the middle of the frame at speed_px per frame, on dark grey."""
    os.makedirs(folder, exist_ok=True)
    for t in range(frames):
        rows = []
        for y in range(HEIGHT):
            yy = y - speed_px * t
            row = bytearray()
            for x in range(WIDTH):
                if abs(x - WIDTH // 2) < 28:
                    r = 0.5 + 0.5 * math.sin(x / 3.1 + 0.8 * math.sin(yy / 5.3))
                    g = 0.5 + 0.5 * math.sin(yy / 2.7 + x / 9.0)
                    b = 0.5 + 0.5 * math.cos((x + 2 * yy) / 4.3)
                    row += bytes((int(40 + 215 * r), int(40 + 215 * g), int(40 + 215 * b)))
                else:
                    row += b"\x20\x20\x20"
            rows.append(bytes(row))
        write_png(os.path.join(folder, "%06d.png" % (t + 1)), WIDTH, HEIGHT, rows)
    return os.path.join(folder, "%06d.png")


def particle_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.fps = 25
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 0.01
    scene.view_settings.view_transform = "Standard"
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.location = (0.0, -8.0, 0.0)
    camera.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    mesh = bpy.data.meshes.new("Emitter")
    mesh.from_pydata([(-0.2, 0, -0.2), (0.2, 0, -0.2), (0.2, 0, 0.2), (-0.2, 0, 0.2)], [], [(0, 1, 2, 3)])
    emitter = bpy.data.objects.new("Emitter", mesh)
    emitter.location = (-2.2, 0.0, 0.6)
    scene.collection.objects.link(emitter)
    emitter.modifiers.new("Particles", "PARTICLE_SYSTEM")
    settings = emitter.particle_systems[0].settings
    settings.count = 6
    settings.frame_start = 1
    settings.frame_end = 2
    settings.lifetime = 200
    settings.normal_factor = 0.0
    settings.object_align_factor = (12.0, 0.0, 0.0)  # 12 m/s along +x
    settings.factor_random = 0.3
    settings.effector_weights.gravity = 1.0
    settings.render_type = "NONE"
    emitter.hide_render = True
    return scene, camera, emitter


def read_pixels(path):
    image = bpy.data.images.load(path)
    width, height = image.size
    values = list(image.pixels)
    channels = image.channels
    bpy.data.images.remove(image)
    # Blender stores rows bottom-up; return [y][x] -> (r, g, b) with y down.
    return [[tuple(values[((height - 1 - y) * width + x) * channels:][:3]) for x in range(width)]
            for y in range(height)]


def test_end_to_end_render():
    from flowvid_blender import api

    folder = tempfile.mkdtemp(prefix="flowvid_e2e_")
    try:
        clip = synthetic_clip(os.path.join(folder, "clip"))
        drawn = os.path.join(folder, "drawn.flowlines.json")
        with open(drawn, "w") as handle:
            json.dump({"format": "flowvid.flowlines", "version": "1.0",
                       "image": {"width": WIDTH, "height": HEIGHT, "pixel_convention": "opencv"},
                       "inputs": [{"id": "in-1", "points": [[WIDTH // 2, -4], [WIDTH // 2, HEIGHT + 3]]}]}, handle)
        bank = os.path.join(folder, "fall.bank.exr")
        api.run_flowvid_tool("track", "--clip", clip, "--fps", "25", "--flowlines", drawn, "--out", bank,
                             "--patch", "16")

        scene, camera, emitter = particle_scene()
        lines_path = os.path.join(folder, "particles.flowlines.json")
        summary = api.bake_flowlines(emitter, camera, 1, 8, lines_path, inputs=drawn)
        assert summary["lines"] == 6, summary
        first = api.synthesize(bank, lines_path, 1, 5, os.path.join(folder, "synth"), background="none",
                               capture=clip)
        image = api.load_image_sequence(first, 1, 5)
        api.show_on_camera_plane(camera, image, 1, 5, scene=scene)
        rendered = api.render_frames(os.path.join(folder, "render"), 1, 5, scene=scene)
        assert len(rendered) == 5

        with open(lines_path) as handle:
            lines = json.load(handle)["outputs"]
        def mean_difference(a, b):
            return sum(abs(x - y) for ra, rb in zip(a, b) for pa, pb in zip(ra, rb)
                       for x, y in zip(pa, pb)) / (3 * WIDTH * HEIGHT)

        synth_first = read_pixels(os.path.join(folder, "synth", "%06d.png" % 1))
        for frame, path in zip(range(1, 6), rendered):
            render = read_pixels(path)
            synth = read_pixels(os.path.join(folder, "synth", "%06d.png" % frame))
            if frame > 1:
                # The sequence advances with the frame: this frame's texture, not the first one's.
                other = mean_difference(render, synth_first)
                assert mean_difference(render, synth) < 0.5 * other, (frame, other)
            brightness = [[sum(p) / 3.0 for p in row] for row in render]
            mean = sum(map(sum, brightness)) / (WIDTH * HEIGHT)
            spread = math.sqrt(sum((b - mean) ** 2 for row in brightness for b in row) / (WIDTH * HEIGHT))
            difference = mean_difference(render, synth)
            # Where the particles are (their lines at this frame) versus far from every line.
            points = [p for line in lines for key in line["keys"] if key["frame"] == frame for p in key["points"]]
            near, far = [], []
            for y in range(0, HEIGHT, 2):
                for x in range(0, WIDTH, 2):
                    d = min(math.hypot(x - p[0], y - p[1]) for p in points)
                    if d < 3.0:
                        near.append(brightness[y][x])
                    elif d > 30.0:
                        far.append(brightness[y][x])
            near_mean = sum(near) / len(near)
            far_mean = sum(far) / max(len(far), 1)
            print("frame %d: render mean %.3f spread %.3f, |render - synthesized| %.4f, near particles %.3f "
                  "(%d px), far %.3f (%d px)" % (frame, mean, spread, difference, near_mean, len(near), far_mean,
                                                 len(far)))
            assert spread > 0.02, "empty render"
            assert difference < 0.03, difference
            assert near_mean > 0.15 and near_mean > 4.0 * far_mean, (near_mean, far_mean)

        # The texture choice reaches the tool: over black, the moving layer keeps only the light the
        # flow adds to the clip's dark plate, (pixel - plate) / (1 - plate) <= pixel: never brighter than
        # the whole patches on the same pixels, and darker on the whole (the same frame without it).
        # Like for like: the moving layer has no edge fade, so the whole patches are rendered without it.
        whole_first = read_pixels(api.synthesize(bank, lines_path, 1, 1, os.path.join(folder, "whole"), background="none",
                                                 texture="whole", capture=clip, edge_fade=0))
        moving_first = api.synthesize(bank, lines_path, 1, 1, os.path.join(folder, "moving"), background="none",
                                      texture="moving", capture=clip)
        covered = [(sum(w), sum(m)) for rw, rm in zip(whole_first, read_pixels(moving_first))
                   for w, m in zip(rw, rm) if sum(w) > 0.15]
        share = sum(m for _, m in covered) / sum(w for w, _ in covered)
        brighter = max(m - w for w, m in covered)
        print("moving layer over black: %.3f of the whole patches' brightness on %d covered px, at most %.4f brighter"
              % (share, len(covered), brighter))
        assert len(covered) > 100 and share < 0.97 and brighter < 3 * 2.0 / 255, (share, len(covered), brighter)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
