"""The flowvid Python module imports in the interpreter Blender uses and reads
and writes fabric presets with the same validation as the C++ library."""
import json
import os
import sys
import tempfile
import unittest

import flowvid

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXAMPLE = os.path.join(REPO, "formats", "examples", "cotton.fabric.json")
DRAWING = os.path.join(REPO, "data", "demo", "waterfall", "flowlines.svg")


class ModuleTest(unittest.TestCase):
    def test_built_for_this_interpreter(self):
        self.assertRegex(flowvid.__version__, r"^\d+\.\d+\.\d+$")
        abi = "cpython-%d%d" % sys.version_info[:2]
        self.assertIn(abi, os.path.basename(flowvid.__file__))

    def test_preset_round_trip(self):
        preset = flowvid.formats.read_fabric_preset(EXAMPLE)
        self.assertEqual(preset["format"], "flowvid.fabric")
        self.assertAlmostEqual(preset["parameters"]["areal_density_kg_per_m2"]["value"], 0.15)
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "copy.fabric.json")
            flowvid.formats.write_fabric_preset(path, preset)
            self.assertEqual(flowvid.formats.read_fabric_preset(path), preset)

    def test_invalid_preset_raises_with_field(self):
        with open(EXAMPLE) as handle:
            preset = json.load(handle)
        preset["parameters"]["bend_stiffness_N_m"]["value"] = -2.0
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "bad.fabric.json")
            with self.assertRaises(flowvid.ValidationError) as caught:
                flowvid.formats.write_fabric_preset(path, preset)
            self.assertIn("/parameters/bend_stiffness_N_m/value", str(caught.exception))
            self.assertFalse(os.path.exists(path))
            with open(path, "w") as handle:
                json.dump(preset, handle)
            messages = flowvid.formats.validate_fabric_preset(path)
            self.assertTrue(any("/parameters/bend_stiffness_N_m/value" in m for m in messages), messages)

    def test_flow_lines_from_a_drawing_or_json(self):
        # An artist's SVG reads as the same set as the JSON written from it.
        drawn = flowvid.flow.read_flowline_set(DRAWING)
        self.assertGreaterEqual(len(drawn["inputs"]), 2)
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "drawn.flowlines.json")
            flowvid.flow.write_flowline_set(path, drawn)
            self.assertEqual(flowvid.flow.read_flowline_set(path), drawn)


if __name__ == "__main__":
    unittest.main(verbosity=2)
