#!/usr/bin/env python3
"""Where a captured drape bends: a study of truth/ (evaluation only, never a fit).

For each cloth capture's first frame (its settled drape), prints
  * the out-of-plane fold amplitude (depth off the best plane, a quadratic
    sag removed) and the share of its power, along each row, at wavelengths
    shorter than two edges of a 12x12 mesh (what such a mesh cannot carry);
  * how far the drape sampled at the 12x12 uv points and interpolated back
    is from it (RMS and max, mm);
  * the sharpest bend: second differences of positions along rows and
    columns (1/m), and the radius they imply;
  * how the mesh's cells deform: each cell's corner shears (w_u . w_v from
    the two sides meeting at a corner), the pair at one diagonal's ends
    against the pair at the other's. A cell folded along a diagonal keeps
    the corners on the fold line and changes the other two; an in-plane
    shear changes all four. The smaller pair's share is what in-plane shear
    the drape holds (docs/cloth_model.md, "What the shear does on the
    footage's mesh").
docs/cloth_model.md ("The same fabric on other meshes, from both starts").

    OPENCV_IO_ENABLE_OPENEXR=1 /usr/bin/python3 bench/drape_folds.py [CAPTURES_DIR]
"""
import json
import os
import sys

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import cv2  # noqa: E402
import numpy as np  # noqa: E402


def first_frame(capture_dir):
    """The truth's frame 1 as rows x cols x 3 (metres)."""
    image = cv2.imread(os.path.join(capture_dir, "truth", "positions.exr"), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SystemExit(f"{capture_dir}/truth/positions.exr: cannot be read (OpenCV built without OpenEXR?)")
    grid = json.load(open(os.path.join(capture_dir, "truth", "truth.json")))
    rgb = image[:, :, ::-1].astype(np.float64)  # OpenCV gives BGR
    return rgb[0].reshape(grid["rows"], grid["cols"], 3)


def resample_rows_cols(points, out_rows, out_cols):
    """Bilinear resampling of a rows x cols x 3 grid over the unit square."""
    rows, cols, _ = points.shape
    src_r, src_c = np.linspace(0, 1, rows), np.linspace(0, 1, cols)
    dst_r, dst_c = np.linspace(0, 1, out_rows), np.linspace(0, 1, out_cols)
    along_c = np.stack([[np.interp(dst_c, src_c, points[r, :, k]) for r in range(rows)] for k in range(3)], -1)
    return np.stack([[np.interp(dst_r, src_r, along_c[:, c, k]) for c in range(out_cols)] for k in range(3)], -1).transpose(1, 0, 2)


def corner_shear_split(points, edge_u_m, edge_v_m):
    """(sum over cells of the mean corner shear^2, of the smaller diagonal pair's): folds vs in-plane shear."""
    a, b, c, d = points[:-1, :-1], points[:-1, 1:], points[1:, 1:], points[1:, :-1]
    scale = edge_u_m * edge_v_m
    at_a = np.sum((b - a) * (d - a), -1) / scale
    at_b = np.sum((b - a) * (c - b), -1) / scale
    at_c = np.sum((c - d) * (c - b), -1) / scale
    at_d = np.sum((c - d) * (d - a), -1) / scale
    pair_ac, pair_bd = (at_a**2 + at_c**2) / 2, (at_b**2 + at_d**2) / 2
    return float(((pair_ac + pair_bd) / 2).sum()), float(np.minimum(pair_ac, pair_bd).sum())


def main():
    captures = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..", "shared", "captures")
    for name in sorted(os.listdir(captures)):
        folder = os.path.join(captures, name)
        if not name.startswith("cloth-") or not os.path.exists(os.path.join(folder, "truth", "positions.exr")):
            continue
        capture = json.load(open(os.path.join(folder, "capture.json")))
        width_m = capture["swatch"]["width_m"]
        points = first_frame(folder)
        rows, cols, _ = points.shape
        edge_m = width_m / (cols - 1)
        flat = points.reshape(-1, 3)
        centre = flat.mean(0)
        normal = np.linalg.svd(flat - centre, full_matrices=False)[2][2]
        depth = (points - centre) @ normal
        u, v = np.meshgrid(np.linspace(0, 1, cols), np.linspace(0, 1, rows))
        basis = np.stack([np.ones_like(u), u, v, u * u, u * v, v * v], -1).reshape(-1, 6)
        sag = basis @ np.linalg.lstsq(basis, depth.ravel(), rcond=None)[0]
        folds = depth - sag.reshape(rows, cols)
        window = np.hanning(cols)
        power = np.mean(np.abs(np.fft.rfft((folds - folds.mean(1, keepdims=True)) * window, axis=1)) ** 2, axis=0)[1:]
        wavelength_m = 1.0 / np.fft.rfftfreq(cols, d=edge_m)[1:]
        coarse_limit_m = 2 * width_m / 11  # two edges of a 12x12 mesh
        short_share = power[wavelength_m < coarse_limit_m].sum() / power.sum()
        back = resample_rows_cols(resample_rows_cols(points, 12, 12), rows, cols)
        miss = np.linalg.norm(back - points, axis=-1)
        bend_u = np.linalg.norm(points[:, 2:] - 2 * points[:, 1:-1] + points[:, :-2], axis=-1) / edge_m**2
        bend_v = np.linalg.norm(points[2:] - 2 * points[1:-1] + points[:-2], axis=-1) / edge_m**2
        sharpest = max(bend_u.max(), bend_v.max())
        all_corners, in_plane = corner_shear_split(points, edge_m, capture["swatch"]["height_m"] / (rows - 1))
        print(f"{name}: fold amplitude {1e3 * folds.std():.1f} mm RMS; power below {1e3 * coarse_limit_m:.1f} mm "
              f"wavelength {100 * short_share:.0f} %; at the 12x12 points and back {1e3 * np.sqrt((miss**2).mean()):.1f} mm RMS, "
              f"{1e3 * miss.max():.1f} max; sharpest bend {sharpest:.0f} 1/m (radius {1e3 / sharpest:.1f} mm, edge {1e3 * edge_m:.1f}); "
              f"cells' corner shear RMS {np.sqrt(all_corners / ((rows - 1) * (cols - 1))):.3f}, in-plane "
              f"(the smaller diagonal pair) {100 * in_plane / all_corners:.1f} % of its square")


if __name__ == "__main__":
    main()
