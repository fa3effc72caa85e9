"""Flow lines from Blender: particle systems and Grease Pencil strokes seen
through a camera, written as *.flowlines.json (needs bpy; which input line an
output line takes is core/flowlines.py)."""
import bpy
from mathutils import Vector

from .core import jobs
from .core.backend import BackendError
from .core.errors import FlowvidError
from .core.flowlines import assign_inputs
from .library import get_backend


def render_size(scene):
    scale = scene.render.resolution_percentage / 100.0
    return int(round(scene.render.resolution_x * scale)), int(round(scene.render.resolution_y * scale))


def project_to_pixels(scene, camera, point):
    """World point -> (x, y) pixels, OpenCV convention (y down, top-left pixel centre at 0, 0), and depth."""
    from bpy_extras.object_utils import world_to_camera_view

    width, height = render_size(scene)
    ndc = world_to_camera_view(scene, camera, point)
    return (ndc.x * width - 0.5, (1.0 - ndc.y) * height - 0.5), ndc.z


def _resample(points, count):
    """A polyline resampled to `count` points evenly by arc length (in 3D)."""
    if len(points) == count:
        return list(points)
    lengths = [0.0]
    for a, b in zip(points, points[1:]):
        lengths.append(lengths[-1] + (b - a).length)
    total = lengths[-1]
    result = []
    j = 0
    for k in range(count):
        s = total * k / (count - 1)
        while j < len(points) - 2 and lengths[j + 1] < s:
            j += 1
        span = lengths[j + 1] - lengths[j]
        t = 0.0 if span <= 0 else (s - lengths[j]) / span
        result.append(points[j].lerp(points[j + 1], min(max(t, 0.0), 1.0)))
    return result


def particle_paths(emitter, frame_start, frame_end, scene=None, system=0, max_points=32, min_length_m=1e-4):
    """World-space trajectory of every particle alive in [frame_start, frame_end]: {index: [Vector]}.

    Paths are resampled to at most max_points by 3D arc length (exact positions
    when the particle lived fewer frames)."""
    return jobs.run_to_end(_particle_path_steps(emitter, frame_start, frame_end, scene, system, max_points,
                                                min_length_m))


def _particle_path_steps(emitter, frame_start, frame_end, scene, system, max_points, min_length_m, share=1.0):
    scene = scene or bpy.context.scene
    if emitter is None or not emitter.particle_systems:
        raise FlowvidError("%s has no particle system" % (emitter.name if emitter else "nothing"))
    if system >= len(emitter.particle_systems):
        raise FlowvidError("%s has no particle system %d" % (emitter.name, system))
    paths = {}
    for frame in range(frame_start, frame_end + 1):
        yield share * (frame - frame_start) / (frame_end - frame_start + 1), "particles at frame %d" % frame
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        particles = emitter.evaluated_get(depsgraph).particle_systems[system].particles
        for index, particle in enumerate(particles):
            if particle.alive_state == "ALIVE":
                paths.setdefault(index, []).append(particle.location.copy())
    result = {}
    for index, path in paths.items():
        length = sum((b - a).length for a, b in zip(path, path[1:]))
        if len(path) >= 2 and length > min_length_m:
            result[index] = _resample(path, min(len(path), max_points))
    return result


def _input_lines(inputs):
    if inputs is None:
        return None
    if isinstance(inputs, str):
        try:
            return get_backend().read_flowline_set(bpy.path.abspath(inputs))["inputs"]
        except BackendError as error:
            raise FlowvidError(str(error)) from None
    return list(inputs)


def bake_flowlines(emitter, camera, frame_start, frame_end, path, inputs=None, system=0, rule="nearest",
                   by_hand=None, max_points=32, scene=None):
    """Writes a flow-line set of the particles' trajectories seen through the camera (bake_steps to the end;
    the scene's current frame is put back)."""
    return jobs.run_to_end(bake_steps(emitter, camera, frame_start, frame_end, path, inputs, system, rule, by_hand,
                                      max_points, scene))


def bake_steps(emitter, camera, frame_start, frame_end, path, inputs=None, system=0, rule="nearest",
               by_hand=None, max_points=32, scene=None):
    """Writes a flow-line set whose output lines are the particles' trajectories seen through the camera.

    Every particle alive during [frame_start, frame_end] gives one output line
    "p<index>" with one key per frame: its whole 3D trajectory projected
    through the camera as it is at that frame (an animated camera gives lines
    that move). inputs: a flow-line file (e.g. the one a particle bank was
    tracked with) or a list of input lines; without them, one input line is made
    from the mean trajectory (replace it before synthesis). Returns a summary dict."""
    scene = scene or bpy.context.scene
    if emitter is None or not emitter.particle_systems:
        raise FlowvidError("%s has no particle system: choose an emitter" % (emitter.name if emitter else "nothing"))
    if camera is None or camera.type != "CAMERA":
        raise FlowvidError("no camera: set the scene camera or pass one")
    if frame_end < frame_start:
        raise FlowvidError("frame range %d..%d is empty" % (frame_start, frame_end))
    current = scene.frame_current
    try:
        summary = yield from _bake(emitter, camera, frame_start, frame_end, path, inputs, system, rule, by_hand,
                                   max_points, scene)
    finally:
        scene.frame_set(current)
    return summary


