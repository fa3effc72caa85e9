"""Plain Python API of the add-on for pipeline scripts (needs bpy).

    import flowvid_blender.api as fv
    report = fv.apply_fabric_preset(bpy.data.objects["Skirt"], "silk.fabric.json")
    fv.bake_flowlines(bpy.data.objects["Emitter"], scene.camera, 1, 48, "out.flowlines.json")

Every function raises FlowvidError (a RuntimeError) with a readable message on
failure; the operators turn it into self.report({'ERROR'}, ...).
"""
import datetime
import math
import os

import bpy

from .core import backend as backend_module
from .core import calibration as cal
from .core import mapping
from .core.backend import BackendError


class FlowvidError(RuntimeError):
    """A failure with a message meant for the artist."""


_BACKEND = None


def _checkout_build(pattern):
    """In a development checkout: the most recently built file matching build*/PATTERN, else None."""
    import glob

    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    built = sorted(glob.glob(os.path.join(repo, "build*", pattern)), key=os.path.getmtime)
    return built[-1] if built else None


def get_backend():
    """The flowvid library (native module, else CLI); cached."""
    global _BACKEND
    if _BACKEND is None:
        candidates = []
        if not os.environ.get("FLOWVID_PYTHON_DIR"):
            module = _checkout_build(os.path.join("python", "flowvid*.so"))
            candidates = [os.path.dirname(module)] if module else []
        try:
            _BACKEND = backend_module.find_backend(module_paths=candidates, executable=_checkout_tool())
        except BackendError as error:
            raise FlowvidError(str(error)) from None
    return _BACKEND


def _checkout_tool():
    return None if backend_module.find_tool() else _checkout_build(os.path.join("cli", "flowvid"))


# ---- mesh and scene -------------------------------------------------------------


def scene_fps(scene):
    return scene.render.fps / scene.render.fps_base


def mesh_stats(obj):
    """MeshStats of a mesh object in world space (the object's base mesh: modifiers
    before Cloth are not taken into account)."""
    if obj is None or obj.type != "MESH":
        raise FlowvidError("%s is not a mesh object" % (obj.name if obj else "nothing"))
    mesh = obj.data
    world = obj.matrix_world
    points = [world @ v.co for v in mesh.vertices]
    if not mesh.edges or not mesh.polygons:
        raise FlowvidError("%s has no faces: a cloth needs a surface" % obj.name)
    edge_total = sum((points[e.vertices[0]] - points[e.vertices[1]]).length for e in mesh.edges)
    area = 0.0
    quads = 0
    faces_of_edge = {}
    for polygon in mesh.polygons:
        corners = [points[i] for i in polygon.vertices]
        for k in range(1, len(corners) - 1):
            area += 0.5 * (corners[k] - corners[0]).cross(corners[k + 1] - corners[0]).length
        quads += len(corners) == 4
        for key in polygon.edge_keys:
            faces_of_edge[key] = faces_of_edge.get(key, 0) + 1
    boundary = sum((points[a] - points[b]).length for (a, b), count in faces_of_edge.items() if count == 1)
    return mapping.MeshStats(vertex_count=len(points), mean_edge_length_m=edge_total / len(mesh.edges),
                             area_m2=area, quad_fraction=quads / len(mesh.polygons), boundary_length_m=boundary)


def cloth_modifier(obj, create=True):
    for modifier in obj.modifiers:
        if modifier.type == "CLOTH":
            return modifier
    if not create:
        return None
    return obj.modifiers.new("Cloth", "CLOTH")


def blender_limits():
    """Hard limits of the live ClothSettings properties."""
    properties = bpy.types.ClothSettings.bl_rna.properties
    return {name: (properties[name].hard_min, properties[name].hard_max)
            for name in mapping.MAPPED_SETTINGS if name in properties}


def read_preset(path):
    path = bpy.path.abspath(path)
    if not path or not os.path.isfile(path):
        raise FlowvidError("fabric preset %r does not exist" % path)
    try:
        return get_backend().read_fabric_preset(path)
    except BackendError as error:
        raise FlowvidError(str(error)) from None


