"""Flow-based video in Blender: synthesis through the library, the frames on a
camera-facing plane or as the camera's background, rendering and encoding
(needs bpy)."""
import os

import bpy

from .core import backend as backend_module
from .core.backend import BackendError
from .core.errors import FlowvidError
from .library import find_tool, get_backend
from .flowlines import render_size


def run_flowvid_tool(*arguments):
    """Runs the flowvid command-line tool (e.g. track, which has no binding); raises FlowvidError with its message."""
    executable = find_tool()
    if not executable:
        raise FlowvidError("the flowvid tool was not found: set its path in Edit > Preferences > Add-ons > flowvid")
    try:
        return backend_module.CliBackend(executable).run(*arguments)
    except BackendError as error:
        raise FlowvidError("flowvid %s failed: %s" % (arguments[0], str(error)[-2000:])) from None


def synthesize(bank, flowlines, frame_start, frame_end, out_dir, background=None, texture=None, capture=None,
               progress=None, edge_fade=None):
    """flowvid edit for the frame range, in process where the module is there (else through the tool): PNG
    frames out_dir/%06d.png; returns the first frame's path.
    background: auto, median, loop, replay, relit or none (None: auto). texture: auto, whole or moving
    (moving keeps only the light flames or smoke add to the scene, screened over its dark plate or over
    black; None: auto). capture: the source clip (None: the one the bank records). edge_fade: px over which
    the texture fades out where it ends (None: auto, a patch for whole textures; 0: a hard edge).
    progress(stage, fraction, message) -> False cancels."""
    os.makedirs(out_dir, exist_ok=True)
    pattern = os.path.join(out_dir, "%06d.png")
    try:
        get_backend().synthesize(bank, pattern, (frame_start, frame_end), edit=True, flowlines=flowlines,
                                 capture=capture or "", background=background or "auto", texture=texture or "auto",
                                 progress=progress, edge_fade=edge_fade)
    except BackendError as error:
        raise FlowvidError("synthesis failed: %s" % error) from None
    return pattern % frame_start


def load_image_sequence(first_frame_path, frame_start, frame_count):
    image = bpy.data.images.load(first_frame_path, check_existing=True)
    image.source = "SEQUENCE"
    return image


def show_on_camera_plane(camera, image, frame_start, frame_count, distance=None, scene=None):
    """A plane filling the camera's view at `distance`, parented to the camera, textured with the
    image sequence (emission, so lighting does not change it). Returns the plane object."""
    scene = scene or bpy.context.scene
    cam = camera.data
    distance = distance or 0.5 * (cam.clip_start + min(cam.clip_end, 100.0 * cam.clip_start + 10.0))
    width_px, height_px = render_size(scene)
    frame = cam.view_frame(scene=scene)  # corners at depth -1 (camera space); scale to distance
    xs = [c.x for c in frame]
    ys = [c.y for c in frame]
    depth = -frame[0].z
    sx = (max(xs) - min(xs)) * distance / depth
    sy = (max(ys) - min(ys)) * distance / depth
    mesh = bpy.data.meshes.new("flowvid_plane")
    hx, hy = 0.5 * sx, 0.5 * sy
    cx = 0.5 * (max(xs) + min(xs)) * distance / depth
    cy = 0.5 * (max(ys) + min(ys)) * distance / depth
    mesh.from_pydata([(cx - hx, cy - hy, -distance), (cx + hx, cy - hy, -distance), (cx + hx, cy + hy, -distance),
                      (cx - hx, cy + hy, -distance)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new()
    for loop, coords in zip(uv.data, ((0, 0), (1, 0), (1, 1), (0, 1))):
        loop.uv = coords
    plane = bpy.data.objects.new("flowvid_plane", mesh)
    scene.collection.objects.link(plane)
    plane.parent = camera
    material = bpy.data.materials.new("flowvid_sequence")
    material.use_nodes = True
    nodes = material.node_tree.nodes
    links = material.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    emission = nodes.new("ShaderNodeEmission")
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.interpolation = "Closest"
    texture.image_user.frame_duration = frame_count
    texture.image_user.frame_start = frame_start
    texture.image_user.frame_offset = frame_start - 1
    texture.image_user.use_auto_refresh = True
    links.new(texture.outputs["Color"], emission.inputs["Color"])
    links.new(emission.outputs["Emission"], out.inputs["Surface"])
    mesh.materials.append(material)
    return plane


def show_as_camera_background(camera, image, frame_start, frame_count):
    """The image sequence as the camera's viewport background (not rendered; use the plane for renders)."""
    cam = camera.data
    cam.show_background_images = True
    background = cam.background_images.new()
    background.image = image
    background.image_user.frame_duration = frame_count
    background.image_user.frame_start = frame_start
    background.image_user.use_auto_refresh = True
    return background


def render_frames(out_dir, frame_start, frame_end, scene=None):
    """Renders the frames to out_dir/####.png; returns the file paths."""
    scene = scene or bpy.context.scene
    os.makedirs(out_dir, exist_ok=True)
    scene.render.image_settings.file_format = "PNG"
    paths = []
    for frame in range(frame_start, frame_end + 1):
        scene.frame_set(frame)
        scene.render.filepath = os.path.join(out_dir, "%04d.png" % frame)
        bpy.ops.render.render(write_still=True, scene=scene.name)
        paths.append(scene.render.filepath)
    return paths


def encode_video(frame_paths, out_path, fps, scene=None):
    """Joins rendered frames (same size, in order) into one H.264 MP4 through Blender's sequencer, in a
    temporary scene so the caller's scene keeps its settings. Returns out_path."""
    if not frame_paths:
        raise FlowvidError("no frames to encode")
    source = scene or bpy.context.scene
    width, height = render_size(source)
    movie = bpy.data.scenes.new("flowvid_encode")
    try:
        movie.render.resolution_x, movie.render.resolution_y = width, height
        movie.render.resolution_percentage = 100
        movie.render.fps = int(round(fps))
        movie.render.fps_base = movie.render.fps / fps
        movie.sequence_editor_create()
        folder = os.path.dirname(os.path.abspath(frame_paths[0]))
        strip = movie.sequence_editor.sequences.new_image("frames", os.path.abspath(frame_paths[0]), 1, 1)
        for path in frame_paths[1:]:
            if os.path.dirname(os.path.abspath(path)) != folder:
                raise FlowvidError("frames to encode must share one folder: %s" % path)
            strip.elements.append(os.path.basename(path))
        movie.frame_start, movie.frame_end = 1, len(frame_paths)
        movie.render.image_settings.file_format = "FFMPEG"
        movie.render.ffmpeg.format = "MPEG4"
        movie.render.ffmpeg.codec = "H264"
        movie.render.ffmpeg.constant_rate_factor = "HIGH"
        movie.render.filepath = os.path.abspath(out_path)
        movie.render.use_file_extension = False
        os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
        bpy.ops.render.render(animation=True, scene=movie.name)
    finally:
        bpy.data.scenes.remove(movie)
    if not os.path.isfile(out_path):
        raise FlowvidError("Blender wrote no video to %s (is its FFmpeg support installed?)" % out_path)
    return out_path
