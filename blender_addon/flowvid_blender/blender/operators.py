"""Operators: undoable, errors through self.report, never a traceback. The long ones (Calibrate, Export,
Bake, Synthesize) are JobOperators: modal with progress and Esc from the UI, to the end from scripts.

Heavy imports (the api module, the library) happen inside execute()/job()."""
import os
import traceback

import bpy
from bpy.props import FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ..core import jobs, presentation
from .jobs import JobOperator


def fail(operator, error):
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


_SOURCES = {"formula": "formulas", "adapter": "stored calibration", "calibrated": "calibrated now"}


def _store_report(obj, report, first=None):
    """What the panel shows after Apply/Calibrate (short) and Details/Info tell (every note)."""
    obj.flowvid.last_status = first or "Applied: %s" % _SOURCES[report["source"]]
    obj.flowvid.last_warning = presentation.fold_warning(report["folds"]) if report.get("folds") else ""
    obj.flowvid.last_report = "\n".join(report["not_represented"])


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
            return fail(self, error)


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
            _store_report(context.object, report)
            _report_notes(self, report)
            self.report({"INFO"}, "applied %s (%s)" % (report["preset_name"], _SOURCES[report["source"]]))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return fail(self, error)


class FLOWVID_OT_calibrate_fabric_preset(JobOperator, bpy.types.Operator):
    """Run the static drape and waving swatch in Blender and in flowvid, refine Blender's settings until they
match, store them in the preset (Esc cancels)"""
    bl_idname = "flowvid.calibrate_fabric_preset"
    bl_label = "Calibrate for This Mesh"
    bl_options = {"REGISTER", "UNDO"}
    progress_title = "flowvid calibration"
    max_evaluations: IntProperty(name="Blender Runs", default=12, min=4, max=60)

    @classmethod
    def poll(cls, context):
        return _mesh_with_cloth(context) and bool(context.object.flowvid.fabric_preset)

    def job(self, context):
        from .. import api

        obj = context.object
        return api.calibrate_steps(obj, obj.flowvid.fabric_preset, scene=context.scene,
                                   max_evaluations=self.max_evaluations, apply=True)

    def done(self, context, result):
        calibration, report = result
        text = "Calibrated: RMS %.1f mm (formulas %.1f mm)" % (1000 * calibration["rms_vertex_error_m"],
                                                              1000 * calibration["formula_rms_vertex_error_m"])
        _store_report(context.object, report, text)
        return text


class FLOWVID_OT_export_fabric_preset(JobOperator, bpy.types.Operator, ExportHelper):
    """Write this object's Blender cloth settings as a fabric preset (fits the flowvid model to Blender's swatch;
Esc cancels)"""
    bl_idname = "flowvid.export_fabric_preset"
    bl_label = "Export Fabric Preset"
    bl_options = {"REGISTER"}
    progress_title = "flowvid export"
    filename_ext = ".fabric.json"
    filter_glob: StringProperty(default="*.fabric.json", options={"HIDDEN"})
    areal_density: FloatProperty(name="Areal Density", default=0.15, min=0.001, max=5.0, unit="NONE",
                                 description="Real weight of the fabric in kg/m\u00b2: Blender's mass unit is free, "
                                             "so it cannot be read from the cloth settings")
    max_evaluations: IntProperty(name="Fit Runs", default=10, min=3, max=60)

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and any(m.type == "CLOTH" for m in obj.modifiers)

    def invoke(self, context, event):
        # The file browser first (ExportHelper); its confirmation comes back through execute().
        self._modal_after_browser = context.window is not None
        return ExportHelper.invoke(self, context, event)

    def execute(self, context):
        if getattr(self, "_modal_after_browser", False):
            self._modal_after_browser = False
            return JobOperator.invoke(self, context, None)
        return JobOperator.execute(self, context)

    def job(self, context):
        from .. import api

        return api.export_steps(context.object, self.filepath, areal_density_kg_per_m2=self.areal_density,
                                scene=context.scene, max_evaluations=self.max_evaluations)

    def done(self, context, result):
        return "exported %s: RMS %.1f mm" % (result["path"], 1000 * result["rms_vertex_error_m"])


def _by_hand(text):
    pairs = {}
    for item in text.split(","):
        if "=" in item:
            key, value = item.split("=", 1)
            pairs[key.strip()] = value.strip()
    return pairs


class FLOWVID_OT_bake_flowlines(JobOperator, bpy.types.Operator):
    """Bake the particle trajectories, projected through the camera at every frame, into a flow-line set
(Esc cancels)"""
    bl_idname = "flowvid.bake_flowlines"
    bl_label = "Bake Flow Lines"
    bl_options = {"REGISTER"}
    progress_title = "flowvid bake"

    def job(self, context):
        from .. import api

        settings = context.scene.flowvid
        return api.bake_steps(settings.emitter, settings.camera or context.scene.camera, settings.frame_start,
                              settings.frame_end, settings.flowlines, inputs=settings.input_lines or None,
                              system=settings.particle_system, rule=settings.rule,
                              by_hand=_by_hand(settings.by_hand), scene=context.scene)

    def done(self, context, summary):
        return "%d lines x %d frames -> %s" % (summary["lines"], summary["frames"], summary["path"])


