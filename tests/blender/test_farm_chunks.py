"""Farm chunks of a Blender render (docs/farm.md): scripts/blender_batch.py --frames A:B renders exactly
frames A..B, named by frame number, and a chunk that starts after the scene's first frame shows an unbaked
cloth simulation in the state a render of the whole range does, so the chunks join pixel for pixel."""
import os
import shutil
import subprocess
import tempfile

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SCRIPT = os.path.join(REPO, "scripts", "blender_batch.py")
PRESET = os.path.join(REPO, "formats", "examples", "cotton.fabric.json")


def _render(blend, frames, out):
    command = [bpy.app.binary_path, "-b", blend, "--factory-startup", "-noaudio", "--python-exit-code", "1",
               "--python", SCRIPT, "--", "--preset", PRESET, "--object", "Skirt", "--frames", frames, "--render", out]
    done = subprocess.run(command, capture_output=True, text=True, timeout=240, env=dict(os.environ))
    assert done.returncode == 0, done.stderr[-2000:]
    return sorted(os.listdir(out))


def _pixels(path):
    image = bpy.data.images.load(path)
    try:
        return list(image.pixels)
    finally:
        bpy.data.images.remove(image)


def test_batch_chunks_join():
    folder = tempfile.mkdtemp(prefix="flowvid_farm_chunks_")
    try:
        bpy.ops.wm.read_factory_settings(use_empty=False)  # the default cube, camera and light
        scene = bpy.context.scene
        bpy.data.objects.remove(bpy.data.objects["Cube"])
        # A hanging swatch that moves from frame 1 on: its cloth is simulated, never baked.
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=11, y_subdivisions=11, size=1.0, location=(0, 0, 1),
                                        rotation=(1.5708, 0, 0))
        bpy.context.object.name = "Skirt"
        scene.render.engine = "CYCLES"
        scene.cycles.samples = 1
        scene.cycles.use_denoising = False
        scene.render.resolution_x = 64
        scene.render.resolution_y = 48
        scene.frame_start, scene.frame_end = 1, 4
        blend = os.path.join(folder, "scene.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend)

        whole = _render(blend, "1:4", os.path.join(folder, "whole"))
        assert whole == ["0001.png", "0002.png", "0003.png", "0004.png"], whole
        chunk = _render(blend, "3:4", os.path.join(folder, "chunk"))
        assert chunk == ["0003.png", "0004.png"], chunk
        # Pixels, not bytes: Blender writes the render time and date into each PNG's metadata.
        moved = _pixels(os.path.join(folder, "whole", "0001.png")) != _pixels(os.path.join(folder, "whole", "0004.png"))
        assert moved, "the swatch should move between frames 1 and 4, or the test proves nothing"
        for name in chunk:
            a = _pixels(os.path.join(folder, "whole", name))
            b = _pixels(os.path.join(folder, "chunk", name))
            differing = sum(1 for x, y in zip(a, b) if x != y)
            assert differing == 0, "%s: %d channel values differ between the chunk and the whole render" % (name, differing)
        print("farm chunks: frames 3:4 rendered alone equal the whole 1:4 render pixel for pixel")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
