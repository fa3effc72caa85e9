"""Add-on properties: per object (fabric preset) and per scene (flow video)."""
import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty, StringProperty


class FlowvidObjectSettings(bpy.types.PropertyGroup):
    fabric_preset: StringProperty(name="Fabric preset", subtype="FILE_PATH",
                                  description="A *.fabric.json fitted by flowvid")
    summary: StringProperty(name="Summary", description="The loaded preset, one 'Label: value' line per entry")
    last_status: StringProperty(name="Last Status", description="What the last Apply or Calibrate did, in a line")
    last_warning: StringProperty(name="Last Warning", description="What the artist should know about the last "
                                                                  "Apply, in a line (Details says why), or empty")
    last_report: StringProperty(name="Last Report", description="What Apply/Calibrate set and could not represent, "
                                                                "one note per line (Details shows them)")


def _is_camera(_self, obj):
    return obj.type == "CAMERA"


def _has_particles(_self, obj):
    return obj.type == "MESH" and len(obj.particle_systems) > 0


def _is_grease_pencil(_self, obj):
    return obj.type in ("GPENCIL", "GREASEPENCIL")  # up to 4.2, from 4.3


def _scene_frame(key):
    # The scene's frame range until the user sets one here (a property whose default follows the scene).
    def get(self):
        return self.get("chosen_" + key, getattr(self.id_data, key))

    def set(self, value):
        self["chosen_" + key] = value

    return get, set


class FlowvidSceneSettings(bpy.types.PropertyGroup):
    emitter: PointerProperty(name="Emitter", type=bpy.types.Object, poll=_has_particles,
                             description="Object whose particle system gives the output flow lines")
    particle_system: IntProperty(name="Particle System", min=0, default=0)
    camera: PointerProperty(name="Camera", type=bpy.types.Object, poll=_is_camera,
                            description="Camera the lines are seen through (the scene camera when empty)")
    frame_start: IntProperty(name="Frame Start", min=0, get=_scene_frame("frame_start")[0],
                             set=_scene_frame("frame_start")[1],
                             description="First frame to bake and synthesize (the scene's until set here)")
    frame_end: IntProperty(name="End", min=0, get=_scene_frame("frame_end")[0], set=_scene_frame("frame_end")[1],
                           description="Last frame to bake and synthesize (the scene's until set here)")
    strokes: PointerProperty(name="Strokes", type=bpy.types.Object, poll=_is_grease_pencil,
                             description="Grease Pencil object whose layers 'input' and 'output' hold drawn flow "
                                         "lines (the active one when it is a Grease Pencil)")
    input_lines: StringProperty(name="Input Lines", subtype="FILE_PATH",
                                description="Flow-line set (or SVG) the particle bank was tracked with")
    bank: StringProperty(name="Bank", subtype="FILE_PATH", description="*.bank.exr from flowvid track")
    flowlines: StringProperty(name="Flow Lines", subtype="FILE_PATH", default="//flowvid/particles.flowlines.json")
    output_dir: StringProperty(name="Frames", subtype="DIR_PATH", default="//flowvid/frames/",
                               description="Folder the synthesized frames are written to")
    rule: EnumProperty(name="Assign", description="Which input line each output line takes its texture from", default="nearest", items=(
        ("nearest", "Nearest", "Each output line takes the nearest input line flowing its way: it keeps the "
                               "texture of the flow it is drawn over"),
        ("direction", "By Direction", "Each output line takes the input line whose direction is closest"),
        ("cycle", "In Turn", "Output lines take the input lines one after the other"),
    ))
    by_hand: StringProperty(name="By Hand", description="Overrides of the rule, output=input: 'p3=in-2, p7=in-1'")
    background: EnumProperty(name="Background", default="median", items=(
        ("median", "Median Plate", "Where no line reaches: the clip's static median frame"),
        ("loop", "Looped Clip", "Where no line reaches: the clip itself, looped"),
        ("replay", "Replayed Clip", "Where no line reaches: the clip frame the particles show"),
        ("relit", "Relit Plate", "Where no line reaches: the median plate, darkened where the frame the particles "
                                 "show is darker (the light of flames comes and goes on the scene)"),
        ("none", "Black", "Where no line reaches: black, to add the texture over a render"),
    ), description="What shows where no output line carries texture (flowvid edit --background)")
    texture: EnumProperty(name="Texture", default="whole", items=(
        ("whole", "Whole Patches", "Particles carry everything in their patches (water)"),
        ("moving", "Moving Light", "Particles carry only the light flames or smoke add to the scene, screened "
                                        "over its dark plate (or over black): edits leave the scene behind them"),
    ), description="What each particle's patch carries (flowvid edit --texture)")
    display: EnumProperty(name="Show as", default="PLANE", items=(
        ("PLANE", "Camera Plane", "Rendered: an emissive plane facing the camera, filling its view"),
        ("BACKGROUND", "Background", "Viewport only: the camera's background image (not rendered)"),
    ))


classes = (FlowvidObjectSettings, FlowvidSceneSettings)


def register_properties():
    bpy.types.Object.flowvid = PointerProperty(type=FlowvidObjectSettings)
    bpy.types.Scene.flowvid = PointerProperty(type=FlowvidSceneSettings)


def unregister_properties():
    del bpy.types.Scene.flowvid
    del bpy.types.Object.flowvid
