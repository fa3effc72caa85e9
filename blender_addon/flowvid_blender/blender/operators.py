"""Operators: undoable, errors through self.report, never a traceback.

Heavy imports (the api module, the library) happen inside execute()."""
import os
import traceback

import bpy
from bpy.props import FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper


def _fail(operator, error):
    """Any exception -> one readable error in Blender's UI (details on the console)."""
    from ..core.backend import BackendError

    known = error.__class__.__name__ in ("FlowvidError", "MappingError") or isinstance(error, BackendError)
    if not known:
        traceback.print_exc()
    operator.report({"ERROR"}, str(error) if known else "flowvid: unexpected %s: %s (details on the console)"
                    % (error.__class__.__name__, error))
    return {"CANCELLED"}


def _report_notes(operator, report):
    for note in report.get("not_represented", []):
        operator.report({"WARNING"}, note)


def _mesh_with_cloth(context):
    obj = context.object
    return obj is not None and obj.type == "MESH"


class FLOWVID_OT_load_fabric_preset(bpy.types.Operator, ImportHelper):
    """Load a fabric preset (*.fabric.json) for the active object"""
    bl_idname = "flowvid.load_fabric_preset"
    bl_label = "Load Fabric Preset"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".json"
    filter_glob: StringProperty(default="*.fabric.json", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return _mesh_with_cloth(context)

    def execute(self, context):
        try:
            from .. import api
            from ..core import mapping

            preset = api.read_preset(self.filepath)
            context.object.flowvid.fabric_preset = self.filepath
            context.object.flowvid.summary = "\n".join(mapping.summarize_preset(preset))
            self.report({"INFO"}, "loaded %s" % preset.get("name", self.filepath))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001 - shown in the UI
            return _fail(self, error)


class FLOWVID_OT_apply_fabric_preset(bpy.types.Operator):
    """Set this object's cloth from the fabric preset, mapped for this mesh (edge length, area, fps)"""
    bl_idname = "flowvid.apply_fabric_preset"
    bl_label = "Apply Fabric Preset"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _mesh_with_cloth(context) and bool(context.object.flowvid.fabric_preset)

    def execute(self, context):
        try:
            from .. import api

            report = api.apply_fabric_preset(context.object, context.object.flowvid.fabric_preset,
                                             scene=context.scene)
            context.object.flowvid.last_report = "\n".join(
                ["%s (%s)" % (report["preset_name"], report["source"])] + report["not_represented"])
            _report_notes(self, report)
            self.report({"INFO"}, "applied %s (%s)" % (report["preset_name"], report["source"]))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return _fail(self, error)


class FLOWVID_OT_calibrate_fabric_preset(bpy.types.Operator):
    """Run the static drape and waving swatch in Blender and in flowvid, refine Blender's settings until they
match, store them in the preset (Esc cancels)"""
    bl_idname = "flowvid.calibrate_fabric_preset"
    bl_label = "Calibrate for This Mesh"
    bl_options = {"REGISTER", "UNDO"}
    max_evaluations: IntProperty(name="Blender runs", default=12, min=4, max=60)

    _timer = None
    _calibration = None

    @classmethod
    def poll(cls, context):
        return _mesh_with_cloth(context) and bool(context.object.flowvid.fabric_preset)

    def _finish(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.area:
            context.area.header_text_set(None)
        if self._calibration is not None:
            self._calibration.cleanup()

    def execute(self, context):
        # Without a window (scripts, tests): run to the end.
        try:
            from .. import api

            result = api.calibrate_fabric_preset(context.object, context.object.flowvid.fabric_preset,
                                                 scene=context.scene, max_evaluations=self.max_evaluations)
            api.apply_fabric_preset(context.object, context.object.flowvid.fabric_preset, scene=context.scene)
            self.report({"INFO"}, "calibrated: RMS %.2f mm (formula %.2f mm)" % (
                1000 * result["rms_vertex_error_m"], 1000 * result["formula_rms_vertex_error_m"]))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return _fail(self, error)

    def invoke(self, context, event):
        try:
            from .. import api

            obj = context.object
            self._path = bpy.path.abspath(obj.flowvid.fabric_preset)
            self._preset = api.read_preset(self._path)
            self._stats = api.mesh_stats(obj)
            self._fps = api.scene_fps(context.scene)
            self._calibration = api.Calibration(self._preset, self._stats, self._fps,
                                                max_evaluations=self.max_evaluations)
        except Exception as error:  # noqa: BLE001
            return _fail(self, error)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.05, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._finish(context)
            self.report({"WARNING"}, "calibration cancelled; the preset is unchanged")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            from .. import api

            running = self._calibration.step()
            fraction = self._calibration.fraction()
            context.window_manager.progress_update(int(100 * fraction))
            if context.area and self._calibration.history:
                context.area.header_text_set("flowvid calibration %d%%: RMS %.2f mm (Esc cancels)" % (
                    100 * fraction, 1000 * self._calibration.history[-1]["rms_m"]))
            if running:
                return {"RUNNING_MODAL"}
            api.store_calibration(self._path, self._preset, self._calibration, self._stats, self._fps)
            result = self._calibration.result
            self._finish(context)
            report = api.apply_fabric_preset(context.object, self._path, scene=context.scene)
            context.object.flowvid.last_report = "\n".join(
                ["calibrated: RMS %.2f mm (formula %.2f mm)" % (1000 * result["rms_vertex_error_m"],
                                                               1000 * result["formula_rms_vertex_error_m"])]
                + report["not_represented"])
            self.report({"INFO"}, context.object.flowvid.last_report.split("\n")[0])
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            self._finish(context)
            return _fail(self, error)


class FLOWVID_OT_export_fabric_preset(bpy.types.Operator, ExportHelper):
    """Write this object's Blender cloth settings as a fabric preset (fits the flowvid model to Blender's swatch)"""
    bl_idname = "flowvid.export_fabric_preset"
    bl_label = "Export Fabric Preset"
    bl_options = {"REGISTER"}
    filename_ext = ".fabric.json"
    filter_glob: StringProperty(default="*.fabric.json", options={"HIDDEN"})
    areal_density: FloatProperty(name="Areal density (kg/m^2)", default=0.15, min=0.001, max=5.0,
                                 description="Real weight of the fabric: Blender's mass unit is free")
    max_evaluations: IntProperty(name="Fit runs", default=10, min=3, max=60)

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and any(m.type == "CLOTH" for m in obj.modifiers)

    def execute(self, context):
        wm = context.window_manager
        try:
            from .. import api

            wm.progress_begin(0, 100)
            result = api.export_fabric_preset(context.object, self.filepath,
                                              areal_density_kg_per_m2=self.areal_density, scene=context.scene,
                                              max_evaluations=self.max_evaluations,
                                              progress=lambda f, _m: wm.progress_update(int(100 * f)))
            self.report({"INFO"}, "exported %s: RMS %.2f mm" % (result["path"], 1000 * result["rms_vertex_error_m"]))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return _fail(self, error)
        finally:
            wm.progress_end()


def _by_hand(text):
    pairs = {}
    for item in text.split(","):
        if "=" in item:
            key, value = item.split("=", 1)
            pairs[key.strip()] = value.strip()
    return pairs


class FLOWVID_OT_bake_flowlines(bpy.types.Operator):
    """Bake the particle trajectories, projected through the camera at every frame, into a flow-line set"""
    bl_idname = "flowvid.bake_flowlines"
    bl_label = "Bake Flow Lines"
    bl_options = {"REGISTER"}

    def execute(self, context):
        settings = context.scene.flowvid
        try:
            from .. import api

            frame = context.scene.frame_current
            try:
                summary = api.bake_flowlines(settings.emitter, settings.camera or context.scene.camera,
                                             settings.frame_start, settings.frame_end, settings.flowlines,
                                             inputs=settings.input_lines or None, system=settings.particle_system,
                                             rule=settings.rule, by_hand=_by_hand(settings.by_hand),
                                             scene=context.scene)
            finally:
                context.scene.frame_set(frame)
            self.report({"INFO"}, "%d lines x %d frames -> %s" % (summary["lines"], summary["frames"], summary["path"]))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return _fail(self, error)


class FLOWVID_OT_grease_pencil_flowlines(bpy.types.Operator):
    """Export the active Grease Pencil's strokes (layers 'input' and 'output') as flow lines"""
    bl_idname = "flowvid.grease_pencil_flowlines"
    bl_label = "Strokes to Flow Lines"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == "GPENCIL"

    def execute(self, context):
        settings = context.scene.flowvid
        try:
            from .. import api

            summary = api.grease_pencil_flowlines(context.object, settings.camera or context.scene.camera,
                                                  settings.flowlines, scene=context.scene)
            self.report({"INFO"}, "%d input, %d output lines" % (summary["inputs"], summary["outputs"]))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return _fail(self, error)


class FLOWVID_OT_synthesize(bpy.types.Operator):
    """Run flowvid edit for the frame range and show the frames through the camera"""
    bl_idname = "flowvid.synthesize"
    bl_label = "Synthesize and Show"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        settings = context.scene.flowvid
        try:
            from .. import api

            if not settings.bank:
                raise api.FlowvidError("choose a particle bank (*.bank.exr from flowvid track)")
            first = api.synthesize(bpy.path.abspath(settings.bank), bpy.path.abspath(settings.flowlines),
                                   settings.frame_start, settings.frame_end, bpy.path.abspath(settings.output_dir),
                                   background=settings.background, texture=settings.texture)
            count = settings.frame_end - settings.frame_start + 1
            image = api.load_image_sequence(first, settings.frame_start, count)
            camera = settings.camera or context.scene.camera
            if settings.display == "PLANE":
                api.show_on_camera_plane(camera, image, settings.frame_start, count, scene=context.scene)
            else:
                api.show_as_camera_background(camera, image, settings.frame_start, count)
            self.report({"INFO"}, "synthesized %d frames into %s" % (count, os.path.dirname(first)))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return _fail(self, error)


classes = (
    FLOWVID_OT_load_fabric_preset,
    FLOWVID_OT_apply_fabric_preset,
    FLOWVID_OT_calibrate_fabric_preset,
    FLOWVID_OT_export_fabric_preset,
    FLOWVID_OT_bake_flowlines,
    FLOWVID_OT_grease_pencil_flowlines,
    FLOWVID_OT_synthesize,
)
