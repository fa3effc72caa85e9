"""bench/blender_cloth_swatch.py, the Blender side of the capacity bench's bounds: a run started from
given positions keeps the flat grid as the cloth's rest shape.

Run inside Blender (tests/blender/run.py); the swatch script runs in a Blender process of its own."""
import json
import math
import os
import struct
import subprocess
import tempfile

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SWATCH_SCRIPT = os.path.join(REPO, "bench", "blender_cloth_swatch.py")


def _write_capture(folder, width_m, height_m, pins):
    """A minimal cloth.static capture.json: the swatch, its pins (uv and one position each) and one frame."""
    capture = {"format": "flowvid.capture", "version": 1, "kind": "cloth.static", "fps": 30,
               "frames": {"pattern": "frames/%06d.png", "first": 1, "count": 1},
               "swatch": {"width_m": width_m, "height_m": height_m, "mass_kg": 0.01,
                          "pins": [{"uv": list(uv), "positions": [list(p)]} for uv, p in pins]}}
    with open(os.path.join(folder, "capture.json"), "w") as f:
        json.dump(capture, f)


def test_bench_swatch_start_keeps_the_flat_rest_shape():
    """A 7 x 7 swatch started shrunk to 0.8 of its size about its top edge, its pins held where the
    shrunk start has them, settles with its bottom row and its side columns at least 0.95 of their flat
    (rest) lengths. Before the fix the start became Blender's rest shape and both stayed at 0.80."""
    width, height, top, n, shrink = 0.3, 0.3, 1.2, 7, 0.8
    start = []
    for r in range(n):
        for c in range(n):
            x = (c / (n - 1) - 0.5) * width
            z = top - (1.0 - r / (n - 1)) * height
            start.append((shrink * x, 0.0, top + shrink * (z - top)))
    pins = [((0.0, 1.0), start[(n - 1) * n]), ((1.0, 1.0), start[n * n - 1])]
    with tempfile.TemporaryDirectory() as folder:
        _write_capture(folder, width, height, pins)
        start_file = os.path.join(folder, "start.raw")
        with open(start_file, "wb") as f:
            f.write(struct.pack("<%dd" % (3 * n * n), *[v for p in start for v in p]))
        out = os.path.join(folder, "positions.raw")
        run = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", "-noaudio", "--python", SWATCH_SCRIPT, "--",
                              "--capture", folder, "--rows", str(n), "--cols", str(n), "--frames", "1",
                              "--quality", "5", "--preroll", "40", "--start-positions", start_file,
                              "--positions-out", out], capture_output=True, text=True, timeout=240)
        assert run.returncode == 0 and os.path.isfile(out), run.stdout[-2000:] + run.stderr[-2000:]
        with open(out, "rb") as f:
            raw = f.read()
    values = struct.unpack("<%dd" % (len(raw) // 8), raw)
    settled = [values[3 * i:3 * i + 3] for i in range(n * n)]

    def path_length(indices):
        return sum(math.dist(settled[a], settled[b]) for a, b in zip(indices, indices[1:]))

    bottom_row = path_length(list(range(n)))
    side_columns = [path_length([r * n + c for r in range(n)]) for c in (0, n - 1)]
    assert bottom_row > 0.95 * width, ("bottom row", bottom_row, "rest", width)
    for length in side_columns:
        assert length > 0.95 * height, ("side column", length, "rest", height)
