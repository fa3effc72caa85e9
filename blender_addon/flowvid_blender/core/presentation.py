"""What the add-on tells people: preset summaries with units, what the preset's
Blender adapter is and whether Apply uses it, why Vertex Mass is what it is, and
text wrapped to a measured width. Plain Python (no bpy): the panels, the Details
popup, the Info log and Apply all take their words from here, so they agree."""
from . import calibration as cal

# Apply reuses a stored calibration for meshes whose mean edge is within this of the calibrated one.
ADAPTER_EDGE_TOLERANCE = 0.25


def _number(value, digits=3):
    """`digits` significant figures, without an exponent from 1 to a million (1.2e+02 reads as 120)."""
    text = "%.*g" % (digits, value)
    return "%d" % round(float(text)) if "e" in text and 1.0 <= abs(value) < 1e6 else text


def _quantity(entry, unit, scale=1.0):
    if not isinstance(entry, dict):
        return "-" if entry is None else "%s %s" % (_number(float(entry) * scale), unit)
    text = _number(entry["value"] * scale)
    if entry.get("uncertainty") is not None:
        text += " \u00b1 %s" % _number(entry["uncertainty"] * scale, 2)
    return "%s %s" % (text, unit)


def adapter_status(preset, mean_edge_length_m=None, fps=None):
    """The preset's Blender adapter as Apply treats it (one truth for the summary, Details and Apply).

    Returns {"state": "none" | "foreign" | "calibrated", "usable": whether Apply uses it for this mesh and fps
    (None when no mesh is given), "factors", "quality", "short": a panel value, "text": a sentence}."""
    adapter = preset.get("adapters", {}).get("blender")
    if not adapter:
        return {"state": "none", "usable": False, "factors": None, "quality": None, "short": "not calibrated",
                "text": "No Blender calibration is stored in the preset: Apply uses the formulas (docs/blender.md); "
                        "Calibrate for This Mesh stores one."}
    settings = adapter.get("settings", {})
    stored_for = adapter.get("calibrated_for", {})
    rms = adapter.get("rms_vertex_error_m")
    where = []
    if stored_for.get("blender_version"):
        where.append("Blender %s" % stored_for["blender_version"])
    if stored_for.get("mean_edge_length_m"):
        where.append("mean edge %.1f mm" % (1000 * stored_for["mean_edge_length_m"]))
    if stored_for.get("fps"):
        where.append("%s fps" % _number(stored_for["fps"]))
    described = "%s%s" % (", ".join(where) or "an unknown mesh", "" if rms is None else
                          ", RMS vertex error %.1f mm" % (1000 * rms))
    factors = [settings.get("flowvid_log_factor_" + name) for name, _ in cal.CALIBRATED_GROUPS]
    if any(f is None for f in factors):
        return {"state": "foreign", "usable": False, "factors": None, "quality": None, "short": "not used",
                "text": "The preset stores Blender settings (%s) but not the calibration factors flowvid's "
                        "Calibrate writes, so they cannot be carried over to another mesh: Apply ignores them and "
                        "uses the formulas. Calibrate for This Mesh replaces them with a calibration." % described}
    status = {"state": "calibrated", "factors": [float(f) for f in factors],
              "quality": int(settings.get("quality", 0)), "short": "calibrated" + (
                  "" if rms is None else ", %.1f mm" % (1000 * rms))}
    edge = stored_for.get("mean_edge_length_m")
    if mean_edge_length_m is None:
        status.update(usable=None, text="Calibrated (%s). Apply uses it on meshes whose mean edge is within %d%% of "
                                        "that, at the same fps; otherwise the formulas." % (
                                            described, 100 * ADAPTER_EDGE_TOLERANCE))
    elif not edge or abs(edge - mean_edge_length_m) > ADAPTER_EDGE_TOLERANCE * edge:
        status.update(usable=False, text="The stored calibration is for mean edge %.1f mm, this mesh has %.1f mm: "
                                         "Apply used the formulas; run Calibrate for This Mesh." % (
                                             1000 * (edge or 0.0), 1000 * mean_edge_length_m))
    elif fps is not None and abs(stored_for.get("fps", fps) - fps) > 1e-6:
        status.update(usable=False, text="The stored calibration is for %s fps, the scene runs at %s fps: Apply used "
                                         "the formulas." % (_number(stored_for["fps"]), _number(fps)))
    else:
        status.update(usable=True, text="Apply used the stored calibration (%s)." % described)
    return status


