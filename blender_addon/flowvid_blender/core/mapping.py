"""Fabric preset (per-area Baraff-Witkin parameters, SI) -> Blender cloth settings.

Pure Python, no bpy. The derivation, from Blender 3.4's cloth solver
(blenkernel/intern/cloth.cc, simulation/intern/SIM_mass_spring.cpp and
implicit_blender.c), is written out in docs/blender.md; the names below follow
it. In short:

* Blender's cloth time unit is a frame: one frame advances `time_scale` units
  in `quality` substeps, and gravity enters as 0.001 x the scene gravity. So
  one unit of solver time is tau = 1 / (fps * time_scale) seconds, and real
  gravity needs tau^2 = 0.001 s^2, i.e. time_scale = sqrt(1000) / fps.
* Every Blender force scales with one free mass unit s (Blender mass = s x kg):
  a force F newtons is F * s * tau^2 in the solver, a damping coefficient
  c N s/m is c * s * tau.
* Structural springs: k_spring = tension / L (L = mean structural edge length,
  Blender's avg_spring_len); a quad grid of spacing L gives a membrane
  stiffness of k_spring N/m. Shear springs (quad diagonals, tension only)
  also resist stretching by half their stiffness.
* Angular bending: k_angle = 0.1 * bending * |e|, applied as a force spread
  over the wing polygons; on quads of size L the hinge moment is
  k_angle * theta * L / 2, so a plate bending stiffness D (N m) needs
  bending = 20 D / L^2.
* Air damping: f = -0.01 * air_damping * v per vertex, linear and isotropic:
  the preset's linear normal drag kL plus its quadratic normal drag matched
  at a reference speed.
* Mass is uniform per vertex (Blender has no per-vertex cloth mass): a
  preset's hem cannot be placed on the boundary, so its mass is spread.

Presets of format 1.0 lack the 1.1 parameters: they take their neutral values
(compression ratio 1, kL 0, hem 0).
"""
from dataclasses import dataclass, field
import math

SQRT_1000 = math.sqrt(1000.0)
BLENDER_GRAVITY_SCALE = 0.001       # SIM_mass_spring.cpp: gravity * 0.001
BLENDER_BENDING_SCALE = 0.1         # SIM_mass_spring.cpp: k = bending * restlen * 0.1
BLENDER_AIR_DAMPING_SCALE = 0.01    # SIM_mass_spring.cpp: drag = Cvi * 0.01
DEFAULT_MASS_SCALE = 1000.0         # Blender mass unit = 1 g (any value gives the same motion)
DEFAULT_REFERENCE_SPEED_M_PER_S = 0.5
DEFAULT_MIN_QUALITY = 10

# Hard limits of Blender 3.4's ClothSettings RNA properties (bpy reads the
# live ones; these are for plain-Python use and the tests).
BLENDER_LIMITS = {
    "quality": (1, 2147483647),
    "time_scale": (0.0, 3.4e38),
    "mass": (0.0, 3.4e38),
    "tension_stiffness": (0.0, 10000.0),
    "compression_stiffness": (0.0, 10000.0),
    "shear_stiffness": (0.0, 10000.0),
    "bending_stiffness": (0.0, 10000.0),
    "tension_damping": (0.0, 50.0),
    "compression_damping": (0.0, 50.0),
    "shear_damping": (0.0, 50.0),
    "bending_damping": (0.0, 1000.0),
    "air_damping": (0.0, 10.0),
}

# The numeric Blender settings the mapping writes (plus bending_model).
MAPPED_SETTINGS = (
    "quality", "time_scale", "mass", "tension_stiffness", "compression_stiffness", "shear_stiffness",
    "bending_stiffness", "tension_damping", "compression_damping", "shear_damping", "bending_damping",
    "air_damping",
)


class MappingError(ValueError):
    """A preset or mesh the mapping cannot use; the message says which field and what to do."""


@dataclass
class MeshStats:
    """The garment as Blender's cloth sees it (world space, after the object's scale)."""
    vertex_count: int
    mean_edge_length_m: float       # mean structural edge length (Blender's avg_spring_len)
    area_m2: float
    quad_fraction: float = 1.0      # faces with 4 corners / all faces (the formulas assume quads)
    boundary_length_m: float = 0.0  # free boundary (edges of one face): where a preset's hem lies


@dataclass
class Mapping:
    settings: dict                                   # ClothSettings name -> value
    not_represented: list = field(default_factory=list)  # human-readable notes
    derived: dict = field(default_factory=dict)      # intermediate quantities (tau, spring constants, ...)


