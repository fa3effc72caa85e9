"""Add-on properties: per object (fabric preset) and per scene (flow video)."""
import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty, StringProperty


class FlowvidObjectSettings(bpy.types.PropertyGroup):
    fabric_preset: StringProperty(name="Fabric preset", subtype="FILE_PATH",
                                  description="A *.fabric.json fitted by flowvid")
    summary: StringProperty(name="Summary", description="The loaded preset, one line per entry (\\n separated)")
    last_report: StringProperty(name="Last report", description="What Apply/Calibrate set and could not represent")


def _is_camera(_self, obj):
    return obj.type == "CAMERA"


def _has_particles(_self, obj):
    return obj.type == "MESH" and len(obj.particle_systems) > 0


class FlowvidSceneSettings(bpy.types.PropertyGroup):
    emitter: PointerProperty(name="Emitter", type=bpy.types.Object, poll=_has_particles,
                             description="Object whose particle system gives the output flow lines")
    particle_system: IntProperty(name="Particle system", min=0, default=0)
    camera: PointerProperty(name="Camera", type=bpy.types.Object, poll=_is_camera,
                            description="Camera the lines are seen through (the scene camera when empty)")
    frame_start: IntProperty(name="Start", default=1, min=0)
    frame_end: IntProperty(name="End", default=48, min=0)
    input_lines: StringProperty(name="Input lines", subtype="FILE_PATH",
                                description="Flow-line set (or SVG) the particle bank was tracked with")
    bank: StringProperty(name="Particle bank", subtype="FILE_PATH", description="*.bank.exr from flowvid track")
    flowlines: StringProperty(name="Flow lines", subtype="FILE_PATH", default="//flowvid/particles.flowlines.json")
    output_dir: StringProperty(name="Frames", subtype="DIR_PATH", default="//flowvid/frames/")
    rule: EnumProperty(name="Assign inputs", default="nearest", items=(
        ("nearest", "Nearest", "Each output line takes the nearest input line flowing its way: it keeps the "
                               "texture of the flow it is drawn over"),
        ("direction", "By direction", "Each output line takes the input line whose direction is closest"),
        ("cycle", "In turn", "Output lines take the input lines one after the other"),
    ))
    by_hand: StringProperty(name="By hand", description="Overrides: 'p3=in-2, p7=in-1'")
    background: EnumProperty(name="Background", default="median", items=(
        ("median", "Median plate", "Where no line reaches: the clip's static median frame"),
        ("loop", "Looped clip", "Where no line reaches: the clip itself, looped"),
        ("replay", "Replayed clip", "Where no line reaches: the clip frame the particles show"),
        ("relit", "Relit plate", "Where no line reaches: the median plate, darkened where the frame the particles "
                                 "show is darker (the light of flames comes and goes on the scene)"),
        ("none", "Black", "Where no line reaches: black, to add the texture over a render"),
    ), description="What shows where no output line carries texture (flowvid edit --background)")
    texture: EnumProperty(name="Texture", default="whole", items=(
        ("whole", "Whole patches", "Particles carry everything in their patches (water)"),
        ("moving", "Moving light only", "Particles carry only the light flames or smoke add to the scene, screened "
                                        "over its dark plate (or over black): edits leave the scene behind them"),
    ), description="What each particle's patch carries (flowvid edit --texture)")
    display: EnumProperty(name="Show as", default="PLANE", items=(
        ("PLANE", "Plane facing the camera", "Rendered: an emissive plane filling the camera view"),
        ("BACKGROUND", "Camera background", "Viewport only: the camera's background image"),
    ))


classes = (FlowvidObjectSettings, FlowvidSceneSettings)


def register_properties():
    bpy.types.Object.flowvid = PointerProperty(type=FlowvidObjectSettings)
    bpy.types.Scene.flowvid = PointerProperty(type=FlowvidSceneSettings)


def unregister_properties():
    del bpy.types.Scene.flowvid
    del bpy.types.Object.flowvid