def _adapter_factors(preset, stats, fps):
    """(log factors, quality, None) stored for a similar mesh, or (None, None, the reason)."""
    adapter = preset.get("adapters", {}).get("blender")
    if not adapter:
        return None, None, "no Blender calibration stored in the preset"
    settings = adapter.get("settings", {})
    factors = [settings.get("flowvid_log_factor_" + name) for name, _ in cal.CALIBRATED_GROUPS]
    if any(f is None for f in factors):
        return None, None, "the preset's Blender adapter has no calibration factors (written by another tool)"
    edge = adapter.get("calibrated_for", {}).get("mean_edge_length_m")
    if not edge or abs(edge - stats.mean_edge_length_m) > 0.25 * edge:
        return None, None, ("stored calibration is for mean edge %.1f mm, this mesh has %.1f mm: formula used; "
                            "run Calibrate for this mesh" % (1000 * (edge or 0), 1000 * stats.mean_edge_length_m))
    if abs(adapter.get("calibrated_for", {}).get("fps", fps) - fps) > 1e-6:
        return None, None, "stored calibration is for another fps: formula used"
    return [float(f) for f in factors], int(settings.get("quality", 0)), None


def formula_settings(preset, obj, scene, **options):
    """The documented mapping for this object's mesh and this scene (a mapping.Mapping)."""
    stats = mesh_stats(obj)
    modifier = cloth_modifier(obj, create=False)
    quality = modifier.settings.quality if modifier else 5
    try:
        return mapping.map_preset(preset["parameters"], stats, scene_fps(scene), quality=quality,
                                  limits=blender_limits(), **options), stats
    except mapping.MappingError as error:
        raise FlowvidError(str(error)) from None


def set_cloth_settings(obj, settings):
    modifier = cloth_modifier(obj)
    for key, value in settings.items():
        if hasattr(modifier.settings, key):
            setattr(modifier.settings, key, value)
    return modifier


def apply_fabric_preset(obj, path, calibrate=False, scene=None, progress=None, max_evaluations=12, **options):
    """Adds or updates obj's cloth modifier from a fabric preset, for this mesh and scene.

    calibrate=True first runs calibrate_fabric_preset (Blender and the library
    on a swatch with this mesh's edge length) and stores the result in the
    preset's adapters. Otherwise calibration factors stored in the preset for a
    similar mesh (mean edge within 25%, same fps) are used when present.
    options go to core.mapping.map_preset (mass_scale, reference_speed_m_per_s, min_quality).
    Returns {"set": settings written, "not_represented": [notes], "source":
    "formula" | "adapter" | "calibrated", "derived": {...}, "calibration": {...}}."""
    scene = scene or bpy.context.scene
    preset = read_preset(path)
    calibration_report = None
    if calibrate:
        calibration_report = calibrate_fabric_preset(obj, path, scene=scene, progress=progress,
                                                     max_evaluations=max_evaluations)
        preset = read_preset(path)
    result, stats = formula_settings(preset, obj, scene, **options)
    settings = dict(result.settings)
    notes = list(result.not_represented)
    factors, quality, why_not = _adapter_factors(preset, stats, scene_fps(scene))
    source = "formula"
    if factors is not None:
        settings = cal.scaled_settings(settings, factors, blender_limits())
        settings["quality"] = max(settings["quality"], quality)  # the calibrated substeps
        source = "calibrated" if calibrate else "adapter"
    elif "blender" in preset.get("adapters", {}):
        notes.append(why_not)
    if abs(scene.gravity.length - 9.81) > 0.05 or not scene.use_gravity:
        notes.append("scene gravity is %.3g m/s^2 (use_gravity=%s): the preset was fitted under 9.81"
                     % (scene.gravity.length, scene.use_gravity))
    notes.append("Speed Multiplier (time_scale) set to sqrt(1000)/fps = %.4f so that Blender's cloth falls with "
                 "real gravity" % settings["time_scale"])
    set_cloth_settings(obj, settings)
    return {"set": settings, "not_represented": notes, "source": source, "derived": result.derived,
            "calibration": calibration_report, "preset_name": preset.get("name", "")}


