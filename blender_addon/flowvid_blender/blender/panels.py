"""Panels, in Blender's conventions (property split, short labels, long text in Details / the Info log):
Fabric Preset at the top of Physics > Cloth (drawn before the Cloth panel's own settings: Blender 3.4 appends
add-on subpanels after its own, out of sight), Particles > Flow Video, and Strokes to Flow Lines where a
Grease Pencil object is edited (its Data tab and the 3D view's Object menu).

Each draw goes through draw_* functions taking a layout, so tests can lay them out with a recording layout
and measure every text against the width it gets (tests/blender/test_panels_ui.py)."""
import bpy

GREASE_PENCIL_TYPES = ("GPENCIL", "GREASEPENCIL")  # up to Blender 4.2, from 4.3


def _split_layout(layout):
    layout.use_property_split = True
    layout.use_property_decorate = False


def draw_pairs(layout, lines):
    """'Label: value' lines as Blender draws properties: the label right-aligned in the left 40 %."""
    column = layout.column(align=True)
    for line in lines:
        label, _, value = line.partition(": ")
        split = column.split(factor=0.4, align=True)
        left = split.row()
        left.alignment = "RIGHT"
        left.label(text=label)
        split.label(text=value)


# The summary lines shown in the Cloth panel (all of them are in Details).
SHOWN = ("Fabric", "Density", "Stretch Warp", "Bending", "Blender")


def draw_fabric(layout, settings):
    _split_layout(layout)
    layout.label(text="Fabric Preset", icon="MOD_CLOTH")
    row = layout.row(align=True)
    row.prop(settings, "fabric_preset", text="Preset")
    row.operator("flowvid.load_fabric_preset", text="", icon="IMPORT")
    if settings.summary:
        draw_pairs(layout, [line for line in settings.summary.split("\n") if line.partition(": ")[0] in SHOWN])
    row = layout.row(align=True)
    row.operator("flowvid.apply_fabric_preset", text="Apply")
    row.operator("flowvid.calibrate_fabric_preset", text="Calibrate")
    row = layout.row(align=True)
    row.operator("flowvid.export_fabric_preset", text="Export", icon="EXPORT")
    row.operator("flowvid.fabric_details", text="Details", icon="INFO")
    if settings.last_status:
        layout.label(text=settings.last_status, icon="CHECKMARK")
    if settings.last_warning:
        layout.label(text=settings.last_warning, icon="ERROR")


def draw_flow_video(layout, settings):
    _split_layout(layout)
    column = layout.column()
    column.prop(settings, "emitter")
    column.prop(settings, "particle_system", text="System")
    column.prop(settings, "camera")
    column = layout.column(align=True)
    column.prop(settings, "frame_start")
    column.prop(settings, "frame_end")

    layout.separator()
    column = layout.column()
    column.prop(settings, "input_lines", text="Input Lines")
    column.prop(settings, "rule")
    column.prop(settings, "by_hand")
    column.prop(settings, "flowlines", text="Flow Lines")
    layout.operator("flowvid.bake_flowlines", icon="PARTICLES")
    row = layout.row(align=True)
    row.prop(settings, "strokes")
    row.operator("flowvid.grease_pencil_flowlines", text="", icon="EXPORT")

    layout.separator()
    column = layout.column()
    column.prop(settings, "bank")
    column.prop(settings, "output_dir")
    column.prop(settings, "background")
    column.prop(settings, "texture")
    column.prop(settings, "display")
    layout.operator("flowvid.synthesize", icon="RENDER_ANIMATION")


def draw_strokes(layout, settings):
    _split_layout(layout)
    column = layout.column()
    column.prop(settings, "camera")
    column.prop(settings, "flowlines", text="Flow Lines")
    layout.operator("flowvid.grease_pencil_flowlines", icon="EXPORT")


def cloth_panel_top(self, context):
    """Prepended to Blender's Cloth panel (PHYSICS_PT_cloth): the preset above the settings it sets."""
    if context.object is not None and context.object.type == "MESH":
        draw_fabric(self.layout.box(), context.object.flowvid)


class PARTICLE_PT_flowvid_video(bpy.types.Panel):
    bl_label = "Flow Video"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "particle"

    def draw(self, context):
        draw_flow_video(self.layout, context.scene.flowvid)


class DATA_PT_flowvid_strokes(bpy.types.Panel):
    """In a Grease Pencil object's Data tab: its strokes as flow lines."""
    bl_label = "Flow Lines"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type in GREASE_PENCIL_TYPES

    def draw(self, context):
        draw_strokes(self.layout, context.scene.flowvid)


def object_menu(self, context):
    if context.object is not None and context.object.type in GREASE_PENCIL_TYPES:
        self.layout.separator()
        self.layout.operator("flowvid.grease_pencil_flowlines", icon="EXPORT")


classes = (PARTICLE_PT_flowvid_video, DATA_PT_flowvid_strokes)


def register_menus():
    bpy.types.PHYSICS_PT_cloth.prepend(cloth_panel_top)
    bpy.types.VIEW3D_MT_object.append(object_menu)


def unregister_menus():
    bpy.types.VIEW3D_MT_object.remove(object_menu)
    bpy.types.PHYSICS_PT_cloth.remove(cloth_panel_top)
