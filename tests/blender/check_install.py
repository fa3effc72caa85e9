"""cmake --install into a temporary prefix: the tool, the module, the add-on zip, the demo data and the docs
are where the top-level CMakeLists.txt says, and they work from there.

python3 tests/blender/check_install.py BUILD_DIR SOURCE_DIR VERSION
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile


def main():
    build, source, version = sys.argv[1:4]
    prefix = tempfile.mkdtemp(prefix="flowvid_prefix_")
    try:
        subprocess.run(["cmake", "--install", build, "--prefix", prefix], check=True, stdout=subprocess.DEVNULL)
        python_dir = os.path.join(prefix, "lib", "python%d.%d" % sys.version_info[:2], "dist-packages")
        share = os.path.join(prefix, "share", "flowvid")
        zip_path = os.path.join(share, "flowvid_blender-%s.zip" % version)
        expected = [os.path.join(prefix, "bin", "flowvid"), zip_path,
                    os.path.join(share, "data", "demo", "cotton-full-fit.fabric.json"),
                    os.path.join(share, "data", "demo", "cotton-static", "capture.json"),
                    os.path.join(share, "formats", "examples", "cotton.fabric.json"),
                    os.path.join(share, "scripts", "demo_blender.py"),
                    os.path.join(share, "blender_addon", "flowvid_blender", "__init__.py"),
                    os.path.join(prefix, "share", "doc", "flowvid", "README.md"),
                    os.path.join(prefix, "share", "doc", "flowvid", "guide", "blender.md")]
        missing = [path for path in expected if not os.path.isfile(path)]
        assert not missing, "not installed: %s" % missing
        # Every demo capture of the source tree, frame for frame.
        for folder, _dirs, files in os.walk(os.path.join(source, "data")):
            relative = os.path.relpath(folder, os.path.join(source, "data"))
            for name in files:
                assert os.path.isfile(os.path.join(share, "data", relative, name)), os.path.join(relative, name)

        tool = os.path.join(prefix, "bin", "flowvid")
        shown = subprocess.run([tool, "--version"], check=True, capture_output=True, text=True).stdout.strip()
        assert shown == "flowvid %s" % version, shown
        imported = subprocess.run([sys.executable, "-c", "import flowvid; print(flowvid.__file__, flowvid.__version__)"],
                                  check=True, capture_output=True, text=True, cwd=prefix,
                                  env=dict(os.environ, PYTHONPATH=python_dir)).stdout.split()
        assert imported == [os.path.join(python_dir, os.path.basename(imported[0])), version], imported
        with zipfile.ZipFile(zip_path) as archive:
            recorded = json.loads(archive.read("flowvid_blender/locations.json"))
            carried = [n for n in archive.namelist() if n.startswith("flowvid_blender/native/flowvid")]
        # The installed zip points at the installed tool and module, not at the build.
        assert recorded == {"tool": tool, "module_dir": python_dir}, recorded
        assert carried, "the installed zip should carry the module"
        # The installed demo finds the installed data by itself (no --data), and
        # reads it as it reads the source tree (its formats stage: every example).
        out = os.path.join(prefix, "demo")
        subprocess.run([tool, "--quiet", "demo", "--only", "formats", "--out", out], check=True,
                       stdout=subprocess.DEVNULL, cwd=prefix)
        with open(os.path.join(out, "formats", "summaries.json")) as handle:
            summaries = json.load(handle)
        examples = os.listdir(os.path.join(source, "formats", "examples"))
        assert len(summaries) == len(examples), (len(summaries), examples)
        read_from = json.dumps(summaries)
        assert os.path.join(share, "formats", "examples") in read_from and source not in read_from, read_from[:400]
        print("install: %d files under %s; %s; module %s from %s; %d examples summarised by the demo" % (
            sum(len(f) for _d, _s, f in os.walk(prefix)), prefix, shown, version, python_dir, len(summaries)))
    finally:
        shutil.rmtree(prefix, ignore_errors=True)


main()
