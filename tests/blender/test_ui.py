"""Operators and panels through bpy.ops and draw(), as the UI calls them (headless: no window, so the
modal Calibrate runs through execute())."""
import os
import shutil
import sys
import tempfile

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "blender_addon"))
EXAMPLE = os.path.join(REPO, "formats", "examples", "cotton.fabric.json")


class FakeLayout:
    """Records what a panel draws; any layout call returns another FakeLayout."""

    def __init__(self, log):
        self.log = log

    def __getattr__(self, name):
        def call(*arguments, **options):
            self.log.append((name, arguments, options))
            return FakeLayout(self.log)
        return call


def _draw(panel_class, context):
    log = []
    panel_class.draw(type("P", (), {"layout": FakeLayout(log)})(), context)
    return log


def test_operators_and_panels():
    import flowvid_blender
    from flowvid_blender.blender import panels

    flowvid_blender.register()
    folder = tempfile.mkdtemp(prefix="flowvid_ui_")
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        scene.render.fps = 30
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=9, y_subdivisions=9, size=0.3)
        obj = bpy.context.object
        preset = os.path.join(folder, "cotton.fabric.json")
        shutil.copy(EXAMPLE, preset)

        assert bpy.ops.flowvid.load_fabric_preset(filepath=preset) == {"FINISHED"}
        assert obj.flowvid.summary.startswith("Fabric: cotton (example)"), obj.flowvid.summary
        assert bpy.ops.flowvid.apply_fabric_preset() == {"FINISHED"}
        cloth = [m for m in obj.modifiers if m.type == "CLOTH"][0].settings
        assert abs(cloth.time_scale - 1000 ** 0.5 / 30) < 1e-6
        assert "isotropic" in obj.flowvid.last_report
        assert bpy.ops.flowvid.calibrate_fabric_preset(max_evaluations=4) == {"FINISHED"}
        exported = os.path.join(folder, "exported.fabric.json")
        assert bpy.ops.flowvid.export_fabric_preset(filepath=exported, max_evaluations=4) == {"FINISHED"}
        assert os.path.isfile(exported)

        log = []
        panels.draw_fabric(FakeLayout(log), obj.flowvid)
        drawn = [entry[0] for entry in log]
        assert drawn.count("operator") == 5 and "label" in drawn, drawn
        drawn = [entry[0] for entry in _draw(panels.PARTICLE_PT_flowvid_video, bpy.context)]
        assert drawn.count("operator") == 3, drawn
        # Details says in the Info log what the popup shows (no window here).
        assert bpy.ops.flowvid.fabric_details() == {"FINISHED"}

        # Bake without an emitter: a report, not a traceback.
        try:
            bpy.ops.flowvid.bake_flowlines()
            raise AssertionError("baking without an emitter succeeded")
        except RuntimeError as error:
            assert "has no particle system" in str(error) or "nothing" in str(error), str(error)
        print("ui: load, apply, calibrate, export, panels drawn, errors reported")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        flowvid_blender.unregister()


def test_calibrate_and_export_through_the_tool():
    """Where the module cannot load, Calibrate and Export run the swatch through `flowvid swatch`: the
    calibration's RMS and the exported preset's values equal the module's run for run."""
    import json

    import flowvid_blender
    from flowvid_blender import library
    from flowvid_blender.core.backend import CliBackend

    tool = os.environ.get("FLOWVID_CLI")
    if not tool:
        print("SKIPPED: FLOWVID_CLI not set (the flowvid tool was not built)")
        return
    flowvid_blender.register()
    folder = tempfile.mkdtemp(prefix="flowvid_cli_ops_")
    try:
        results = {}
        for name in ("native", "cli"):
            bpy.ops.wm.read_factory_settings(use_empty=True)
            bpy.context.scene.render.fps = 30
            library.reset()
            if name == "cli":
                library._BACKEND = CliBackend(tool)
            assert library.get_backend().name == name
            bpy.ops.mesh.primitive_grid_add(x_subdivisions=9, y_subdivisions=9, size=0.3)
            preset = os.path.join(folder, name + ".fabric.json")
            shutil.copy(EXAMPLE, preset)
            assert bpy.ops.flowvid.load_fabric_preset(filepath=preset) == {"FINISHED"}
            assert bpy.ops.flowvid.calibrate_fabric_preset(max_evaluations=4) == {"FINISHED"}
            with open(preset) as handle:
                calibrated = json.load(handle)["adapters"]["blender"]
            exported = os.path.join(folder, name + "-exported.fabric.json")
            assert bpy.ops.flowvid.export_fabric_preset(filepath=exported, max_evaluations=4) == {"FINISHED"}
            with open(exported) as handle:
                results[name] = (calibrated, json.load(handle)["parameters"])
        (native_cal, native_exp), (cli_cal, cli_exp) = results["native"], results["cli"]
        assert abs(native_cal["rms_vertex_error_m"] - cli_cal["rms_vertex_error_m"]) < 1e-9, (native_cal, cli_cal)
        worst = max(abs(native_exp[k]["value"] - cli_exp[k]["value"]) / max(abs(native_exp[k]["value"]), 1e-30)
                    for k in native_exp)
        assert worst < 1e-9, worst
        print("through the tool: calibration RMS %.3f mm (module %.3f mm), exported values within %.1e relative"
              % (1000 * cli_cal["rms_vertex_error_m"], 1000 * native_cal["rms_vertex_error_m"], worst))
    finally:
        library.reset()
        shutil.rmtree(folder, ignore_errors=True)
        flowvid_blender.unregister()
