"""The add-on's bpy-free core: the preset -> Blender mapping, its inverse, the
calibration helpers. Plain python3 (no Blender)."""
import json
import math
import os
import sys
import tempfile
import unittest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "blender_addon"))

from flowvid_blender.core import backend, calibration, mapping, presentation  # noqa: E402

EXAMPLE = os.path.join(REPO, "formats", "examples", "cotton.fabric.json")


def cotton():
    with open(EXAMPLE) as handle:
        return json.load(handle)["parameters"]


class MappingTest(unittest.TestCase):
    def test_gravity_time_unit(self):
        # Blender's gravity is 0.001 g per (solver time unit)^2: real only when tau^2 = 0.001 s^2.
        for fps in (24.0, 25.0, 30.0, 60.0):
            tau = mapping.time_unit_s(fps, mapping.gravity_time_scale(fps))
            self.assertAlmostEqual(0.001 * 9.81 / tau ** 2, 9.81, places=9)

    def test_stiffness_scales_with_edge_length(self):
        coarse = mapping.map_preset(cotton(), mapping.MeshStats(100, 0.02, 0.04), 30.0).settings
        fine = mapping.map_preset(cotton(), mapping.MeshStats(400, 0.01, 0.04), 30.0).settings
        # Springs: tension = k L (same membrane stiffness); bending = 20 D / L^2; mass per vertex = rho A / N.
        self.assertAlmostEqual(fine["tension_stiffness"] / coarse["tension_stiffness"], 0.5, places=12)
        self.assertAlmostEqual(fine["bending_stiffness"] / coarse["bending_stiffness"], 4.0, places=12)
        self.assertAlmostEqual(fine["mass"] / coarse["mass"], 0.25, places=12)
        self.assertAlmostEqual(fine["air_damping"] / coarse["air_damping"], 0.25, places=12)

    def test_inverse_round_trip(self):
        stats = mapping.MeshStats(576, 0.3 / 23, 0.09)
        settings = mapping.map_preset(cotton(), stats, 30.0).settings
        back = mapping.parameters_from_settings(settings, stats, areal_density_kg_per_m2=0.15)
        for key in ("stretch_warp_stiffness_N_per_m", "shear_stiffness_N_per_m", "bend_stiffness_N_m",
                    "stretch_warp_damping_N_s_per_m", "bend_damping_N_m_s"):
            self.assertAlmostEqual(back[key] / cotton()[key]["value"], 1.0, places=9, msg=key)
        # Drag comes back as the linear drag of the reference speed, on the normal (kL) and tangent (kT).
        self.assertAlmostEqual(back["drag_tangential_kg_per_m2_s"], 0.6 * 0.5 / (1 + 0.1 * 0.25), places=9)
        self.assertAlmostEqual(back["drag_linear_normal_kg_per_m2_s"], 0.6 * 0.5 / (1 + 0.1 * 0.25), places=9)
        self.assertEqual(back["drag_normal_kg_per_m3"], 0.0)
        self.assertAlmostEqual(back["stretch_warp_compression_ratio"], 1.0, places=9)

    def test_format_1_1_parameters(self):
        # Softer compression sets Blender's compression springs; kL adds to its linear air damping;
        # a hem's mass is spread over the vertices (and noted); a 1.0 preset maps as before.
        stats = mapping.MeshStats(576, 0.3 / 23, 0.09, boundary_length_m=1.2)
        old = cotton()
        for key in mapping.OPTIONAL_PARAMETERS:
            old.pop(key, None)
        base = mapping.map_preset(old, stats, 30.0)
        self.assertEqual(base.settings, mapping.map_preset(cotton(), stats, 30.0).settings)
        parameters = cotton()
        parameters["stretch_warp_compression_ratio"]["value"] = 0.2
        parameters["stretch_weft_compression_ratio"]["value"] = 0.2
        parameters["drag_linear_normal_kg_per_m2_s"]["value"] = 0.3
        parameters["hem_line_density_kg_per_m"]["value"] = 0.001
        result = mapping.map_preset(parameters, stats, 30.0)
        self.assertAlmostEqual(result.settings["compression_stiffness"] / base.settings["compression_stiffness"], 0.2,
                               places=12)
        damping = mapping.DEFAULT_MASS_SCALE / mapping.SQRT_1000
        added_drag = 0.3 * (0.09 / 576) * damping / mapping.BLENDER_AIR_DAMPING_SCALE
        self.assertAlmostEqual(result.settings["air_damping"] - base.settings["air_damping"], added_drag, places=9)
        self.assertAlmostEqual(result.settings["mass"] / base.settings["mass"], (0.15 * 0.09 + 0.001 * 1.2) / (0.15 * 0.09),
                               places=12)
        self.assertIn("hem", " ".join(result.not_represented))
        back = mapping.parameters_from_settings(result.settings, stats, areal_density_kg_per_m2=0.15)
        self.assertAlmostEqual(back["stretch_warp_compression_ratio"], 0.2, places=9)
        # Diagonal tension fibres are Blender's diagonal springs, at half their stiffness each.
        parameters["diagonal_tension_stiffness_N_per_m"]["value"] = 40.0
        fibres = mapping.map_preset(parameters, stats, 30.0)
        self.assertAlmostEqual(fibres.derived["shear_spring_N_per_m"] - result.derived["shear_spring_N_per_m"], 20.0,
                               places=9)

    def test_clamps_and_notes(self):
        parameters = cotton()
        parameters["stretch_warp_damping_N_s_per_m"]["value"] = 100.0
        parameters["stretch_weft_stiffness_N_per_m"]["value"] = 400.0
        result = mapping.map_preset(parameters, mapping.MeshStats(100, 0.02, 0.04), 30.0)
        self.assertEqual(result.settings["tension_damping"], 50.0)
        text = " ".join(result.not_represented)
        self.assertIn("tension_damping", text)
        self.assertIn("anisotropic stretch", text)

    def test_bad_preset_names_fields(self):
        parameters = cotton()
        del parameters["bend_stiffness_N_m"]
        parameters["drag_normal_kg_per_m3"]["value"] = float("nan")
        with self.assertRaises(mapping.MappingError) as caught:
            mapping.map_preset(parameters, mapping.MeshStats(100, 0.02, 0.04), 30.0)
        self.assertIn("/parameters/bend_stiffness_N_m", str(caught.exception))
        self.assertIn("/parameters/drag_normal_kg_per_m3", str(caught.exception))


