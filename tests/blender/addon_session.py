"""A user's Blender session with the add-on installed from its zip (test_install.py runs it).

blender -b -noaudio --python-exit-code 1 --python tests/blender/addon_session.py -- SCRATCH
Runs with a clean user folder whose saved preferences enable the add-on and with
no FLOWVID_* variable: the add-on must find the library by itself. Applies a
fabric preset and bakes particles to flow lines through the add-on's operators
and checks the numbers against the docs' formulas and an independent
projection; prints one JSON summary line; any failure exits 1.
"""
import importlib.util
import json
import math
import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
ADDON = "flowvid_blender"


def _helpers(name):
    # The test helpers (scene builders, hand formulas), not the checkout's add-on: their module-level
    # sys.path entry for blender_addon/ is taken out again.
    spec = importlib.util.spec_from_file_location(name, os.path.join(HERE, name + ".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sys.path[:] = [p for p in sys.path if os.path.realpath(p) != os.path.join(os.path.realpath(REPO), "blender_addon")]
    return module


def check_found(user_scripts):
    """The add-on came from the user folder, is enabled by the saved preferences, and Test finds the module it
    carries (in-process backend)."""
    assert not [k for k in os.environ if k.startswith("FLOWVID_")], "the session must run without FLOWVID_*"
    assert ADDON in bpy.context.preferences.addons, "the saved preferences should enable the add-on"
    package = sys.modules[ADDON]
    assert os.path.realpath(package.__file__).startswith(os.path.realpath(user_scripts) + os.sep), package.__file__
    assert bpy.ops.flowvid.test_library() == {"FINISHED"}
    shown = bpy.context.preferences.addons[ADDON].preferences.last_test
    library = sys.modules[ADDON + ".library"]
    found = library.discover()
    native = os.path.join(os.path.realpath(user_scripts), "addons", ADDON, "native")
    assert found["backend"] == "native" and os.path.dirname(found["module"]) == native, found
    assert found["module_version"] == ".".join(str(n) for n in package.bl_info["version"]), found
    assert found["tool"] and found["tool_version"] == "flowvid %s" % found["module_version"], found
    assert "Uses: the module" in shown and found["module"] in shown, shown
    return found


def apply_preset(preset_path):
    """Load + Apply on a 9 x 7 grid (edge 0.03 m, 0.24 x 0.18 m) at 25 fps: the cloth settings equal the hand
    formulas for the preset's values."""
    fabric = _helpers("test_fabric")
    bpy.ops.wm.read_homefile(use_empty=True)  # keeps the preferences (a factory reset would disable the add-on)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = 50, 2.0
    obj = fabric.grid_object("Garment", 9, 7, 0.02, scale=1.5)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    assert bpy.ops.flowvid.load_fabric_preset(filepath=preset_path) == {"FINISHED"}
    assert bpy.ops.flowvid.apply_fabric_preset() == {"FINISHED"}
    cloth = [m for m in obj.modifiers if m.type == "CLOTH"][0].settings
    with open(preset_path) as handle:
        expected = fabric.formula_expectation(json.load(handle), 0.03, 0.24 * 0.18, 63, 25.0)
    for key, value in expected.items():
        got = getattr(cloth, key)
        assert abs(got - value) <= 2e-6 * abs(value), "%s: Blender has %r, the formula gives %r" % (key, got, value)
    return {key: getattr(cloth, key) for key in expected}


def bake_lines(path, frame_end=10):
    """Bake Flow Lines on test_flowlines' particle scene: one line per particle, one key per frame, every point
    where the particle's recorded position projects through the camera at that key's frame (< 0.5 px)."""
    lines = _helpers("test_flowlines")
    scene, camera, emitter = lines.particle_scene(frame_end=frame_end, keep_preferences=True)
    recorded = lines.record_alive_particles(scene, emitter, frame_end)
    settings = scene.flowvid
    settings.emitter, settings.camera = emitter, camera
    settings.frame_start, settings.frame_end = 1, frame_end
    settings.flowlines = path
    assert bpy.ops.flowvid.bake_flowlines() == {"FINISHED"}
    with open(path) as handle:
        document = json.load(handle)
    assert sorted(line["id"] for line in document["outputs"]) == sorted("p%d" % i for i in recorded), document["outputs"]
    worst, checked = 0.0, 0
    for line in document["outputs"]:
        path3d = recorded[int(line["id"][1:])]
        assert [key["frame"] for key in line["keys"]] == list(range(1, frame_end + 1))
        for key in line["keys"]:
            scene.frame_set(key["frame"])
            assert len(key["points"]) == len(path3d)
            for baked, point in zip(key["points"], path3d):
                x, y = lines.independent_projection(scene, camera, point)
                worst = max(worst, math.hypot(baked[0] - x, baked[1] - y))
                checked += 1
    assert len(recorded) >= 6 and checked > 100, (len(recorded), checked)
    assert worst < 0.5, worst
    return {"lines": len(document["outputs"]), "points_checked": checked, "worst_px": worst}


def main():
    scratch = sys.argv[sys.argv.index("--") + 1]
    found = check_found(os.environ["BLENDER_USER_SCRIPTS"])
    cloth = apply_preset(os.path.join(REPO, "data", "demo", "cotton-full-fit.fabric.json"))
    baked = bake_lines(os.path.join(scratch, "particles.flowlines.json"))
    print(json.dumps({"found": found, "cloth": cloth, "baked": baked}))


main()