# Parameters added since format 1.0 and their neutral values (an older preset lacks them).
OPTIONAL_PARAMETERS = {
    "stretch_warp_compression_ratio": 1.0,
    "stretch_weft_compression_ratio": 1.0,
    "drag_linear_normal_kg_per_m2_s": 0.0,
    "hem_line_density_kg_per_m": 0.0,
    "diagonal_tension_stiffness_N_per_m": 0.0,
    "shear_cell_fraction": 0.0,  # 1.2: where a grid reads the shear; Blender's springs need no mapping of it
}


def parameter_values(parameters):
    """Preset `parameters` ({"key": {"value": ...}} or {"key": number}) -> {key: float}; the 1.1
    parameters a 1.0 preset lacks get their neutral values."""
    values = dict(OPTIONAL_PARAMETERS)
    for key, entry in parameters.items():
        values[key] = float(entry["value"] if isinstance(entry, dict) else entry)
    return values


def time_unit_s(fps, time_scale):
    """Seconds per unit of Blender's cloth solver time."""
    return 1.0 / (fps * time_scale)


def gravity_time_scale(fps):
    """The Speed Multiplier for which Blender's cloth falls with the scene's gravity in m/s^2."""
    return SQRT_1000 / fps


def linear_drag_per_area(values, reference_speed_m_per_s):
    """Linear drag coefficient (kg/(m^2 s)) equal to the preset's normal drag at the reference speed.

    The library's normal drag is kL v + kN v^2 / (1 + kf v^2); a linear drag c v with
    c = kL + kN v_ref / (1 + kf v_ref^2) gives the same force at v_ref (less below,
    more above; exactly the same at every speed when kN = 0)."""
    v = reference_speed_m_per_s
    return (values.get("drag_linear_normal_kg_per_m2_s", 0.0)
            + values["drag_normal_kg_per_m3"] * v / (1.0 + values["drag_degradation_s2_per_m2"] * v * v))


def _check(values, mesh, fps):
    problems = []
    required = (
        "areal_density_kg_per_m2", "stretch_warp_stiffness_N_per_m", "stretch_weft_stiffness_N_per_m",
        "shear_stiffness_N_per_m", "bend_stiffness_N_m", "stretch_warp_damping_N_s_per_m",
        "stretch_weft_damping_N_s_per_m", "shear_damping_N_s_per_m", "bend_damping_N_m_s",
        "drag_normal_kg_per_m3", "drag_degradation_s2_per_m2", "drag_tangential_kg_per_m2_s",
    )
    for key in required + tuple(OPTIONAL_PARAMETERS):
        if key not in values:
            problems.append("/parameters/%s: missing (load a valid *.fabric.json)" % key)
        elif not math.isfinite(values[key]) or values[key] < 0.0:
            problems.append("/parameters/%s: %r is not a finite number >= 0" % (key, values[key]))
    if not problems:
        if values["areal_density_kg_per_m2"] <= 0.0:
            problems.append("/parameters/areal_density_kg_per_m2: must be > 0")
        if values["bend_stiffness_N_m"] <= 0.0:
            problems.append("/parameters/bend_stiffness_N_m: must be > 0")
        for key in ("stretch_warp_compression_ratio", "stretch_weft_compression_ratio"):
            if values[key] <= 0.0:
                problems.append("/parameters/%s: must be > 0" % key)
    if mesh.vertex_count < 3 or not mesh.mean_edge_length_m > 0.0 or not mesh.area_m2 > 0.0:
        problems.append("mesh: needs faces with non-zero area and edge length (got %d vertices, mean edge %g m, "
                        "area %g m^2)" % (mesh.vertex_count, mesh.mean_edge_length_m, mesh.area_m2))
    if not fps > 0.0:
        problems.append("scene fps: must be > 0 (got %r)" % fps)
    if problems:
        raise MappingError("; ".join(problems))