class CalibrationHelpersTest(unittest.TestCase):
    def test_nelder_mead_finds_minimum(self):
        best, value, evaluations = calibration.nelder_mead(
            lambda x: (x[0] - 0.3) ** 2 + 2 * (x[1] + 0.2) ** 2 + 1.0, [0.0, 0.0], max_evaluations=80,
            tolerance=1e-12)
        self.assertLess(abs(best[0] - 0.3), 1e-3)
        self.assertLess(abs(best[1] + 0.2), 1e-3)
        self.assertLessEqual(evaluations, 80)

    def test_rms_mirror(self):
        a = [[(0.0, 0.1, 0.0), (1.0, -0.2, 0.0)]]
        b = [[(0.0, -0.1, 0.0), (1.0, 0.2, 0.0)]]
        self.assertAlmostEqual(calibration.rms_error(a, b), 0.0)
        self.assertAlmostEqual(calibration.rms_error(a, b, mirror_y=False), math.sqrt((0.04 + 0.16) / 2))

    def test_experiments(self):
        static, waving = calibration.swatch_experiments(fps=25.0, waving_frames=26)
        self.assertEqual(len(waving["pins"][1]["positions_m"]), 26)
        # One period of 1.2 Hz at 25 fps: the right pin is back near its start after 21 frames.
        self.assertAlmostEqual(waving["pins"][1]["positions_m"][0][0], 0.12)
        self.assertEqual(static["pins"][0]["positions_m"][0], [-0.12, 0.0, 0.0])


