"""Calibration machinery without bpy: the swatch experiments, the error between
two simulations, and a small Nelder-Mead search.

The experiments are the preset's own calibration tests (docs/cloth_model.md):
a static drape (a swatch hung by its two top corners, closer together than the
swatch is wide) and a waving swatch (the right corner moves sideways). Both
are symmetric under y -> -y (the pins stay in the plane y = 0), so a hung
swatch may bow to either side; errors are taken for the closer of the two
mirror images.
"""
import math

DEFAULT_ROWS = 12
DEFAULT_COLS = 12


def swatch_experiments(width_m=0.30, height_m=0.30, separation_m=0.24, fps=30.0, static_frames=45,
                       waving_frames=30, amplitude_m=0.06, frequency_hz=1.2):
    """The static and waving experiments as dicts for flowvid.cloth.simulate_swatch.

    Pins: uv (0, 1) and (1, 1) at x = -/+ separation/2, y = 0, z = 0 (world z
    up). Waving: the right pin moves x += amplitude * sin(2 pi f t), t = k/fps."""
    half = 0.5 * separation_m
    static = {
        "name": "static",
        "width_m": width_m, "height_m": height_m, "fps": fps, "frame_count": static_frames,
        "pins": [
            {"uv": [0.0, 1.0], "positions_m": [[-half, 0.0, 0.0]] * static_frames},
            {"uv": [1.0, 1.0], "positions_m": [[half, 0.0, 0.0]] * static_frames},
        ],
    }
    moving = [[half + amplitude_m * math.sin(2.0 * math.pi * frequency_hz * k / fps), 0.0, 0.0]
              for k in range(waving_frames)]
    waving = {
        "name": "waving",
        "width_m": width_m, "height_m": height_m, "fps": fps, "frame_count": waving_frames,
        "pins": [
            {"uv": [0.0, 1.0], "positions_m": [[-half, 0.0, 0.0]] * waving_frames},
            {"uv": [1.0, 1.0], "positions_m": moving},
        ],
    }
    return [static, waving]


def cantilever_experiment(width_m=0.06, rows=12, cols=12, fps=30.0, frames=90):
    """A bending test: the swatch held horizontally by its two top rows (a clamp: one pinned row
    would be a hinge), the rest overhanging. Returns (experiment, flat horizontal start positions);
    the droop is set by the bending length (D / (rho g))^(1/3)."""
    spacing = width_m / (cols - 1)
    pins = []
    for r in (rows - 1, rows - 2):
        for c in range(cols):
            position = [width_m * (c / (cols - 1) - 0.5), (rows - 1 - r) * spacing, 0.0]
            pins.append({"uv": [c / (cols - 1), r / (rows - 1)], "positions_m": [position] * frames})
    experiment = {"name": "cantilever", "width_m": width_m, "height_m": width_m, "fps": fps,
                  "frame_count": frames, "pins": pins}
    start = [(width_m * (c / (cols - 1) - 0.5), (rows - 1 - r) * spacing, 0.0)
             for r in range(rows) for c in range(cols)]
    return experiment, start


def grid_vertex(row, col, cols):
    """Vertex index of a swatch grid (row 0 at v = 0, the bottom as hung)."""
    return row * cols + col


def flat_grid(width_m, height_m, rows, cols):
    """Rest positions of the flat swatch in the plane y = 0, top row at z = 0, centred on x = 0."""
    points = []
    for r in range(rows):
        for c in range(cols):
            points.append((width_m * (c / (cols - 1) - 0.5), 0.0, height_m * (r / (rows - 1) - 1.0)))
    return points


def rms_error(frames_a, frames_b, mirror_y=True):
    """RMS vertex distance (metres) over all frames and vertices; with mirror_y,
    the smaller of the direct error and the error against b mirrored in y."""
    def rms(sign):
        total = 0.0
        count = 0
        for fa, fb in zip(frames_a, frames_b):
            for pa, pb in zip(fa, fb):
                dx = pa[0] - pb[0]
                dy = pa[1] - sign * pb[1]
                dz = pa[2] - pb[2]
                total += dx * dx + dy * dy + dz * dz
                count += 1
        return math.sqrt(total / max(count, 1))

    direct = rms(1.0)
    return min(direct, rms(-1.0)) if mirror_y else direct