def map_preset(parameters, mesh, fps, quality=None, mass_scale=DEFAULT_MASS_SCALE,
               reference_speed_m_per_s=DEFAULT_REFERENCE_SPEED_M_PER_S, min_quality=DEFAULT_MIN_QUALITY,
               limits=None):
    """Blender cloth settings for a preset on this mesh (see the module docstring and docs/blender.md).

    parameters: the preset's `parameters` object; mesh: MeshStats; fps: scene
    frames per second (render.fps / render.fps_base); quality: the object's
    current substeps per frame (raised to min_quality). Returns a Mapping whose
    settings are clamped to Blender's limits; every clamp and approximation is
    listed in not_represented."""
    values = parameter_values(parameters)
    _check(values, mesh, fps)
    limits = dict(BLENDER_LIMITS, **(limits or {}))
    s = float(mass_scale)
    L = mesh.mean_edge_length_m
    n = mesh.vertex_count
    time_scale = gravity_time_scale(fps)
    tau = time_unit_s(fps, time_scale)            # = 1/sqrt(1000) s
    force = s * tau * tau                          # N -> Blender force units
    damping = s * tau                              # N s/m -> Blender damping units
    notes = []

    def isotropic(key, name, unit):
        # Blender's springs are isotropic: warp and weft averaged (noted when they differ by over 5 %).
        warp, weft = values["stretch_warp_" + key], values["stretch_weft_" + key]
        mean = 0.5 * (warp + weft)
        if abs(warp - weft) > 0.05 * max(mean, 1e-30):
            notes.append("anisotropic %s (warp %g, weft %g%s) averaged to %g: Blender's springs are isotropic"
                         % (name, warp, weft, unit, mean))
        return mean

    k_stretch = isotropic("stiffness_N_per_m", "stretch", " N/m")
    k_shear = values["shear_stiffness_N_per_m"]
    d_stretch = isotropic("damping_N_s_per_m", "stretch damping", " N s/m")
    bend = values["bend_stiffness_N_m"]
    bend_damping = values["bend_damping_N_m_s"]
    compression_ratio = isotropic("compression_ratio", "compression ratio", "")
    hem = values["hem_line_density_kg_per_m"]

    # Shear springs (quad diagonals) carry 2 k_shear and add k_shear to the
    # stretch stiffness in tension (diagonals are tension-only in Blender).
    # Diagonal tension-only fibres are what Blender's diagonal springs are: a
    # spring of stiffness c along a quad's diagonal stores c (sqrt 2 L eps_d)^2 / 2
    # = c L^2 eps_d^2, the fibre k/2 L^2 eps_d^2: c = k / 2.
    k_diagonal = values["diagonal_tension_stiffness_N_per_m"]
    shear_spring = 2.0 * k_shear + 0.5 * k_diagonal
    tension_spring = k_stretch - k_shear
    if tension_spring <= 0.0:
        notes.append("shear stiffness exceeds stretch stiffness: tension springs set to 10% of stretch")
        tension_spring = 0.1 * k_stretch
    c_drag = linear_drag_per_area(values, reference_speed_m_per_s)
    k_tangential = values["drag_tangential_kg_per_m2_s"]
    notes.append("air drag is linear and isotropic in Blender: the normal drag kN v^2/(1+kf v^2) is matched at "
                 "%.2f m/s (%.3g kg/(m^2 s)); below that speed Blender drags more, above it less; the tangential "
                 "drag (%.3g kg/(m^2 s)) is replaced by the same isotropic value" % (reference_speed_m_per_s,
                                                                                     c_drag, k_tangential))
    notes.append("mass is uniform per vertex in Blender (the library lumps it by area, so edges are lighter there)")
    if hem > 0.0:
        notes.append("the hem (%.3g kg per m of boundary) is spread over every vertex: Blender has no per-vertex cloth "
                     "mass" % hem)
    if mesh.quad_fraction < 0.9:
        notes.append("the mesh is %.0f%% triangles: the spring formulas assume quads (triangles have no shear "
                     "springs in Blender); run Calibrate for this mesh" % (100.0 * (1.0 - mesh.quad_fraction)))
    notes.append("bending damping is approximate (Blender damps the wings' mean normal velocity)")

    bending = 20.0 * bend * force / (L * L)
    settings = {
        "quality": max(int(quality or 0), int(min_quality)),
        "time_scale": time_scale,
        "mass": s * (values["areal_density_kg_per_m2"] * mesh.area_m2 + hem * mesh.boundary_length_m) / n,
        "tension_stiffness": tension_spring * force * L,
        "compression_stiffness": compression_ratio * k_stretch * force * L,
        "shear_stiffness": shear_spring * force * L,
        "bending_stiffness": bending,
        "tension_damping": d_stretch * damping,
        "compression_damping": d_stretch * damping,
        "shear_damping": 2.0 * values["shear_damping_N_s_per_m"] * damping,
        "bending_damping": 0.2 * bending * (bend_damping / bend) / tau,
        "air_damping": c_drag * (mesh.area_m2 / n) * damping / BLENDER_AIR_DAMPING_SCALE,
    }
    for name, value in list(settings.items()):
        low, high = limits.get(name, (-math.inf, math.inf))
        if value > high or value < low:
            clamped = min(max(value, low), high)
            notes.append("%s = %.4g is outside Blender's range [%g, %g]: set to %g" % (name, value, low, high, clamped))
            settings[name] = type(value)(clamped)
    settings["bending_model"] = "ANGULAR"
    derived = {
        "tau_s": tau, "mass_scale": s, "force_scale": force, "damping_scale": damping,
        "mean_edge_length_m": L, "area_m2": mesh.area_m2, "vertex_count": n, "fps": fps,
        "linear_drag_kg_per_m2_s": c_drag, "reference_speed_m_per_s": reference_speed_m_per_s,
        "tension_spring_N_per_m": tension_spring, "shear_spring_N_per_m": shear_spring,
        "areal_density_kg_per_m2": values["areal_density_kg_per_m2"], "hem_line_density_kg_per_m": hem,
        "boundary_length_m": mesh.boundary_length_m,
    }
    return Mapping(settings=settings, not_represented=notes, derived=derived)


