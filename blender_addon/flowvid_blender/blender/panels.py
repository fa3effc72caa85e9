"""Panels: Physics > Cloth > Fabric preset, and Particles > flowvid flow video."""
import bpy


class PHYSICS_PT_flowvid_fabric(bpy.types.Panel):
    bl_label = "Fabric Preset"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "physics"
    bl_parent_id = "PHYSICS_PT_cloth"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == "MESH"

    def draw(self, context):
        layout = self.layout
        settings = context.object.flowvid
        row = layout.row(align=True)
        row.prop(settings, "fabric_preset", text="")
        row.operator("flowvid.load_fabric_preset", text="", icon="FILEBROWSER")
        if settings.summary:
            box = layout.box()
            for line in settings.summary.split("\n"):
                box.label(text=line)
        row = layout.row(align=True)
        row.operator("flowvid.apply_fabric_preset", text="Apply")
        row.operator("flowvid.calibrate_fabric_preset", text="Calibrate for This Mesh")
        layout.operator("flowvid.export_fabric_preset", text="Export Cloth as Preset", icon="EXPORT")
        if settings.last_report:
            box = layout.box()
            box.label(text="Not represented in Blender:", icon="INFO")
            for line in settings.last_report.split("\n"):
                box.label(text=line)


class PARTICLE_PT_flowvid_video(bpy.types.Panel):
    bl_label = "flowvid Flow Video"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "particle"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        settings = context.scene.flowvid
        col = layout.column()
        col.prop(settings, "emitter")
        col.prop(settings, "particle_system")
        col.prop(settings, "camera")
        row = col.row(align=True)
        row.prop(settings, "frame_start")
        row.prop(settings, "frame_end")
        col.prop(settings, "input_lines")
        col.prop(settings, "rule")
        col.prop(settings, "by_hand")
        col.prop(settings, "flowlines")
        col.operator("flowvid.bake_flowlines", icon="PARTICLES")
        col.operator("flowvid.grease_pencil_flowlines", icon="GREASEPENCIL")
        col.separator()
        col.prop(settings, "bank")
        col.prop(settings, "output_dir")
        col.prop(settings, "background")
        col.prop(settings, "texture")
        col.prop(settings, "display")
        col.operator("flowvid.synthesize", icon="RENDER_ANIMATION")
        col.label(text="Then render as usual (Render > Render Animation).")


classes = (PHYSICS_PT_flowvid_fabric, PARTICLE_PT_flowvid_video)
