"""The module's pipelines are the library's entry points, which the flowvid tool
calls too: the same request gives the same result in process and through the
tool. Plain python3 with the module and the tool built (ctest gives both)."""
import json
import os
import subprocess
import tempfile
import unittest

import flowvid

SHARED = os.environ.get("FLOWVID_SHARED_DIR", "")
SILK_STATIC = os.path.join(SHARED, "captures", "cloth-silk-static-1")
TOSS = os.path.join(SHARED, "captures", "rigid-toss-major")
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TOSS_FIT = os.path.join(REPO, "formats", "examples", "toss.rigid_fit.json")


@unittest.skipUnless(os.environ.get("FLOWVID_CLI") and os.path.isdir(SILK_STATIC),
                     "needs the flowvid tool and ../shared/captures")
class PipelineTest(unittest.TestCase):
    def test_fit_in_process_gives_the_tools_fabric(self):
        with tempfile.TemporaryDirectory() as folder:
            tool_out = os.path.join(folder, "tool.fabric.json")
            completed = subprocess.run(
                [os.environ["FLOWVID_CLI"], "fit", "cloth", "--capture", SILK_STATIC, "--out", tool_out,
                 "--evaluations", "10", "--variability-runs", "0", "--resolution", "8x8", "--seed", "3", "--json"],
                capture_output=True, text=True)
            self.assertEqual(completed.returncode, 0, completed.stderr)
            tool = json.loads(completed.stdout)
            phases = []
            module_out = os.path.join(folder, "module.fabric.json")
            result = flowvid.cloth.fit([SILK_STATIC], out=module_out, evaluations=10, variability_runs=0, rows=8,
                                       cols=8, seed=3, progress=lambda phase, f, m: phases.append(phase))
            with open(tool_out) as handle:
                self.assertEqual(result["preset"]["parameters"], json.load(handle)["parameters"])
            self.assertEqual(flowvid.formats.read_fabric_preset(module_out)["parameters"],
                             result["preset"]["parameters"])
            self.assertEqual(result["final_error"], tool["final_error"])
            self.assertEqual(result["final_error_floor"], tool["final_error_floor"])
            self.assertIn("final", phases)
            self.assertLess(result["final_error"], result["start_error"])

    def test_diagnose_names_what_is_missing_and_can_be_cancelled(self):
        with self.assertRaises(flowvid.Error) as caught:
            flowvid.gap.diagnose([SILK_STATIC])
        self.assertIn("preset", str(caught.exception))
        with self.assertRaises(flowvid.Error) as caught:
            flowvid.gap.diagnose([SILK_STATIC], preset="x.fabric.json", effects=["gremlins"])
        self.assertIn("gremlins", str(caught.exception))
        preset = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                              "tests", "data", "cloth", "silk.fabric.json")
        with self.assertRaises(flowvid.Cancelled):
            flowvid.gap.diagnose([SILK_STATIC], preset=preset, frames=4, progress=lambda stage, f, m: False)


    def test_predict_in_process_gives_the_tools_masks_and_agreement(self):
        with tempfile.TemporaryDirectory() as folder:
            completed = subprocess.run(
                [os.environ["FLOWVID_CLI"], "predict", "rigid", "--fit", TOSS_FIT, "--capture", TOSS, "--out",
                 os.path.join(folder, "tool"), "--frames", "3:8", "--json"], capture_output=True, text=True)
            self.assertEqual(completed.returncode, 0, completed.stderr)
            tool = json.loads(completed.stdout)
            result = flowvid.rigid.predict(TOSS_FIT, TOSS, frames=(3, 8), masks=os.path.join(folder, "module"))
            self.assertEqual([f["frame"] for f in result["frames"]], list(range(3, 9)))
            self.assertEqual(result["iou_pooled"], tool["iou_pooled"])
            self.assertEqual([f["iou"] for f in result["frames"]], [f["iou"] for f in tool["per_frame"]])
            self.assertGreater(result["iou_min"], 0.5)  # the example fit is of this toss
            for frame in range(3, 9):
                name = "%06d.png" % frame
                with open(os.path.join(folder, "tool", name), "rb") as a, \
                        open(os.path.join(folder, "module", name), "rb") as b:
                    self.assertEqual(a.read(), b.read(), name)
            with self.assertRaises(flowvid.Error) as caught:
                flowvid.rigid.predict(TOSS_FIT, TOSS, frames=(3, 10000))
            self.assertIn("frames", str(caught.exception))

if __name__ == "__main__":
    unittest.main(verbosity=2)
