"""Calibration swatches in Blender's own cloth solver.

A temporary scene holds two rows x cols quad grids, one per experiment. Their
rest shape (a shape key used as the cloth's rest shape) is the flat swatch;
their start shape is given (the library's static equilibrium in calibration,
so both solvers start from the same state). Pinned vertices follow keyframed
empties through hook modifiers.

* static: pins still. Its equilibrium does not depend on damping, so it runs
  with the air damping raised (STATIC_AIR_DAMPING_FACTOR, clamped to
  Blender's maximum): otherwise slow swings of hung cloth outlast the run
  (measured: a 6 cm cotton cantilever still swings +-7 mm after 8 s).
* waving: Blender frame 1 is the start state (library frame 0); frame 1 + k
  is library frame k, pins at the waving positions.
"""
import bpy
from mathutils import Matrix, Vector

from ..core import calibration

STATIC_AIR_DAMPING_FACTOR = 30.0


def static_settings(settings, air_damping_max=10.0):
    """The settings of the static run: the same, with the air damping raised."""
    result = dict(settings)
    result["air_damping"] = min(air_damping_max, max(settings["air_damping"], 1e-3) * STATIC_AIR_DAMPING_FACTOR)
    return result


class _SwatchObject:
    def __init__(self, scene, name, experiment, start_positions, rows, cols, frame_count, rest_positions=None):
        flat = rest_positions or calibration.flat_grid(experiment["width_m"], experiment["height_m"], rows, cols)
        faces = []
        for r in range(rows - 1):
            for c in range(cols - 1):
                a = calibration.grid_vertex(r, c, cols)
                faces.append((a, a + 1, a + cols + 1, a + cols))
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([tuple(p) for p in start_positions], [], faces)
        mesh.update()
        obj = bpy.data.objects.new(name, mesh)
        scene.collection.objects.link(obj)
        self.object = obj
        obj.shape_key_add(name="Basis", from_mix=False)
        rest = obj.shape_key_add(name="flat", from_mix=False)
        for i, p in enumerate(flat):
            rest.data[i].co = p
        rest.value = 0.0

        group = obj.vertex_groups.new(name="pin")
        self.empties = []
        self.pinned = []
        for index, pin in enumerate(experiment["pins"]):
            u, v = pin["uv"]
            vertex = calibration.grid_vertex(round(v * (rows - 1)), round(u * (cols - 1)), cols)
            self.pinned.append(vertex)
            group.add([vertex], 1.0, "REPLACE")
            empty = bpy.data.objects.new("%s_pin%d" % (name, index), None)
            scene.collection.objects.link(empty)
            start = Vector(start_positions[vertex])
            positions = pin["positions_m"][:frame_count]
            for frame, p in enumerate(positions, start=1):
                empty.location = p
                empty.keyframe_insert("location", frame=frame)
            for curve in empty.animation_data.action.fcurves:
                for key in curve.keyframe_points:
                    key.interpolation = "LINEAR"
            hook = obj.modifiers.new("pin%d" % index, "HOOK")
            hook.object = empty
            hook.vertex_indices_set([vertex])
            # The hook moves the vertex by the empty's motion away from the vertex's start.
            hook.matrix_inverse = Matrix.Translation(start).inverted()
            self.empties.append(empty)

        modifier = obj.modifiers.new("Cloth", "CLOTH")
        self.modifier = modifier
        modifier.settings.vertex_group_mass = "pin"
        modifier.settings.rest_shape_key = rest
        modifier.collision_settings.use_collision = False
        modifier.collision_settings.use_self_collision = False
        modifier.point_cache.frame_start = 1
        modifier.point_cache.frame_end = frame_count
        self.frame_count = frame_count

    def apply(self, settings):
        cloth = self.modifier.settings
        for key, value in settings.items():
            setattr(cloth, key, value)
        # Changing settings marks the cache outdated; frame 1 resets it.
        self.modifier.point_cache.frame_end = self.frame_count

    def remove(self):
        for empty in self.empties:
            action = empty.animation_data.action if empty.animation_data else None
            bpy.data.objects.remove(empty)
            if action is not None and action.users == 0:
                bpy.data.actions.remove(action)
        mesh = self.object.data
        bpy.data.objects.remove(self.object)
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)  # its shape keys go with it


class BlenderSwatch:
    """The static and waving experiments in one temporary scene.

    static_frames: length of the static run (its last frame is compared);
    waving["frame_count"] frames of waving. rest_positions: the flat rest shape (default: the hung
    swatch's, calibration.flat_grid)."""

    def __init__(self, static, waving, static_start, rows, cols, waving_start=None, static_frames=120,
                 rest_positions=None, name="flowvid_swatch"):
        self.rows = rows
        self.cols = cols
        self.static_frames = static_frames
        self.waving_frames = waving["frame_count"]
        scene = bpy.data.scenes.new(name)
        self.scene = scene
        scene.render.fps = int(round(static["fps"]))
        scene.render.fps_base = scene.render.fps / static["fps"]
        scene.frame_start = 1
        scene.frame_end = max(static_frames, self.waving_frames)
        scene.use_gravity = True
        scene.gravity = (0.0, 0.0, -9.81)
        still = dict(static, pins=[dict(p, positions_m=[p["positions_m"][0]] * static_frames)
                                   for p in static["pins"]])
        self.static = _SwatchObject(scene, name + "_static", still, static_start, rows, cols, static_frames,
                                    rest_positions)
        self.waving = _SwatchObject(scene, name + "_waving", waving, waving_start or static_start, rows, cols,
                                    self.waving_frames, rest_positions)
        self.pinned = self.static.pinned

    def run(self, settings, should_continue=None, static_override=None):
        """Simulates both experiments with these cloth settings (the static one with static_settings()
        unless static_override is given). Returns (static final frame, waving frames) as lists of
        (x, y, z) per vertex, or None when should_continue() asked to stop."""
        self.static.apply(static_override or static_settings(settings))
        self.waving.apply(settings)
        view_layer = self.scene.view_layers[0]
        with bpy.context.temp_override(scene=self.scene, view_layer=view_layer):
            depsgraph = bpy.context.evaluated_depsgraph_get()
        static_final = None
        waving = []
        for frame in range(1, self.scene.frame_end + 1):
            if should_continue is not None and frame % 10 == 0 and not should_continue():
                return None
            self.scene.frame_set(frame)
            if frame <= self.waving_frames:
                evaluated = self.waving.object.evaluated_get(depsgraph)
                waving.append([tuple(v.co) for v in evaluated.data.vertices])
            if frame == self.static_frames:
                evaluated = self.static.object.evaluated_get(depsgraph)
                static_final = [tuple(v.co) for v in evaluated.data.vertices]
        return static_final, waving

    def remove(self):
        self.static.remove()
        self.waving.remove()
        bpy.data.scenes.remove(self.scene)
