"""The add-on as a user installs it: the zip the build makes (FLOWVID_TEST_ADDON_ZIP), its 4.2+ extension
manifest, and the zip installed into a clean Blender user folder, then used with no FLOWVID_* variable."""
import ast
import json
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
ADDON = "flowvid_blender"


def _zip_path():
    path = os.environ.get("FLOWVID_TEST_ADDON_ZIP", "")
    assert os.path.isfile(path), "FLOWVID_TEST_ADDON_ZIP should name the zip `ninja flowvid_addon_zip` builds: %r" % path
    return path


def _terse(text):
    # The extension manifest's one-liners: at most 64 characters, trimmed, not ending in punctuation.
    return 0 < len(text) <= 64 and text == text.strip() and (text[-1].isalnum() or text[-1] in ")]}")


def test_addon_zip_manifest():
    """One top folder holding bl_info's __init__.py (Blender < 4.2) and a blender_manifest.toml whose fields
    follow the 4.2 extension schema 1.0.0, with the same version as bl_info."""
    with zipfile.ZipFile(_zip_path()) as archive:
        names = archive.namelist()
        manifest = tomllib.loads(archive.read(ADDON + "/blender_manifest.toml").decode("utf-8"))
        init = archive.read(ADDON + "/__init__.py").decode("utf-8")
    assert {name.split("/")[0] for name in names} == {ADDON}, sorted({n.split("/")[0] for n in names})
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    bl_info = [ast.literal_eval(node.value) for node in ast.parse(init).body
               if isinstance(node, ast.Assign) and [t.id for t in node.targets] == ["bl_info"]][0]
    required = {"schema_version", "id", "version", "name", "tagline", "maintainer", "type", "blender_version_min",
                "license"}
    assert required <= set(manifest), required - set(manifest)
    assert manifest["schema_version"] == "1.0.0"
    assert manifest["id"] == ADDON and manifest["type"] == "add-on"
    assert manifest["version"] == ".".join(str(n) for n in bl_info["version"]), (manifest["version"], bl_info)
    assert _terse(manifest["tagline"]), manifest["tagline"]
    numbers = manifest["blender_version_min"].split(".")
    assert len(numbers) == 3 and all(n.isdigit() for n in numbers) and tuple(map(int, numbers)) >= (4, 2, 0)
    assert manifest["license"] and all(entry.startswith("SPDX:") for entry in manifest["license"])
    assert isinstance(manifest["permissions"], dict) and set(manifest["permissions"]) <= {
        "files", "network", "clipboard", "camera", "microphone"}
    assert all(_terse(reason) for reason in manifest["permissions"].values()), manifest["permissions"]
    assert tuple(bl_info["blender"]) < (4, 2, 0), "bl_info serves the Blender versions before extensions"
    native = [n for n in names if n.startswith(ADDON + "/native/flowvid")]
    print("zip: %d files, manifest %s %s, native module %s" % (len(names), manifest["id"], manifest["version"],
                                                                native or "none"))


def _blender(arguments, env, log):
    with open(log, "w") as out:
        done = subprocess.run([bpy.app.binary_path, "-b", "-noaudio", "--python-exit-code", "1", *arguments],
                              env=env, stdout=out, stderr=subprocess.STDOUT, timeout=240)
    with open(log) as handle:
        text = handle.read()
    assert done.returncode == 0, "Blender exited with %d:\n%s" % (done.returncode, text[-4000:])
    return text


def test_addon_zip_installs():
    """Install the zip with addon_install into an empty user folder and enable it (saving the preferences), then
    in a new Blender session that only has those preferences: Test finds the module the zip carries, Apply sets
    the cloth the formulas give for a preset, Bake writes the particles' projections (addon_session.py)."""
    zip_path = _zip_path()
    home = tempfile.mkdtemp(prefix="flowvid_user_")
    try:
        env = {k: v for k, v in os.environ.items() if not k.startswith(("FLOWVID_", "PYTHON"))}
        env.update(HOME=home, BLENDER_USER_CONFIG=os.path.join(home, "config"),
                   BLENDER_USER_SCRIPTS=os.path.join(home, "scripts"),
                   BLENDER_USER_DATAFILES=os.path.join(home, "datafiles"))
        install = ("import bpy\n"
                   "assert bpy.ops.preferences.addon_install(filepath=%r) == {'FINISHED'}\n"
                   "assert bpy.ops.preferences.addon_enable(module=%r) == {'FINISHED'}\n"
                   "assert bpy.ops.wm.save_userpref() == {'FINISHED'}\n" % (zip_path, ADDON))
        _blender(["--factory-startup", "--python-expr", install], env, os.path.join(home, "install.log"))
        installed = os.path.join(home, "scripts", "addons", ADDON)
        assert os.path.isfile(os.path.join(installed, "blender_manifest.toml")), os.listdir(home)
        assert os.path.isfile(os.path.join(home, "config", "userpref.blend"))

        text = _blender(["--python", os.path.join(HERE, "addon_session.py"), "--", home], env,
                        os.path.join(home, "session.log"))
        summary = json.loads([line for line in text.splitlines() if line.startswith("{")][-1])
        print("installed add-on: backend %s (module %s, tool %s); %d cloth settings equal the formulas; %d lines, "
              "%d points within %.1e px" % (summary["found"]["backend"], summary["found"]["module"],
                                            summary["found"]["tool"], len(summary["cloth"]),
                                            summary["baked"]["lines"], summary["baked"]["points_checked"],
                                            summary["baked"]["worst_px"]))
    finally:
        shutil.rmtree(home, ignore_errors=True)
    sys.stdout.flush()


def test_linked_addon_finds_its_build():
    """The add-on folder linked into a clean user folder (the guide's old way, which failed without
    FLOWVID_PYTHON_DIR): enabled with no FLOWVID_* variable, it finds the module and tool of the checkout the
    link points into, by real path."""
    source = os.path.join(os.path.dirname(os.path.dirname(HERE)), "blender_addon", ADDON)
    home = tempfile.mkdtemp(prefix="flowvid_user_")
    try:
        env = {k: v for k, v in os.environ.items() if not k.startswith(("FLOWVID_", "PYTHON"))}
        env.update(HOME=home, BLENDER_USER_CONFIG=os.path.join(home, "config"),
                   BLENDER_USER_SCRIPTS=os.path.join(home, "scripts"))
        os.makedirs(os.path.join(home, "scripts", "addons"))
        os.symlink(source, os.path.join(home, "scripts", "addons", ADDON))
        script = ("import bpy, json, sys\n"
                  "assert bpy.ops.preferences.addon_enable(module=%r) == {'FINISHED'}\n"
                  "print(json.dumps(sys.modules[%r].discover()))\n" % (ADDON, ADDON + ".library"))
        text = _blender(["--factory-startup", "--python-expr", script], env, os.path.join(home, "linked.log"))
        found = json.loads([line for line in text.splitlines() if line.startswith("{")][-1])
        # A module of the checkout's build folders (build*/python), reached without the ctest environment's.
        folder = os.path.dirname(found["module"] or "")
        checkout = os.path.realpath(os.path.dirname(os.path.dirname(HERE)))
        assert found["backend"] == "native" and os.path.basename(folder) == "python", found
        assert os.path.basename(os.path.dirname(folder)).startswith("build"), found
        assert os.path.dirname(os.path.dirname(folder)) == checkout, found
        assert found["tool"] and found["tool_version"].startswith("flowvid "), found
        print("linked add-on: module %s, tool %s" % (found["module"], found["tool"]))
    finally:
        shutil.rmtree(home, ignore_errors=True)
