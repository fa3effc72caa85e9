"""Particle systems -> time-varying flow lines, checked against an independent
pinhole projection built from the camera's parameters."""
import json
import math
import os
import shutil
import sys
import tempfile

import bpy
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "blender_addon"))


def particle_scene(count=12, frame_end=10, keep_preferences=False):
    """Empty scene: an animated camera (moves and zooms, shifted lens, 50% resolution) and a small plane
    emitting particles upwards that fall under gravity. keep_preferences: empty the user's home file instead
    of resetting to factory settings (which would disable the add-ons the user enabled)."""
    if keep_preferences:
        bpy.ops.wm.read_homefile(use_empty=True)
    else:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = 640
    scene.render.resolution_y = 480
    scene.render.resolution_percentage = 50
    scene.frame_start = 1
    scene.frame_end = frame_end

    camera_data = bpy.data.cameras.new("Camera")
    camera_data.lens = 35.0
    camera_data.shift_x = 0.05
    camera_data.shift_y = -0.03
    camera = bpy.data.objects.new("Camera", camera_data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.location = (0.0, -6.0, 1.5)
    camera.rotation_euler = (math.radians(85.0), 0.0, 0.0)
    camera.keyframe_insert("location", frame=1)
    camera_data.keyframe_insert("lens", frame=1)
    camera.location = (1.0, -5.0, 2.0)
    camera_data.lens = 45.0
    camera.keyframe_insert("location", frame=frame_end)
    camera_data.keyframe_insert("lens", frame=frame_end)

    mesh = bpy.data.meshes.new("Emitter")
    mesh.from_pydata([(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0)], [], [(0, 1, 2, 3)])
    emitter = bpy.data.objects.new("Emitter", mesh)
    scene.collection.objects.link(emitter)
    emitter.modifiers.new("Particles", "PARTICLE_SYSTEM")
    settings = emitter.particle_systems[0].settings
    settings.count = count
    settings.frame_start = 1
    settings.frame_end = 3
    settings.lifetime = 100
    settings.normal_factor = 3.0
    settings.factor_random = 0.5
    emitter.particle_systems[0].seed = 7
    return scene, camera, emitter


def record_alive_particles(scene, emitter, frame_end):
    """Each live particle's world position at frames 1..frame_end, read independently of the add-on:
    {particle index: [(x, y, z), ...]}."""
    recorded = {}
    for frame in range(1, frame_end + 1):
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for index, particle in enumerate(emitter.evaluated_get(depsgraph).particle_systems[0].particles):
            if particle.alive_state == "ALIVE":
                recorded.setdefault(index, []).append(tuple(particle.location))
    return recorded


def independent_projection(scene, camera, point):
    """Pixel (x, y), OpenCV convention, from the camera's matrix, lens, sensor, shift and resolution,
    written out as K [R | t] (sensor fit AUTO, square pixels)."""
    width = scene.render.resolution_x * scene.render.resolution_percentage / 100.0
    height = scene.render.resolution_y * scene.render.resolution_percentage / 100.0
    data = camera.data
    size = max(width, height)
    focal_px = data.lens / data.sensor_width * size
    world_to_camera = camera.matrix_world.normalized().inverted()
    p = world_to_camera @ Vector(point)
    depth = -p.z  # Blender cameras look down -z, y up
    cx = 0.5 * width - data.shift_x * size
    cy = 0.5 * height + data.shift_y * size
    return focal_px * p.x / depth + cx - 0.5, -focal_px * p.y / depth + cy - 0.5


def test_particles_projection():
    """Every key of every baked line equals the independent projection of the particle's recorded
    positions with the camera as it is at that key's frame (< 0.5 px)."""
    from flowvid_blender import api

    frame_end = 10
    scene, camera, emitter = particle_scene(frame_end=frame_end)
    recorded = record_alive_particles(scene, emitter, frame_end)
    folder = tempfile.mkdtemp(prefix="flowvid_lines_")
    try:
        path = os.path.join(folder, "particles.flowlines.json")
        summary = api.bake_flowlines(emitter, camera, 1, frame_end, path)
        with open(path) as handle:
            document = json.load(handle)
        assert document["image"] == {"width": 320, "height": 240, "pixel_convention": "opencv"}, document["image"]
        assert api.get_backend().module.flow.validate_flowline_set(path) == []
        worst = 0.0
        checked = 0
        moved = 0.0
        for line in document["outputs"]:
            path3d = recorded[int(line["id"][1:])]
            assert len(line["keys"]) == frame_end, len(line["keys"])
            for key in line["keys"]:
                scene.frame_set(key["frame"])
                assert len(key["points"]) == len(path3d)
                for baked, point in zip(key["points"], path3d):
                    x, y = independent_projection(scene, camera, point)
                    worst = max(worst, math.hypot(baked[0] - x, baked[1] - y))
                    checked += 1
            first, last = line["keys"][0]["points"][0], line["keys"][-1]["points"][0]
            moved = max(moved, math.hypot(first[0] - last[0], first[1] - last[1]))
        print("particles: %d lines, %d points checked, worst %.2e px; the animated camera moves a line by "
              "up to %.1f px" % (summary["lines"], checked, worst, moved))
        assert summary["lines"] >= 6 and checked > 100
        assert worst < 0.5, worst
        assert moved > 5.0, "the camera animation should make the lines time-varying"
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_grease_pencil_flowlines():
    """Strokes on layers 'input' and 'output' become input and output flow lines (projected)."""
    from flowvid_blender import api

    scene, camera, _emitter = particle_scene()
    scene.frame_set(1)
    data = bpy.data.grease_pencils.new("Sketch")
    gp = bpy.data.objects.new("Sketch", data)
    scene.collection.objects.link(gp)
    strokes = {"input": [[(-1, 0, 2), (-1, 0, 0)]], "output": [[(1, 0, 2), (1.2, 0, 1), (1, 0, 0)]]}
    for name, lines in strokes.items():
        layer = data.layers.new(name)
        frame = layer.frames.new(1)
        for points in lines:
            stroke = frame.strokes.new()
            stroke.points.add(len(points))
            for p, co in zip(stroke.points, points):
                p.co = co
    folder = tempfile.mkdtemp(prefix="flowvid_gp_")
    try:
        path = os.path.join(folder, "sketch.flowlines.json")
        summary = api.grease_pencil_flowlines(gp, camera, path, scene=scene)
        with open(path) as handle:
            document = json.load(handle)
        assert summary["inputs"] == 1 and summary["outputs"] == 1
        assert document["outputs"][0]["from"] == "in-1"
        x, y = independent_projection(scene, camera, (1.2, 0, 1))
        got = document["outputs"][0]["points"][1]
        assert math.hypot(got[0] - x, got[1] - y) < 0.5, (got, x, y)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_assign_inputs_nearest_keeps_the_flow_under_the_line():
    """The default rule gives each output line the nearest input line flowing its way; the direction
    rule gives every near-vertical line the most vertical input, wherever it is drawn."""
    from flowvid_blender import api

    inputs = [{"id": "in-1", "points": [[100, 0], [100, 300]]},      # exactly vertical
              {"id": "in-2", "points": [[190, 0], [210, 300]]},      # tilted 3.8 degrees
              {"id": "up", "points": [[204, 300], [204, 0]]},        # nearest, but flowing the other way
              {"id": "in-3", "points": [[300, 0], [300, 300]]}]
    outputs = [{"id": "a", "points": [[205, 0], [205, 300]]},
               {"id": "b", "keys": [{"frame": 1, "points": [[290, 0], [296, 300]]},
                                    {"frame": 2, "points": [[120, 0], [120, 300]]}]},
               {"id": "c", "points": [[110, 0], [110, 300]]}]
    api.assign_inputs(outputs, inputs)
    assert [line["from"] for line in outputs] == ["in-2", "in-3", "in-1"], outputs
    api.assign_inputs(outputs, inputs, rule="direction")
    assert [line["from"] for line in outputs] == ["in-1", "in-1", "in-1"], outputs
    api.assign_inputs(outputs, inputs, by_hand={"a": "in-3"})
    assert outputs[0]["from"] == "in-3"
    try:
        api.assign_inputs(outputs, inputs, rule="closest")
    except api.FlowvidError as error:
        assert "nearest, direction or cycle" in str(error)
    else:
        raise AssertionError("an unknown rule should be refused")
