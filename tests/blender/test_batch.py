"""The headless entry point scripts/blender_batch.py: works on a saved scene, exits non-zero on failure."""
import json
import os
import shutil
import subprocess
import sys
import tempfile

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SCRIPT = os.path.join(REPO, "scripts", "blender_batch.py")
EXAMPLE = os.path.join(REPO, "formats", "examples", "cotton.fabric.json")


def _run(blend, *arguments):
    command = [bpy.app.binary_path, "-b", blend, "--factory-startup", "-noaudio", "--python", SCRIPT, "--",
               *arguments]
    return subprocess.run(command, capture_output=True, text=True, timeout=240, env=dict(os.environ))


def test_batch_script():
    folder = tempfile.mkdtemp(prefix="flowvid_batch_")
    try:
        bpy.ops.wm.read_factory_settings(use_empty=False)  # the default cube, camera and light
        scene = bpy.context.scene
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=11, y_subdivisions=11, size=0.3, location=(0, 0, 1))
        bpy.context.object.name = "Skirt"
        scene.render.engine = "CYCLES"
        scene.cycles.samples = 1
        scene.cycles.use_denoising = False
        scene.render.resolution_x = 64
        scene.render.resolution_y = 48
        blend = os.path.join(folder, "scene.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend)

        out = os.path.join(folder, "render")
        ok = _run(blend, "--preset", EXAMPLE, "--object", "Skirt", "--frames", "1:2", "--render", out, "--json")
        assert ok.returncode == 0, ok.stderr[-2000:]
        summary = json.loads([line for line in ok.stdout.splitlines() if line.startswith("{")][-1])
        assert summary["applied"]["Skirt"]["source"] == "formula", summary
        assert [os.path.basename(p) for p in summary["rendered"]] == ["0001.png", "0002.png"]
        assert all(os.path.getsize(p) > 0 for p in summary["rendered"])

        missing = _run(blend, "--preset", EXAMPLE, "--object", "Cape")
        assert missing.returncode == 1, missing.returncode
        assert "flowvid batch: error: no object named 'Cape'" in missing.stderr, missing.stderr[-500:]
        assert "Traceback" not in missing.stderr

        bad = _run(blend, "--preset", os.path.join(folder, "none.fabric.json"), "--object", "Skirt")
        assert bad.returncode == 1 and "does not exist" in bad.stderr, bad.stderr[-500:]
        usage = _run(blend, "--no-such-option")
        assert usage.returncode == 2, usage.returncode
        print("batch: apply + render exit 0; missing object, missing preset exit 1; bad option exit 2")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