def parameters_from_settings(settings, mesh, areal_density_kg_per_m2=0.15,
                             reference_speed_m_per_s=DEFAULT_REFERENCE_SPEED_M_PER_S):
    """The inverse of map_preset (the start of export): Blender settings -> preset parameter values.

    Blender's mass unit is free, so the real areal density must be declared;
    every force parameter scales with it. Solver time is read with
    tau = 1/sqrt(1000) s, the time unit in which Blender's gravity is the
    scene's gravity: static shapes then match exactly, and a scene whose
    fps * time_scale differs from sqrt(1000) moves by the same shapes at another
    speed (noted by the caller)."""
    L = mesh.mean_edge_length_m
    n = mesh.vertex_count
    tau = 1.0 / SQRT_1000
    s = settings["mass"] * n / (areal_density_kg_per_m2 * mesh.area_m2)
    force = s * tau * tau
    damping = s * tau
    k_shear = settings["shear_stiffness"] / (2.0 * force * L)
    # Tension: the structural springs and the diagonals; compression: the structural springs alone.
    k_stretch = settings["tension_stiffness"] / (force * L) + k_shear
    compression_ratio = settings["compression_stiffness"] / (force * L) / k_stretch
    bend = settings["bending_stiffness"] * L * L / (20.0 * force)
    c_drag = settings["air_damping"] * BLENDER_AIR_DAMPING_SCALE / (damping * mesh.area_m2 / n)
    d_stretch = 0.5 * (settings["tension_damping"] + settings["compression_damping"]) / damping
    bend_damping = (settings["bending_damping"] * tau * bend / (0.2 * settings["bending_stiffness"])
                    if settings["bending_stiffness"] > 0 else 0.0)
    return {
        "areal_density_kg_per_m2": areal_density_kg_per_m2,
        "stretch_warp_stiffness_N_per_m": k_stretch,
        "stretch_weft_stiffness_N_per_m": k_stretch,
        "shear_stiffness_N_per_m": max(k_shear, 1e-6),
        "bend_stiffness_N_m": max(bend, 1e-12),
        "stretch_warp_damping_N_s_per_m": d_stretch,
        "stretch_weft_damping_N_s_per_m": d_stretch,
        "shear_damping_N_s_per_m": 0.5 * settings["shear_damping"] / damping,
        "bend_damping_N_m_s": bend_damping,
        # Blender's drag is linear and isotropic: kL = kT = c, no quadratic part.
        "drag_normal_kg_per_m3": 0.0,
        "drag_degradation_s2_per_m2": 0.0,
        "drag_tangential_kg_per_m2_s": c_drag,
        "stretch_warp_compression_ratio": compression_ratio,
        "stretch_weft_compression_ratio": compression_ratio,
        "drag_linear_normal_kg_per_m2_s": c_drag,
        "hem_line_density_kg_per_m": 0.0,
        "diagonal_tension_stiffness_N_per_m": 0.0,
        "shear_cell_fraction": 0.0,
    }


def summarize_preset(preset):
    """The panel's summary as "Label: value" lines (core/presentation.py words them, with units)."""
    from .presentation import summary_pairs

    return ["%s: %s" % pair for pair in summary_pairs(preset)]
