"""Fabric presets in Blender: applying a preset to a garment's cloth, the
calibration of Blender's solver against the library's, and exporting cloth
settings as a preset (needs bpy; the bpy-free mapping is core/mapping.py)."""
import datetime
import math
import os

import bpy

from .core import calibration as cal
from .core import jobs, mapping, presentation
from .core.backend import BackendError
from .core.errors import FlowvidError
from .library import get_backend


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
    """(log factors, quality, None) stored for a similar mesh, or (None, None, the reason) -- in the words the
    summary and Details use (core/presentation.adapter_status)."""
    status = presentation.adapter_status(preset, stats.mean_edge_length_m, fps)
    if status["usable"]:
        return status["factors"], status["quality"], None
    return None, None, status["text"]


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
    "formula" | "adapter" | "calibrated", "derived": {...}, "calibration": {...}, "folds": whether the
    mesh's edges hold the fabric's folds ({"fold_length_m", "edge_m", "longest_edge_m", "holds_folds"}; the
    first note says what it means when they do not)}."""
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
    notes.append(presentation.vertex_mass_note(settings, result.derived))
    folds = check_folds(path, stats)
    fold_note = presentation.fold_note(folds)
    if fold_note:  # first: the one note that changes what the artist should do
        notes.insert(0, fold_note)
    set_cloth_settings(obj, settings)
    return {"set": settings, "not_represented": notes, "source": source, "derived": result.derived,
            "calibration": calibration_report, "preset_name": preset.get("name", ""), "folds": folds}


def check_folds(path, stats):
    """Whether the mesh (its mean edge, stats a MeshStats) holds the preset's folds: the library's rule."""
    try:
        return get_backend().check_folds(bpy.path.abspath(path), stats.mean_edge_length_m)
    except BackendError as error:
        raise FlowvidError(str(error)) from None


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
        self.library_waving = None
        self.steps = None
        self.done = False
        self.result = None

    def simulate_library(self, progress=None):
        """The library's two experiments. Needs no bpy: a modal operator runs it in a thread.
        progress(fraction, text) -> False cancels (FlowvidError)."""
        backend = get_backend()
        static, waving = self.experiments

        def frames(start, share):
            if progress is None:
                return None
            return lambda frame, count: progress(start + share * frame / max(count, 1), "flowvid's swatch") is not False

        try:
            # The static drape is the equilibrium itself (frame 1): no need to integrate it.
            equilibrium_only = dict(static, frame_count=1, pins=[dict(pin, positions_m=pin["positions_m"][:1])
                                                                 for pin in static["pins"]])
            lib_static = backend.simulate_swatch(equilibrium_only, self.preset["parameters"], rows=self.rows,
                                                 cols=self.cols, integrator=self.library_integrator,
                                                 progress=frames(0.0, 0.05))
            lib_waving = backend.simulate_swatch(waving, self.preset["parameters"], rows=self.rows, cols=self.cols,
                                                 integrator=self.library_integrator, progress=frames(0.05, 0.15))
        except BackendError as error:
            raise FlowvidError(str(error)) from None
        self.library_start = lib_static["frames"][0]
        self.library_static = lib_static["frames"][-1]
        self.library_waving = lib_waving["frames"]

    def prepare(self):
        """Runs the library's two experiments (unless simulate_library did) and builds Blender's swatch."""
        if self.library_waving is None:
            self.simulate_library()
        static, waving = self.experiments
        self.swatch = BlenderSwatchFactory(static, waving, self.library_start, self.rows, self.cols)
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
        # The library's runs take the first 20 %, Blender's the rest.
        return 0.2 + 0.8 * min(len(self.history) / float(self.max_evaluations), 1.0)

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


def calibrate_steps(obj, path, scene=None, max_evaluations=12, apply=False):
    """calibrate_fabric_preset as a job (core/jobs.py): the library's swatch in the background, then one Blender
    run per step; the temporary swatch scene is removed however it ends. apply=True then applies the calibrated
    preset and returns (calibration result, Apply's report)."""
    scene = scene or bpy.context.scene
    path = bpy.path.abspath(path)
    preset = read_preset(path)
    stats = mesh_stats(obj)
    fps = scene_fps(scene)
    calibration = Calibration(preset, stats, fps, max_evaluations=max_evaluations)
    try:
        yield jobs.Background(calibration.simulate_library, "flowvid's swatch")
        yield calibration.fraction(), "building Blender's swatch"
        calibration.prepare()
        while calibration.step():
            yield calibration.fraction(), "RMS %.2f mm" % (1000 * calibration.history[-1]["rms_m"])
    finally:
        calibration.cleanup()
    store_calibration(path, preset, calibration, stats, fps)
    if apply:
        return calibration.result, apply_fabric_preset(obj, path, scene=scene)
    return calibration.result


def calibrate_fabric_preset(obj, path, scene=None, progress=None, max_evaluations=12):
    """Calibrates the preset for obj's mesh and stores the result in the preset file.
    progress(fraction, text) -> False cancels (the preset stays as it was).

    Returns the calibration result: rms_vertex_error_m, formula_rms_vertex_error_m, log_factors, history."""
    return jobs.run_to_end(calibrate_steps(obj, path, scene=scene, max_evaluations=max_evaluations), progress)


# ---- export ---------------------------------------------------------------------------


def export_fabric_preset(obj, path, name=None, areal_density_kg_per_m2=0.15, scene=None, max_evaluations=10,
                         progress=None):
    """Writes obj's current Blender cloth settings as a fabric preset (export_steps to the end; progress(fraction,
    text) -> False cancels and writes nothing)."""
    return jobs.run_to_end(export_steps(obj, path, name=name, areal_density_kg_per_m2=areal_density_kg_per_m2,
                                        scene=scene, max_evaluations=max_evaluations), progress)


def export_steps(obj, path, name=None, areal_density_kg_per_m2=0.15, scene=None, max_evaluations=10):
    """export_fabric_preset as a job (core/jobs.py): the library's runs and the fit in the background, Blender's
    swatch on the main thread.

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

    def equilibrium(_progress):
        try:
            return backend.simulate_swatch(equilibrium_only, values, rows=n, cols=n)
        except BackendError as error:
            raise FlowvidError(str(error)) from None

    start = yield jobs.Background(equilibrium, "flowvid's swatch")
    yield 0.05, "Blender's swatch"
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

    def objective(log_factors, progress):
        try:
            s = backend.simulate_swatch(equilibrium_only, parameters_for(log_factors), rows=n, cols=n)
            w = backend.simulate_swatch(waving, parameters_for(log_factors), rows=n, cols=n,
                                        integrator="rk4_adaptive")
        except BackendError:
            return 1e3
        e = math.sqrt(0.5 * (cal.rms_error([blender_static], [s["frames"][-1]]) ** 2
                             + cal.rms_error(blender_waving, w["frames"]) ** 2))
        history.append(e)
        if progress(0.1 + 0.9 * min(len(history) / float(max_evaluations), 1.0), "RMS %.2f mm" % (1000 * e)) is False:
            raise jobs.Cancelled("export cancelled: nothing written")
        return e

    best, best_value, _ = yield jobs.Background(
        lambda progress: cal.nelder_mead(lambda x: objective(x, progress), [0.0, 0.0, 0.0], step=0.5,
                                         max_evaluations=max_evaluations), "fitting flowvid to Blender")
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