def strokes_object(context):
    """The Grease Pencil object to export: the active one, else the Flow Video panel's choice."""
    from ..flowlines import GREASE_PENCIL_TYPES

    obj = context.object
    if obj is not None and obj.type in GREASE_PENCIL_TYPES:
        return obj
    chosen = context.scene.flowvid.strokes if context.scene else None
    return chosen if chosen is not None and chosen.type in GREASE_PENCIL_TYPES else None


class FLOWVID_OT_grease_pencil_flowlines(bpy.types.Operator):
    """Export a Grease Pencil's strokes (layers "input" and "output"), seen through the camera, as flow lines"""
    bl_idname = "flowvid.grease_pencil_flowlines"
    bl_label = "Strokes to Flow Lines"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        if strokes_object(context) is None:
            cls.poll_message_set("Select a Grease Pencil object (or choose one under Strokes)")
            return False
        return True

    def execute(self, context):
        settings = context.scene.flowvid
        try:
            from .. import api

            summary = api.grease_pencil_flowlines(strokes_object(context), settings.camera or context.scene.camera,
                                                  settings.flowlines, scene=context.scene)
            self.report({"INFO"}, "%d input, %d output lines" % (summary["inputs"], summary["outputs"]))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return fail(self, error)


class FLOWVID_OT_synthesize(JobOperator, bpy.types.Operator):
    """Run flowvid edit for the frame range and show the frames through the camera (Esc cancels)"""
    bl_idname = "flowvid.synthesize"
    bl_label = "Synthesize and Show"
    bl_options = {"REGISTER", "UNDO"}
    progress_title = "flowvid synthesis"

    def job(self, context):
        from .. import api

        settings = context.scene.flowvid
        if not settings.bank:
            raise api.FlowvidError("choose a particle bank (*.bank.exr from flowvid track)")
        start, end = settings.frame_start, settings.frame_end
        arguments = (bpy.path.abspath(settings.bank), bpy.path.abspath(settings.flowlines), start, end,
                     bpy.path.abspath(settings.output_dir))

        def synthesize(progress):
            # The library's (or the tool's) progress, per stage; False once Esc was pressed stops it.
            return api.synthesize(*arguments, background=settings.background, texture=settings.texture,
                                  progress=lambda stage, fraction, _message: progress(fraction, stage))

        first = yield jobs.Background(synthesize, "flowvid edit")
        count = end - start + 1
        image = api.load_image_sequence(first, start, count)
        camera = settings.camera or context.scene.camera
        if settings.display == "PLANE":
            api.show_on_camera_plane(camera, image, start, count, scene=context.scene)
        else:
            api.show_as_camera_background(camera, image, start, count)
        return "synthesized %d frames into %s" % (count, os.path.dirname(first))

    def done(self, context, message):
        return message


class FLOWVID_OT_details(bpy.types.Operator):
    """Everything about the preset and the last Apply: where it comes from, its Blender calibration, what
Blender cannot represent and why Vertex Mass is what it is"""
    bl_idname = "flowvid.fabric_details"
    bl_label = "Details"
    bl_options = {"REGISTER", "INTERNAL"}

    # Popup width in UI units (at UI scale 1, one unit is 20 pixels).
    WIDTH_UNITS = 30

    @classmethod
    def poll(cls, context):
        return context.object is not None and bool(context.object.flowvid.fabric_preset)

    def paragraphs(self, context):
        from .. import api

        settings = context.object.flowvid
        preset = api.read_preset(settings.fabric_preset)
        values = ["%s: %s" % pair for pair in presentation.summary_pairs(preset)]
        result = [("Preset", values + presentation.preset_details(preset))]
        if settings.last_status:
            result.append((settings.last_status, settings.last_report.split("\n") if settings.last_report else []))
        return result

    def execute(self, context):
        # Scripts and `blender -b`: the same text in the Info log.
        try:
            for title, lines in self.paragraphs(context):
                self.report({"INFO"}, title)
                for line in lines:
                    self.report({"INFO"}, line)
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            return fail(self, error)

    def invoke(self, context, _event):
        try:
            self._paragraphs = self.paragraphs(context)
        except Exception as error:  # noqa: BLE001
            return fail(self, error)
        return context.window_manager.invoke_popup(self, width=int(self.WIDTH_UNITS * 20 * ui_scale(context)))

    def draw(self, context):
        from . import measure

        width = (self.WIDTH_UNITS - 2) * 20 * ui_scale(context)
        for title, lines in self._paragraphs:
            self.layout.label(text=title, icon="INFO")
            column = self.layout.column(align=True)
            for line in lines:
                for wrapped in presentation.wrap(line, width, measure.text_width):
                    column.label(text=wrapped)


def ui_scale(context):
    return context.preferences.system.ui_scale


classes = (
    FLOWVID_OT_load_fabric_preset,
    FLOWVID_OT_apply_fabric_preset,
    FLOWVID_OT_calibrate_fabric_preset,
    FLOWVID_OT_export_fabric_preset,
    FLOWVID_OT_bake_flowlines,
    FLOWVID_OT_grease_pencil_flowlines,
    FLOWVID_OT_synthesize,
    FLOWVID_OT_details,
)