class LibraryTest(unittest.TestCase):
    """The native module's swatch simulation (skipped when it is not built)."""

    def test_simulate_swatch(self):
        try:
            import flowvid
        except ImportError:
            self.skipTest("native flowvid module not on PYTHONPATH")
        static, _ = calibration.swatch_experiments(static_frames=1)
        result = flowvid.cloth.simulate_swatch(static, cotton(), rows=8, cols=8)
        self.assertEqual(result["status"], "ok")
        frame = result["frames"][0]
        self.assertEqual(len(frame), 64)
        # Pinned corners stay where the experiment puts them; the rest hangs below.
        self.assertAlmostEqual(frame[7 * 8][0], -0.12, places=9)
        self.assertGreater(calibration.mean_sag(frame), 0.1)
        broken = cotton()
        del broken["shear_stiffness_N_per_m"]
        with self.assertRaises(flowvid.ValidationError) as caught:
            flowvid.cloth.simulate_swatch(static, broken, rows=8, cols=8)
        self.assertIn("/parameters/shear_stiffness_N_per_m", str(caught.exception))
        # A format-1.0 preset lacks the parameters added since: they are neutral, the same cloth to the bit.
        old = cotton()
        for key in mapping.OPTIONAL_PARAMETERS:
            old.pop(key, None)
        self.assertEqual(flowvid.cloth.simulate_swatch(static, old, rows=8, cols=8)["frames"], result["frames"])


@unittest.skipUnless(os.environ.get("FLOWVID_CLI"), "the flowvid tool's path is given by ctest")
class CliBackendTest(unittest.TestCase):
    def test_reads_flow_lines_drawn_in_svg_or_json(self):
        # Without the Python module the add-on reads an artist's drawing as the module does.
        cli = backend.CliBackend(os.environ["FLOWVID_CLI"])
        drawn = cli.read_flowline_set(os.path.join(REPO, "data", "demo", "waterfall", "flowlines.svg"))
        self.assertEqual(drawn["format"], "flowvid.flowlines")
        self.assertGreaterEqual(len(drawn["inputs"]), 2)
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "drawn.flowlines.json")
            cli.write_flowline_set(path, drawn)
            self.assertEqual(cli.read_flowline_set(path), drawn)


@unittest.skipUnless(os.environ.get("FLOWVID_CLI"), "the flowvid tool's path is given by ctest")
class FoldCheckTest(unittest.TestCase):
    def test_module_and_tool_say_alike_whether_a_garments_edges_hold_the_folds(self):
        # Apply's fold note: the library's rule (edges up to 4/3 of the elastogravity length
        # (B / rho g)^(1/3)) through either backend, and what the artist reads.
        import flowvid

        silk = os.path.join(REPO, "tests", "data", "cloth", "silk.fabric.json")
        with open(silk) as handle:
            p = json.load(handle)["parameters"]
        fold_m = (p["bend_stiffness_N_m"]["value"] / (p["areal_density_kg_per_m2"]["value"] * 9.81)) ** (1.0 / 3.0)
        native = backend.NativeBackend(flowvid)
        cli = backend.CliBackend(os.environ["FLOWVID_CLI"])
        for edge_m in (0.012, 0.020):
            checks = [chosen.check_folds(silk, edge_m) for chosen in (native, cli)]
            self.assertEqual(set(checks[0]), set(checks[1]))
            for check in checks:
                self.assertAlmostEqual(check["fitted_edge_m"], 0.3 / 23, places=12)  # the preset's provenance
                self.assertTrue(check["fitted_mesh_holds_folds"])  # 13.04 mm edges hold 9.83 mm folds
                self.assertAlmostEqual(check["fold_length_m"], fold_m, places=12)
                self.assertAlmostEqual(check["longest_edge_m"], 4.0 / 3.0 * fold_m, places=12)
                self.assertAlmostEqual(check["edge_m"], edge_m, places=12)
                self.assertEqual(check["holds_folds"], edge_m < 4.0 / 3.0 * fold_m)
            note, warning = presentation.fold_note(checks[0]), presentation.fold_warning(checks[0])
            if checks[0]["holds_folds"]:
                self.assertIsNone(note)
                self.assertEqual(warning, "")
            else:
                self.assertIn("folds at about 9.8 mm", note)
                self.assertIn("edges average 20 mm", note)
                self.assertIn("at most 13 mm", note)
                self.assertEqual(warning, "Edges too long for its 9.8 mm folds")
                self.assertNotIn("fitted on", note)
                coarse = dict(checks[0], fitted_edge_m=0.3 / 11, fitted_mesh_holds_folds=False)
                self.assertIn("fitted on a swatch with 27 mm edges, which do not hold them either: edges near 27 mm "
                              "reproduce the filmed drape", presentation.fold_note(coarse))
        with self.assertRaises(backend.BackendError):
            native.check_folds(silk, -1.0)


