"""Plain Python API of the add-on for pipeline scripts (needs bpy).

    import flowvid_blender.api as fv
    report = fv.apply_fabric_preset(bpy.data.objects["Skirt"], "silk.fabric.json")
    fv.bake_flowlines(bpy.data.objects["Emitter"], scene.camera, 1, 48, "out.flowlines.json")

Every function raises FlowvidError (a RuntimeError) with a readable message on
failure; the operators turn it into self.report({'ERROR'}, ...). The
functions live by idea: fabric.py (presets), flowlines.py (particles and
strokes to flow lines), video.py (synthesis, showing, rendering), library.py
(reaching the flowvid library); the bpy-free parts are in core/.
"""
from .core.errors import FlowvidError  # noqa: F401
from .core.flowlines import assign_inputs  # noqa: F401
from .fabric import (  # noqa: F401
    CALIBRATION_QUALITIES,
    BlenderSwatchFactory,
    Calibration,
    apply_fabric_preset,
    blender_limits,
    calibrate_fabric_preset,
    calibrate_steps,
    cloth_modifier,
    export_fabric_preset,
    export_steps,
    formula_settings,
    mesh_stats,
    read_preset,
    scene_fps,
    set_cloth_settings,
    store_calibration,
)
from .flowlines import (  # noqa: F401
    bake_flowlines,
    bake_steps,
    grease_pencil_flowlines,
    grease_pencil_strokes,
    particle_paths,
    project_to_pixels,
    render_size,
)
from .library import get_backend  # noqa: F401
from .video import (  # noqa: F401
    encode_video,
    load_image_sequence,
    render_frames,
    run_flowvid_tool,
    show_as_camera_background,
    show_on_camera_plane,
    synthesize,
)