def summary_pairs(preset):
    """(label, value) pairs for the panel: short labels, values with units."""
    p = preset.get("parameters", {})
    provenance = preset.get("provenance", {})
    made = " ".join(x for x in (provenance.get("method", "?"), provenance.get("created_utc", "")[:10]) if x)
    captures = len(provenance.get("captures", []))
    if captures:
        made += ", %d capture%s" % (captures, "" if captures == 1 else "s")
    return [
        ("Fabric", preset.get("name", "?")),
        ("Density", _quantity(p.get("areal_density_kg_per_m2"), "g/m\u00b2", 1000.0)),
        ("Stretch Warp", _quantity(p.get("stretch_warp_stiffness_N_per_m"), "N/m")),
        ("Stretch Weft", _quantity(p.get("stretch_weft_stiffness_N_per_m"), "N/m")),
        ("Shear", _quantity(p.get("shear_stiffness_N_per_m"), "N/m")),
        ("Bending", _quantity(p.get("bend_stiffness_N_m"), "\u00b5N\u00b7m", 1e6)),
        ("Drag", _quantity(p.get("drag_normal_kg_per_m3"), "kg/m\u00b3")),
        ("Made by", made),
        ("Blender", adapter_status(preset)["short"]),
    ]


def preset_details(preset):
    """Longer sentences for the Details popup and the Info log: description, provenance, the adapter."""
    lines = []
    if preset.get("description"):
        lines.append(preset["description"])
    provenance = preset.get("provenance", {})
    fitted = ["method %s" % provenance.get("method", "?")]
    for key, label in (("created_utc", "made"), ("optimizer", "optimizer"), ("simulator", "simulator"),
                       ("metric", "metric")):
        if provenance.get(key):
            fitted.append("%s %s" % (label, provenance[key]))
    errors = ["%s %s" % (e.get("capture", "?").rstrip("/").split("/")[-1], _number(e.get("error", 0.0)))
              for e in provenance.get("final_errors", [])]
    if errors:
        fitted.append("final errors (the fit's metric, no unit): " + ", ".join(errors))
    lines.append("Provenance: " + "; ".join(fitted) + ".")
    lines.append(adapter_status(preset)["text"])
    return lines


def vertex_mass_note(settings, derived):
    """Why Blender's Vertex Mass is what Apply set (the mapping's mass formula with this mesh's numbers)."""
    s = derived["mass_scale"]
    hem = derived.get("hem_line_density_kg_per_m", 0.0)
    mass_of = "%s kg/m\u00b2 \u00d7 %s m\u00b2" % (_number(derived["areal_density_kg_per_m2"]),
                                                     _number(derived["area_m2"]))
    if hem > 0.0:
        mass_of = "(%s + hem %s kg/m \u00d7 %s m)" % (mass_of, _number(hem), _number(derived["boundary_length_m"]))
    return ("Vertex Mass %s = %s \u00d7 %s / %d vertices. Only the ratio of forces to mass moves the cloth, so "
            "Blender's mass unit is free; flowvid counts it in grams (\u00d7 %s), which keeps the stiffness "
            "values in Blender's usual range: each vertex carries %s g of fabric, although Blender labels the "
            "field kg." % (_number(settings["mass"], 4), _number(s), mass_of, derived["vertex_count"], _number(s),
                           _number(settings["mass"] * 1000.0 / s, 4)))


def fold_note(check):
    """What a mesh too coarse for the fabric's folds means for the artist (a backend's check_folds), or None
    where the mesh holds them."""
    if check["holds_folds"]:
        return None
    text = ("This fabric folds at about %s mm when it hangs (its elastogravity length), and this mesh's edges "
            "average %s mm: the cloth folds at the mesh's own scale, so its drape is the mesh's and changes when "
            "you subdivide. Edges of at most %s mm show the fabric's own folds."
            % (_number(1e3 * check["fold_length_m"], 2), _number(1e3 * check["edge_m"], 3),
               _number(1e3 * check["longest_edge_m"], 2)))
    if check.get("fitted_mesh_holds_folds") is False:
        text += (" The preset was fitted on a swatch with %s mm edges, which do not hold them either: edges near "
                 "%s mm reproduce the filmed drape most closely." % ((_number(1e3 * check["fitted_edge_m"], 2),) * 2))
    return text


def fold_warning(check):
    """fold_note in a panel's line, or "" where the mesh holds the folds."""
    return "" if check["holds_folds"] else "Edges too long for its %s mm folds" % _number(1e3 * check["fold_length_m"], 2)


def wrap(text, width, measure):
    """Words of `text` in lines no wider than `width` as measure(str) gives widths (a single longer word
    stands alone)."""
    lines = []
    for paragraph in text.split("\n"):
        line = ""
        for word in paragraph.split():
            candidate = word if not line else line + " " + word
            if line and measure(candidate) > width:
                lines.append(line)
                line = word
            else:
                line = candidate
        lines.append(line)
    return lines