def _bake(emitter, camera, frame_start, frame_end, path, inputs, system, rule, by_hand, max_points, scene):
    paths = yield from _particle_path_steps(emitter, frame_start, frame_end, scene, system, max_points, 1e-4, 0.5)
    if not paths:
        raise FlowvidError("no particle of %s is alive and moving in frames %d..%d" % (emitter.name, frame_start,
                                                                                      frame_end))
    width, height = render_size(scene)
    keys = {index: [] for index in paths}
    for frame in range(frame_start, frame_end + 1):
        yield 0.5 + 0.5 * (frame - frame_start) / (frame_end - frame_start + 1), "projecting frame %d" % frame
        scene.frame_set(frame)
        for index, path3d in paths.items():
            points = [list(project_to_pixels(scene, camera, p)[0]) for p in path3d]
            keys[index].append({"frame": frame, "points": points})
    outputs = []
    for index in sorted(paths):
        line_keys = keys[index]
        if len(line_keys) == 1:
            outputs.append({"id": "p%d" % index, "points": line_keys[0]["points"]})
        else:
            outputs.append({"id": "p%d" % index, "keys": line_keys})
    input_lines = _input_lines(inputs)
    if not input_lines:
        first = outputs[0]["keys"][0]["points"] if "keys" in outputs[0] else outputs[0]["points"]
        input_lines = [{"id": "in-1", "points": first}]
    assign_inputs(outputs, input_lines, rule, by_hand)
    document = {
        "format": "flowvid.flowlines", "version": "1.0",
        "description": "particles of %s seen through %s, frames %d-%d (Blender %s)" % (
            emitter.name, camera.name, frame_start, frame_end, bpy.app.version_string.split()[0]),
        "image": {"width": width, "height": height, "pixel_convention": "opencv"},
        "inputs": [{"id": line["id"], "points": line["points"]} for line in input_lines],
        "outputs": outputs,
    }
    path = bpy.path.abspath(path)
    try:
        get_backend().write_flowline_set(path, document)
    except BackendError as error:
        raise FlowvidError(str(error)) from None
    return {"path": path, "lines": len(outputs), "frames": frame_end - frame_start + 1, "width": width,
            "height": height}


# Object types of Grease Pencil: "GPENCIL" up to Blender 4.2, "GREASEPENCIL" (GPv3) from 4.3.
GREASE_PENCIL_TYPES = ("GPENCIL", "GREASEPENCIL")


def _shown_frame(frames, current):
    """The keyframe shown at `current`: the last one at or before it (else the first)."""
    frames = list(frames)
    shown = [f for f in frames if f.frame_number <= current]
    return max(shown, key=lambda f: f.frame_number) if shown else (frames[0] if frames else None)


def _strokes_legacy(data, current):
    """(layer name, [local points]) per stroke with the Grease Pencil API of Blender 2.8 to 4.2
    (bpy.types.GreasePencil: layer.info, frame.strokes, point.co)."""
    for layer in data.layers:
        frame = _shown_frame(layer.frames, current)
        for stroke in frame.strokes if frame is not None else ():
            yield layer.info, [p.co for p in stroke.points]


def _strokes_v3(data, current):
    """The same with Grease Pencil v3, Blender 4.3+ (bpy.types.GreasePencilv3). Checked against
    docs.blender.org/api/4.3: bpy.types.GreasePencilLayer.html (name, frames), GreasePencilFrame.html
    (frame_number, drawing), GreasePencilDrawing.html (strokes) and GreasePencilStrokePoint.html (position).
    Blender 3.4 cannot run this."""
    for layer in data.layers:
        frame = _shown_frame(layer.frames, current)
        drawing = frame.drawing if frame is not None else None
        for stroke in drawing.strokes if drawing is not None else ():
            yield layer.name, [Vector(p.position) for p in stroke.points]


def grease_pencil_strokes(gpencil, current):
    """(layer name, [local points]) for each stroke shown at frame `current`, whichever API this Blender has."""
    layer = next(iter(gpencil.data.layers), None)
    legacy = layer is None or hasattr(layer, "info")  # v3 layers have `name` only
    return list(_strokes_legacy(gpencil.data, current) if legacy else _strokes_v3(gpencil.data, current))


def grease_pencil_flowlines(gpencil, camera, path, scene=None, frame=None):
    """Exports Grease Pencil strokes as flow lines: strokes on a layer named "input" become input lines,
    on "output" output lines (their `from` by the nearest rule). Stroke point order is the flow direction."""
    scene = scene or bpy.context.scene
    if gpencil is None or gpencil.type not in GREASE_PENCIL_TYPES:
        raise FlowvidError("%s is not a Grease Pencil object" % (gpencil.name if gpencil else "nothing"))
    if camera is None:
        raise FlowvidError("no camera to project the strokes through")
    if frame is not None:
        scene.frame_set(frame)
    lines = {"input": [], "output": []}
    for name, stroke in grease_pencil_strokes(gpencil, scene.frame_current):
        kind = name.lower()
        if kind not in lines:
            continue
        points = [list(project_to_pixels(scene, camera, gpencil.matrix_world @ p)[0]) for p in stroke]
        cleaned = [p for i, p in enumerate(points) if i == 0 or p != points[i - 1]]
        if len(cleaned) >= 2:
            lines[kind].append({"id": "%s-%d" % ("in" if kind == "input" else "out", len(lines[kind]) + 1),
                                "points": cleaned})
    if not lines["input"]:
        raise FlowvidError("no strokes on a Grease Pencil layer named 'input' (draw the input flow lines there)")
    assign_inputs(lines["output"], lines["input"])
    width, height = render_size(scene)
    document = {"format": "flowvid.flowlines", "version": "1.0",
                "description": "Grease Pencil %s through %s" % (gpencil.name, camera.name),
                "image": {"width": width, "height": height, "pixel_convention": "opencv"},
                "inputs": lines["input"], "outputs": lines["output"]}
    try:
        get_backend().write_flowline_set(bpy.path.abspath(path), document)
    except BackendError as error:
        raise FlowvidError(str(error)) from None
    return {"path": path, "inputs": len(lines["input"]), "outputs": len(lines["output"])}