# ---- calibration ------------------------------------------------------------------


CALIBRATION_QUALITIES = (20, 40)


class Calibration:
    """Refines the formula's Blender settings until Blender's swatch matches the library's.

    Step by step (step() runs one Blender evaluation), so a modal operator can
    show progress and cancel; run() does it all. The swatch has this mesh's
    mean edge length (grid of 10..24 vertices a side)."""

    def __init__(self, preset, stats, fps, max_evaluations=12, quality=None, library_integrator="rk4_adaptive"):
        self.preset = preset
        self.stats = stats
        self.fps = fps
        edge = stats.mean_edge_length_m
        n = int(min(max(round(0.30 / edge) + 1, 10), 24))
        self.rows = self.cols = n
        width = edge * (n - 1)
        self.experiments = cal.swatch_experiments(width_m=width, height_m=width, separation_m=0.8 * width, fps=fps,
                                                  amplitude_m=0.2 * width)
        swatch_stats = mapping.MeshStats(vertex_count=n * n, mean_edge_length_m=edge, area_m2=width * width,
                                         boundary_length_m=4.0 * width)
        self.base = mapping.map_preset(preset["parameters"], swatch_stats, fps, quality=quality,
                                       limits=blender_limits()).settings
        self.garment_edge = edge
        self.max_evaluations = max_evaluations
        self.library_integrator = library_integrator
        self.history = []
        self.swatch = None
        self.steps = None
        self.done = False
        self.result = None

    def prepare(self):
        """Runs the library's two experiments and builds Blender's swatch."""
        backend = get_backend()
        static, waving = self.experiments
        try:
            # The static drape is the equilibrium itself (frame 1): no need to integrate it.
            equilibrium_only = dict(static, frame_count=1, pins=[dict(pin, positions_m=pin["positions_m"][:1])
                                                                 for pin in static["pins"]])
            lib_static = backend.simulate_swatch(equilibrium_only, self.preset["parameters"],
                                                 rows=self.rows, cols=self.cols, integrator=self.library_integrator)
            lib_waving = backend.simulate_swatch(waving, self.preset["parameters"], rows=self.rows, cols=self.cols,
                                                 integrator=self.library_integrator)
        except BackendError as error:
            raise FlowvidError(str(error)) from None
        self.library_static = lib_static["frames"][-1]
        self.library_waving = lib_waving["frames"]
        self.swatch = BlenderSwatchFactory(static, waving, lib_static["frames"][0], self.rows, self.cols)
        # First the substeps (Blender's implicit Euler damps the waving less with more of them), then
        # a simplex on the three factors with the remaining runs.
        formula_quality = int(self.base["quality"])
        self.quality_candidates = [q for q in CALIBRATION_QUALITIES if q > formula_quality]
        self.quality_errors = {}
        self.steps = None
        self.point = [0.0] * len(cal.CALIBRATED_GROUPS)

    def evaluate(self, log_factors, should_continue=None):
        settings = cal.scaled_settings(self.base, log_factors, blender_limits())
        run = self.swatch.run(settings, should_continue)
        if run is None:
            return None
        static_final, waving = run
        e_static = cal.rms_error([static_final], [self.library_static])
        e_waving = cal.rms_error(waving, self.library_waving)
        error = math.sqrt(0.5 * (e_static ** 2 + e_waving ** 2))
        self.history.append({"log_factors": list(log_factors), "quality": int(settings["quality"]), "rms_m": error, "static_rms_m": e_static,
                             "waving_rms_m": e_waving,
                             "static_sag_blender_m": cal.mean_sag(static_final),
                             "static_sag_library_m": cal.mean_sag(self.library_static)})
        return error

    def step(self, should_continue=None):
        """One Blender run. Returns False when finished (self.result set)."""
        if self.done:
            return False
        if self.swatch is None:
            self.prepare()
        value = self.evaluate(self.point, should_continue)
        if value is None:
            raise FlowvidError("calibration cancelled")
        if self.steps is None:
            # Quality phase: the formula's quality first, then the candidates.
            self.quality_errors[int(self.base["quality"])] = value
            if self.quality_candidates:
                self.base["quality"] = self.quality_candidates.pop(0)
                return True
            best_quality = min(self.quality_errors, key=self.quality_errors.get)
            self.base["quality"] = best_quality
            budget = max(self.max_evaluations - len(self.history), 2)
            self.steps = cal.nelder_mead_steps([0.0] * len(cal.CALIBRATED_GROUPS), step=0.5, max_evaluations=budget)
            self.point = next(self.steps)
            # The simplex's first point is the formula at the best quality, evaluated already.
            value = self.quality_errors[best_quality]
        try:
            self.point = self.steps.send(value)
            return True
        except StopIteration as finished:
            best, best_value, _evaluations = finished.value
            formula = self.history[0]
            self.result = {
                "log_factors": best, "quality": int(self.base["quality"]), "rms_vertex_error_m": best_value,
                "formula_rms_vertex_error_m": formula["rms_m"], "evaluations": len(self.history),
                "quality_errors_m": dict(self.quality_errors),
                "swatch_grid": [self.rows, self.cols], "history": self.history,
            }
            self.done = True
            return False

    def fraction(self):
        return min(len(self.history) / float(self.max_evaluations), 1.0)

    def cleanup(self):
        if self.swatch is not None:
            self.swatch.remove()
            self.swatch = None

    def run(self, progress=None):
        try:
            while self.step():
                if progress is not None and progress(self.fraction(), "RMS %.2f mm" % (
                        1000 * self.history[-1]["rms_m"])) is False:
                    raise FlowvidError("calibration cancelled")
        finally:
            self.cleanup()
        return self.result