@unittest.skipUnless(os.environ.get("FLOWVID_CLI"), "the flowvid tool's path is given by ctest")
class CliMappingTest(unittest.TestCase):
    def test_cli_mapping_equals_addon(self):
        # flowvid convert PRESET OUT.blender.json --mesh (the C++ library's cloth/blender_cloth) gives the
        # settings this add-on's map_preset gives for the same preset, mesh and fps: one mapping, two homes.
        with open(EXAMPLE) as handle:
            preset = json.load(handle)
        p = preset["parameters"]
        p["stretch_weft_stiffness_N_per_m"]["value"] = 610.0      # anisotropic
        p["hem_line_density_kg_per_m"]["value"] = 0.002
        p["diagonal_tension_stiffness_N_per_m"]["value"] = 35.0
        p["drag_linear_normal_kg_per_m2_s"]["value"] = 0.04
        p["stretch_warp_compression_ratio"]["value"] = 0.5
        p["stretch_weft_compression_ratio"]["value"] = 0.25
        mesh_path = os.path.join(REPO, "tests", "data", "cloth", "panel_9x5.obj")
        # The panel measured by hand: 0.4 m x 0.3 m, 9 x 5 vertices, 40 edges of 5 cm along x, 36 of 7.5 cm along y.
        stats = mapping.MeshStats(vertex_count=45, mean_edge_length_m=(40 * 0.05 + 36 * 0.075) / 76, area_m2=0.12,
                                  quad_fraction=1.0, boundary_length_m=1.4)
        with tempfile.TemporaryDirectory() as folder:
            preset_path = os.path.join(folder, "test.fabric.json")
            with open(preset_path, "w") as handle:
                json.dump(preset, handle)
            out = os.path.join(folder, "panel.blender.json")
            import subprocess
            subprocess.run([os.environ["FLOWVID_CLI"], "convert", preset_path, out, "--mesh", mesh_path,
                            "--fps", "25", "--quality", "12"], check=True, capture_output=True)
            with open(out) as handle:
                written = json.load(handle)
        for key in ("vertex_count", "mean_edge_length_m", "area_m2", "quad_fraction", "boundary_length_m"):
            self.assertAlmostEqual(written["mesh"][key], getattr(stats, key), places=12, msg=key)
        expected = mapping.map_preset(preset["parameters"], stats, 25.0, quality=12)
        self.assertEqual(set(written["settings"]), set(expected.settings))
        for name, value in expected.settings.items():
            if isinstance(value, str):
                self.assertEqual(written["settings"][name], value, msg=name)
            else:
                self.assertAlmostEqual(written["settings"][name] / value if value else written["settings"][name],
                                       1.0 if value else 0.0, places=12, msg=name)
        for name, value in expected.derived.items():
            if name in written["derived"]:
                self.assertAlmostEqual(written["derived"][name], value, places=12, msg=name)
        self.assertEqual(len(written["not_represented"]), len(expected.not_represented) + 1)  # + the adapter note


