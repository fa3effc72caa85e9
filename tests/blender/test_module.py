"""The pybind11 module loads inside Blender's own Python."""
import os
import sys


def test_module_imports():
    import bpy  # noqa: F401  (proves we run inside Blender)

    sys.path.insert(0, os.environ["FLOWVID_PYTHON_DIR"])
    import flowvid

    assert sys.version_info[:2] == (3, 11), sys.version
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    preset = flowvid.formats.read_fabric_preset(os.path.join(repo, "formats", "examples", "cotton.fabric.json"))
    assert abs(preset["parameters"]["areal_density_kg_per_m2"]["value"] - 0.15) < 1e-12
    print("flowvid", flowvid.__version__, "imported in Blender", bpy.app.version_string)