def BlenderSwatchFactory(*arguments, **options):
    from .blender.swatch import BlenderSwatch

    return BlenderSwatch(*arguments, **options)


def store_calibration(path, preset, calibration, stats, fps):
    """Writes the calibrated settings into the preset's adapters.blender (validated, atomic)."""
    garment = mapping.map_preset(preset["parameters"], stats, fps, limits=blender_limits()).settings
    settings = cal.scaled_settings(garment, calibration.result["log_factors"], blender_limits())
    settings["quality"] = max(int(settings["quality"]), calibration.result["quality"])
    stored = {k: (float(v) if not isinstance(v, str) else v) for k, v in settings.items()}
    stored["quality"] = int(settings["quality"])
    for (name, _), factor in zip(cal.CALIBRATED_GROUPS, calibration.result["log_factors"]):
        stored["flowvid_log_factor_" + name] = float(factor)
    preset.setdefault("adapters", {})["blender"] = {
        "settings": stored,
        "calibrated_for": {"blender_version": bpy.app.version_string.split()[0],
                           "mean_edge_length_m": stats.mean_edge_length_m, "fps": fps,
                           "quality": int(settings["quality"]), "vertex_count": stats.vertex_count,
                           "area_m2": stats.area_m2},
        "rms_vertex_error_m": float(calibration.result["rms_vertex_error_m"]),
        "notes": ("flowvid_blender calibration: static drape + waving swatch %dx%d, formula-only RMS %.2f mm, "
                  "calibrated %.2f mm (quality %d) after %d Blender runs" % (
                      calibration.rows, calibration.cols, 1000 * calibration.result["formula_rms_vertex_error_m"],
                      1000 * calibration.result["rms_vertex_error_m"], calibration.result["quality"],
                      calibration.result["evaluations"])),
    }
    try:
        get_backend().write_fabric_preset(path, preset)
    except BackendError as error:
        raise FlowvidError(str(error)) from None


def calibrate_fabric_preset(obj, path, scene=None, progress=None, max_evaluations=12):
    """Calibrates the preset for obj's mesh and stores the result in the preset file.

    Returns the calibration result: rms_vertex_error_m, formula_rms_vertex_error_m, log_factors, history."""
    scene = scene or bpy.context.scene
    path = bpy.path.abspath(path)
    preset = read_preset(path)
    stats = mesh_stats(obj)
    fps = scene_fps(scene)
    calibration = Calibration(preset, stats, fps, max_evaluations=max_evaluations)
    calibration.run(progress)
    store_calibration(path, preset, calibration, stats, fps)
    return calibration.result