def write_falling_clip(folder, frames=24, width=64, height=48, speed_px=2):
    """A textured band falling down the middle at speed_px per frame, as binary PPM frames; returns the pattern."""
    os.makedirs(folder, exist_ok=True)
    for t in range(frames):
        pixels = bytearray()
        for y in range(height):
            yy = y - speed_px * t
            for x in range(width):
                if abs(x - width // 2) < 12:
                    pixels += bytes((int(127 + 100 * math.sin(x / 2.3 + yy / 3.1)), int(127 + 100 * math.cos(yy / 2.2)),
                                     int(127 + 100 * math.sin((x - 2 * yy) / 3.7))))
                else:
                    pixels += b"\x20\x20\x20"
        with open(os.path.join(folder, "%06d.ppm" % (t + 1)), "wb") as handle:
            handle.write(b"P6 %d %d 255\n" % (width, height) + bytes(pixels))
    return os.path.join(folder, "%06d.ppm")


@unittest.skipUnless(os.environ.get("FLOWVID_CLI"), "the flowvid tool's path is given by ctest")
class SynthesisEntryPointTest(unittest.TestCase):
    """The module and the tool render through one library entry point (flow::render_synthesis)."""

    def test_module_and_tool_render_the_same_frames(self):
        import flowvid

        native = backend.NativeBackend(flowvid)
        cli = backend.CliBackend(os.environ["FLOWVID_CLI"])
        with tempfile.TemporaryDirectory() as folder:
            clip = write_falling_clip(os.path.join(folder, "clip"))
            drawn = os.path.join(folder, "drawn.flowlines.json")
            with open(drawn, "w") as handle:
                json.dump({"format": "flowvid.flowlines", "version": "1.0",
                           "image": {"width": 64, "height": 48, "pixel_convention": "opencv"},
                           "inputs": [{"id": "in-1", "points": [[32, -4], [32, 51]]}]}, handle)
            bank = os.path.join(folder, "fall.bank.exr")
            cli.run("track", "--clip", clip, "--fps", "25", "--flowlines", drawn, "--out", bank, "--patch", "12")
            outputs = {}
            for name, chosen in (("module", native), ("tool", cli)):
                stages = []
                summary = chosen.synthesize(bank, os.path.join(folder, name, "%06d.png"), (3, 6), flowlines=drawn,
                                            capture=clip, progress=lambda stage, f, m: stages.append((stage, f)))
                self.assertEqual(summary["frames"], [3, 6])
                self.assertEqual(summary["frames_written"], 4)
                self.assertEqual(stages[-1], ("render", 1.0), name)
                outputs[name] = summary
            for frame in range(3, 7):
                with open(os.path.join(folder, "module", "%06d.png" % frame), "rb") as a, \
                        open(os.path.join(folder, "tool", "%06d.png" % frame), "rb") as b:
                    self.assertEqual(a.read(), b.read(), "frame %d differs between the module and the tool" % frame)
            self.assertEqual(outputs["module"]["period_frames"], outputs["tool"]["period_frames"])
            self.assertEqual(outputs["module"]["background"], outputs["tool"]["background"])
            self.assertEqual(outputs["module"]["edge_fade_px"], 0.0)  # plain synthesis does not fade its edge
            # An edge fade asked for reaches the library through either backend, the same.
            for name, chosen in (("module_fade", native), ("tool_fade", cli)):
                summary = chosen.synthesize(bank, os.path.join(folder, name, "%06d.png"), (3, 3), flowlines=drawn,
                                            capture=clip, edge_fade=6)
                self.assertEqual(summary["edge_fade_px"], 6.0, name)
            with open(os.path.join(folder, "module_fade", "000003.png"), "rb") as a, \
                    open(os.path.join(folder, "tool_fade", "000003.png"), "rb") as b, \
                    open(os.path.join(folder, "module", "000003.png"), "rb") as plain:
                faded = a.read()
                self.assertEqual(faded, b.read(), "the faded frame differs between the module and the tool")
                self.assertNotEqual(faded, plain.read(), "the fade changed nothing")

            # Cancelling from the progress callback keeps the frames written, and says how many.
            def stop_after_two(stage, fraction, message):
                return not (stage == "render" and fraction >= 0.5)

            summary = native.synthesize(bank, os.path.join(folder, "cancelled", "%06d.png"), (1, 4), flowlines=drawn,
                                        capture=clip, progress=stop_after_two)
            self.assertEqual(summary["frames_written"], 2)
            self.assertEqual(sorted(os.listdir(os.path.join(folder, "cancelled"))), ["000001.png", "000002.png"])
            # Before rendering starts, a cancel raises flowvid.Cancelled (a flowvid.Error).
            with self.assertRaises(flowvid.Cancelled):
                flowvid.flow.synthesize(bank, os.path.join(folder, "never", "%06d.png"), frames=(1, 2),
                                        flowlines=drawn, capture=clip, progress=lambda stage, f, m: False)


if __name__ == "__main__":
    unittest.main(verbosity=2)
