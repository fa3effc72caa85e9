"""Where the flowvid library is, from wherever the add-on was installed (no bpy).

The native module is looked for in: the folder set in the add-on's
preferences, $FLOWVID_PYTHON_DIR, the zip's own `native/` folder, the folder
the build recorded in `locations.json`, then install and checkout layouts
around the add-on. The tool likewise, then beside the module found and on the
PATH. Every path is a real path: an add-on folder linked into Blender's
scripts leads back to the checkout or prefix it lives in.
"""
import glob
import importlib.machinery
import importlib.util
import json
import os
import shutil
import subprocess
import sys

ADDON_DIR = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
NATIVE_DIR = "native"                # in the zip: the module built with the add-on
LOCATIONS_FILE = "locations.json"    # in the zip: {"tool": ..., "module_dir": ...} as the build knew them
PYTHON_DIR = os.path.join("lib", "python%d.%d" % sys.version_info[:2], "dist-packages")  # cmake --install's


def recorded_locations(addon_dir=ADDON_DIR):
    """The locations the build wrote into the zip ({} when there are none or the file is unreadable)."""
    try:
        with open(os.path.join(addon_dir, LOCATIONS_FILE), encoding="utf-8") as handle:
            recorded = json.load(handle)
    except (OSError, ValueError):
        return {}
    return recorded if isinstance(recorded, dict) else {}


def _roots(addon_dir):
    # A checkout (ROOT/blender_addon/flowvid_blender) or an install prefix
    # (ROOT/share/flowvid/blender_addon/flowvid_blender): the parents up to four levels.
    roots, folder = [], addon_dir
    for _ in range(4):
        folder = os.path.dirname(folder)
        roots.append(folder)
    return roots


def _newest(pattern):
    found = sorted(glob.glob(pattern), key=os.path.getmtime)
    return found[-1] if found else None


def _unique_real(paths, keep):
    seen, result = set(), []
    for path in paths:
        if not path:
            continue
        real = os.path.realpath(os.path.expanduser(path))
        if real not in seen and keep(real):
            seen.add(real)
            result.append(real)
    return result


def module_dirs(preferred="", addon_dir=ADDON_DIR):
    """Folders that may hold the native module, best first (existing ones only)."""
    candidates = [preferred] + os.environ.get("FLOWVID_PYTHON_DIR", "").split(os.pathsep)
    candidates += [os.path.join(addon_dir, NATIVE_DIR), recorded_locations(addon_dir).get("module_dir")]
    for root in _roots(addon_dir):
        candidates.append(os.path.join(root, PYTHON_DIR))
        built = _newest(os.path.join(root, "build*", "python", "flowvid*"))
        candidates.append(os.path.dirname(built) if built else None)
    return _unique_real(candidates, os.path.isdir)


def module_file(folder):
    """The module file in `folder` built for this Python (its ABI suffix), else None."""
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = os.path.join(folder, "flowvid" + suffix)
        if os.path.isfile(path):
            return path
    return None


def import_module(folders):
    """The native module from the first folder whose file imports here: (module, path, errors).
    Loaded by file, not through sys.path, so no other folder's `flowvid` can take its place."""
    loaded = sys.modules.get("flowvid")
    if loaded is not None:
        return loaded, getattr(loaded, "__file__", None), []
    errors = []
    for folder in folders:
        path = module_file(folder)
        if path is None:
            continue
        try:
            spec = importlib.util.spec_from_file_location("flowvid", path)
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
        except ImportError as error:  # e.g. a library it links is missing on this machine
            errors.append("%s: %s" % (path, error))
            continue
        sys.modules["flowvid"] = module
        return module, path, errors
    return None, None, errors


def _executable(path):
    return os.path.isfile(path) and os.access(path, os.X_OK)


def tool_paths(preferred="", module_path=None, addon_dir=ADDON_DIR):
    """Executables that may be the flowvid tool, best first (existing, executable ones only)."""
    candidates = [preferred, os.environ.get("FLOWVID_CLI"), recorded_locations(addon_dir).get("tool")]
    if module_path:
        # Beside the module: build/python -> build/cli, PREFIX/lib/pythonX.Y/dist-packages -> PREFIX/bin.
        folder = os.path.dirname(os.path.realpath(module_path))
        candidates += [os.path.join(os.path.dirname(folder), "cli", "flowvid"),
                       os.path.join(folder, os.pardir, os.pardir, os.pardir, "bin", "flowvid")]
    for root in _roots(addon_dir):
        candidates += [os.path.join(root, "bin", "flowvid"), _newest(os.path.join(root, "build*", "cli", "flowvid"))]
    candidates.append(shutil.which("flowvid"))
    return _unique_real(candidates, _executable)


def tool_version(executable):
    """`flowvid --version`'s line, or why it could not be had."""
    try:
        done = subprocess.run([executable, "--version"], capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError) as error:
        return "does not run: %s" % error
    text = (done.stdout or done.stderr).strip().splitlines()
    return text[0] if done.returncode == 0 and text else "exited with %d" % done.returncode