# ---- export ---------------------------------------------------------------------------


def export_fabric_preset(obj, path, name=None, areal_density_kg_per_m2=0.15, scene=None, max_evaluations=10,
                         progress=None):
    """Writes obj's current Blender cloth settings as a fabric preset.

    Starts from the inverse of the mapping, then fits the library's stretch,
    bending and drag (log-scale Nelder-Mead) so that the library's swatch
    matches Blender's swatch with these settings. Returns {"path", "rms_vertex_error_m",
    "inverse_rms_vertex_error_m", "parameters"}."""
    scene = scene or bpy.context.scene
    modifier = cloth_modifier(obj, create=False)
    if modifier is None:
        raise FlowvidError("%s has no Cloth modifier to export" % obj.name)
    stats = mesh_stats(obj)
    fps = scene_fps(scene)
    cloth = modifier.settings
    settings = {k: getattr(cloth, k) for k in mapping.MAPPED_SETTINGS}
    values = mapping.parameters_from_settings(settings, stats, areal_density_kg_per_m2)
    edge = stats.mean_edge_length_m
    n = int(min(max(round(0.30 / edge) + 1, 10), 24))
    width = edge * (n - 1)
    static, waving = cal.swatch_experiments(width_m=width, height_m=width, separation_m=0.8 * width, fps=fps,
                                            amplitude_m=0.2 * width)
    # Blender's swatch: these settings rescaled to the swatch mesh (same edge, other vertex count).
    swatch_mass = settings["mass"] * stats.vertex_count / stats.area_m2 * (width * width) / (n * n)
    blender_settings = dict(settings, mass=swatch_mass, bending_model=cloth.bending_model)
    backend = get_backend()
    # The static drape is the library's equilibrium (frame 1); the waving is integrated as in the fits.
    equilibrium_only = dict(static, frame_count=1, pins=[dict(pin, positions_m=pin["positions_m"][:1])
                                                         for pin in static["pins"]])
    try:
        start = backend.simulate_swatch(equilibrium_only, values, rows=n, cols=n)
    except BackendError as error:
        raise FlowvidError(str(error)) from None
    swatch = BlenderSwatchFactory(static, waving, start["frames"][0], n, n)
    try:
        run = swatch.run(blender_settings)
    finally:
        swatch.remove()
    blender_static, blender_waving = run

    groups = (("stretch", ("stretch_warp_stiffness_N_per_m", "stretch_weft_stiffness_N_per_m",
                           "shear_stiffness_N_per_m")),
              ("bending", ("bend_stiffness_N_m",)),
              ("drag", ("drag_normal_kg_per_m3", "drag_tangential_kg_per_m2_s")))
    history = []

    def parameters_for(log_factors):
        scaled = dict(values)
        for (_, keys), factor in zip(groups, log_factors):
            for key in keys:
                scaled[key] = values[key] * math.exp(factor)
        return scaled

    def objective(log_factors):
        try:
            s = backend.simulate_swatch(equilibrium_only, parameters_for(log_factors), rows=n, cols=n)
            w = backend.simulate_swatch(waving, parameters_for(log_factors), rows=n, cols=n,
                                        integrator="rk4_adaptive")
        except BackendError:
            return 1e3
        e = math.sqrt(0.5 * (cal.rms_error([blender_static], [s["frames"][-1]]) ** 2
                             + cal.rms_error(blender_waving, w["frames"]) ** 2))
        history.append(e)
        if progress is not None:
            progress(min(len(history) / float(max_evaluations), 1.0), "RMS %.2f mm" % (1000 * e))
        return e

    best, best_value, _ = cal.nelder_mead(objective, [0.0, 0.0, 0.0], step=0.5, max_evaluations=max_evaluations)
    fitted = parameters_for(best)
    preset = {
        "format": "flowvid.fabric", "version": "1.0",
        "name": name or ("%s (Blender cloth)" % obj.name),
        "description": "Exported from Blender %s cloth settings of %s by fitting the flowvid cloth model to "
                       "Blender's static drape and waving swatch." % (bpy.app.version_string.split()[0], obj.name),
        "parameters": {key: {"value": float(value)} for key, value in fitted.items()},
        "provenance": {
            "method": "adapter_export",
            "created_utc": datetime.datetime.utcnow().strftime("%Y-%m-%dT%H:%M:%SZ"),
            "simulator": "Blender %s cloth" % bpy.app.version_string.split()[0],
            "notes": "swatch %dx%d, edge %.1f mm; the areal density %.3g kg/m^2 is declared (Blender's mass unit "
                     "is free); RMS %.2f mm after the fit (inverse formula %.2f mm)" % (
                         n, n, 1000 * edge, areal_density_kg_per_m2, 1000 * best_value, 1000 * history[0]),
        },
        "adapters": {"blender": {
            "settings": {k: (v if isinstance(v, str) else float(v)) for k, v in blender_settings.items()},
            "calibrated_for": {"blender_version": bpy.app.version_string.split()[0], "mean_edge_length_m": edge,
                               "fps": fps},
            "rms_vertex_error_m": float(best_value),
            "notes": "the Blender settings this preset was exported from (swatch mass per vertex)",
        }},
    }
    path = bpy.path.abspath(path)
    try:
        backend.write_fabric_preset(path, preset)
    except BackendError as error:
        raise FlowvidError(str(error)) from None
    return {"path": path, "rms_vertex_error_m": best_value, "inverse_rms_vertex_error_m": history[0],
            "parameters": fitted}


