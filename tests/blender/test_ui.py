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

        drawn = [entry[0] for entry in _draw(panels.PHYSICS_PT_flowvid_fabric, bpy.context)]
        assert drawn.count("operator") == 4 and "label" in drawn, drawn
        drawn = [entry[0] for entry in _draw(panels.PARTICLE_PT_flowvid_video, bpy.context)]
        assert drawn.count("operator") == 3, drawn

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
