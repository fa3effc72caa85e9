"""Flow lines without Blender: which input line each output line takes its
texture from (assign_inputs), by hand or by rule. Plain Python, tested
without bpy (tests/python/test_addon_core.py)."""
import math

from .errors import FlowvidError


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