# ---- particles and strokes -> flow lines -------------------------------------------------


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
    scene = scene or bpy.context.scene
    if emitter is None or not emitter.particle_systems:
        raise FlowvidError("%s has no particle system" % (emitter.name if emitter else "nothing"))
    if system >= len(emitter.particle_systems):
        raise FlowvidError("%s has no particle system %d" % (emitter.name, system))
    paths = {}
    for frame in range(frame_start, frame_end + 1):
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


def _direction(points):
    dx = points[-1][0] - points[0][0]
    dy = points[-1][1] - points[0][1]
    norm = math.hypot(dx, dy) or 1.0
    return dx / norm, dy / norm


def _distance_to_polyline(point, polyline):
    best = math.inf
    for a, b in zip(polyline, polyline[1:]):
        abx, aby = b[0] - a[0], b[1] - a[1]
        length2 = abx * abx + aby * aby
        t = 0.0 if length2 <= 0.0 else min(max(((point[0] - a[0]) * abx + (point[1] - a[1]) * aby) / length2, 0.0), 1.0)
        best = min(best, math.hypot(point[0] - a[0] - t * abx, point[1] - a[1] - t * aby))
    return best if len(polyline) >= 2 else math.hypot(point[0] - polyline[0][0], point[1] - polyline[0][1])


def _mean_distance(points, polyline):
    return sum(_distance_to_polyline(p, polyline) for p in points) / len(points)


# An output line takes texture only from input lines flowing within this of its direction.
_NEAREST_MAX_ANGLE_DEG = 45.0