def mean_sag(frame, pinned_z=0.0):
    """Mean drop of the vertices below the pins (metres): the simplest 'how much it sags'."""
    return pinned_z - sum(p[2] for p in frame) / len(frame)


def nelder_mead_steps(start, step=0.3, max_evaluations=16, tolerance=1e-3):
    """A small Nelder-Mead simplex as a generator, so that a modal operator can
    run one evaluation per timer tick: it yields the next point to evaluate and
    receives its value through send(); it returns (best_x, best_value,
    evaluations). Few evaluations by design (each one runs Blender)."""
    n = len(start)
    simplex = [list(start)]
    for i in range(n):
        point = list(start)
        point[i] += step
        simplex.append(point)
    values = []
    evaluations = 0
    for point in simplex:
        values.append((yield point))
        evaluations += 1
    while evaluations < max_evaluations:
        order = sorted(range(n + 1), key=lambda i: values[i])
        simplex = [simplex[i] for i in order]
        values = [values[i] for i in order]
        if abs(values[-1] - values[0]) <= tolerance * max(abs(values[0]), 1e-12):
            break
        centroid = [sum(p[i] for p in simplex[:-1]) / n for i in range(n)]
        worst = simplex[-1]
        reflected = [c + (c - w) for c, w in zip(centroid, worst)]
        fr = yield reflected
        evaluations += 1
        if fr < values[0] and evaluations < max_evaluations:
            expanded = [c + 2.0 * (c - w) for c, w in zip(centroid, worst)]
            fe = yield expanded
            evaluations += 1
            if fe < fr:
                simplex[-1], values[-1] = expanded, fe
            else:
                simplex[-1], values[-1] = reflected, fr
        elif fr < values[-2]:
            simplex[-1], values[-1] = reflected, fr
        elif evaluations < max_evaluations:
            contracted = [c + 0.5 * (w - c) for c, w in zip(centroid, worst)]
            fc = yield contracted
            evaluations += 1
            if fc < values[-1]:
                simplex[-1], values[-1] = contracted, fc
            else:
                for i in range(1, n + 1):
                    if evaluations >= max_evaluations:
                        break
                    simplex[i] = [b + 0.5 * (p - b) for b, p in zip(simplex[0], simplex[i])]
                    values[i] = yield simplex[i]
                    evaluations += 1
        elif fr < values[-1]:
            simplex[-1], values[-1] = reflected, fr
    best = min(range(len(values)), key=lambda i: values[i])
    return simplex[best], values[best], evaluations


def nelder_mead(objective, start, **options):
    """nelder_mead_steps driven by a plain objective(x) -> float."""
    steps = nelder_mead_steps(start, **options)
    try:
        point = next(steps)
        while True:
            point = steps.send(objective(point))
    except StopIteration as done:
        return done.value


# Which Blender settings calibration refines, as log-scale factors on the
# formula's values (tension and compression move together; so do the spring
# dampings with their stiffness).
CALIBRATED_GROUPS = (
    ("stretch", ("tension_stiffness", "compression_stiffness", "shear_stiffness")),
    ("bending", ("bending_stiffness",)),
    ("air", ("air_damping",)),
)


def scaled_settings(base, log_factors, limits=None):
    """base settings with each CALIBRATED_GROUPS group multiplied by exp(factor), clamped to limits."""
    settings = dict(base)
    for (name, keys), factor in zip(CALIBRATED_GROUPS, log_factors):
        for key in keys:
            value = base[key] * math.exp(factor)
            if limits and key in limits:
                value = min(max(value, limits[key][0]), limits[key][1])
            settings[key] = value
    return settings