def assign_inputs(outputs, inputs, rule="nearest", by_hand=None):
    """Sets each output line's `from`: by hand ({output id: input id}) first, then by rule:
    "nearest" (the input line nearest the output line, in mean pixel distance, among those flowing
    within 45 degrees of its direction; all of them when none does): a line keeps the texture of the
    flow it is drawn over; "direction" (the input line whose overall direction is closest: one input
    for a whole particle system, whatever it flows over) or "cycle"."""
    if rule not in ("nearest", "direction", "cycle"):
        raise FlowvidError("unknown rule %r for assigning input lines (use nearest, direction or cycle)" % (rule,))
    by_hand = by_hand or {}
    input_dirs = [(line["id"], _direction(line["points"])) for line in inputs]
    cos_max = math.cos(math.radians(_NEAREST_MAX_ANGLE_DEG))
    for k, line in enumerate(outputs):
        if line["id"] in by_hand:
            line["from"] = by_hand[line["id"]]
            continue
        if rule == "cycle":
            line["from"] = input_dirs[k % len(input_dirs)][0]
            continue
        points = line["keys"][0]["points"] if "keys" in line else line["points"]
        d = _direction(points)
        if rule == "direction":
            line["from"] = max(input_dirs, key=lambda item: item[1][0] * d[0] + item[1][1] * d[1])[0]
            continue
        aligned = [line_in for line_in, (_, di) in zip(inputs, input_dirs) if di[0] * d[0] + di[1] * d[1] >= cos_max]
        line["from"] = min(aligned or inputs, key=lambda line_in: _mean_distance(points, line_in["points"]))["id"]


def bake_flowlines(emitter, camera, frame_start, frame_end, path, inputs=None, system=0, rule="nearest",
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
    paths = particle_paths(emitter, frame_start, frame_end, scene, system, max_points)
    if not paths:
        raise FlowvidError("no particle of %s is alive and moving in frames %d..%d" % (emitter.name, frame_start,
                                                                                      frame_end))
    width, height = render_size(scene)
    keys = {index: [] for index in paths}
    for frame in range(frame_start, frame_end + 1):
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


def grease_pencil_flowlines(gpencil, camera, path, scene=None, frame=None):
    """Exports Grease Pencil strokes as flow lines: strokes on a layer named "input" become input lines,
    on "output" output lines (their `from` by the nearest rule). Stroke point order is the flow direction."""
    scene = scene or bpy.context.scene
    if gpencil is None or gpencil.type != "GPENCIL":
        raise FlowvidError("%s is not a Grease Pencil object" % (gpencil.name if gpencil else "nothing"))
    if camera is None:
        raise FlowvidError("no camera to project the strokes through")
    if frame is not None:
        scene.frame_set(frame)
    lines = {"input": [], "output": []}
    for layer in gpencil.data.layers:
        kind = layer.info.lower()
        # The drawing shown at the current frame: the last keyframe at or before it.
        shown = [f for f in layer.frames if f.frame_number <= scene.frame_current] or list(layer.frames)[:1]
        if kind not in lines or not shown:
            continue
        for stroke in max(shown, key=lambda f: f.frame_number).strokes:
            points = [list(project_to_pixels(scene, camera, gpencil.matrix_world @ p.co)[0]) for p in stroke.points]
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


# ---- synthesis and showing the result -------------------------------------------------------


def run_flowvid_tool(*arguments):
    """Runs the flowvid command-line tool (e.g. track, which has no binding); raises FlowvidError with its message."""
    executable = backend_module.find_tool(_checkout_tool())
    if not executable:
        raise FlowvidError("the flowvid tool was not found: set FLOWVID_CLI to build/cli/flowvid")
    try:
        return backend_module.CliBackend(executable).run(*arguments)
    except BackendError as error:
        raise FlowvidError("flowvid %s failed: %s" % (arguments[0], str(error)[-2000:])) from None


def synthesize(bank, flowlines, frame_start, frame_end, out_dir, background=None, texture=None, capture=None,
               progress=None):
    """flowvid edit for the frame range, in process where the module is there (else through the tool): PNG
    frames out_dir/%06d.png; returns the first frame's path.
    background: auto, median, loop, replay, relit or none (None: auto). texture: auto, whole or moving
    (moving keeps only the light flames or smoke add to the scene, screened over its dark plate or over
    black; None: auto). capture: the source clip (None: the one the bank records).
    progress(stage, fraction, message) -> False cancels."""
    os.makedirs(out_dir, exist_ok=True)
    pattern = os.path.join(out_dir, "%06d.png")
    try:
        get_backend().synthesize(bank, pattern, (frame_start, frame_end), edit=True, flowlines=flowlines,
                                 capture=capture or "", background=background or "auto", texture=texture or "auto",
                                 progress=progress)
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
