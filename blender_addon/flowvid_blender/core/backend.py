"""How the add-on reaches the flowvid library.

Preferred: the native pybind11 module `flowvid`, when one built for this
Python's ABI is importable (Debian's Blender uses /usr/bin/python3, which the
build targets). Otherwise (e.g. an official Blender build with its own bundled
Python) the `flowvid` command-line tool is run with `--progress=json`.
"""
import json
import os
import shutil
import subprocess
import sys


class BackendError(RuntimeError):
    """A flowvid failure, with the message the library or tool gave."""


def _import_native(extra_paths=()):
    for path in extra_paths:
        if path and path not in sys.path:
            sys.path.insert(0, path)
    try:
        import flowvid  # noqa: F401
    except ImportError:
        return None
    return flowvid


class NativeBackend:
    name = "native"

    def __init__(self, module):
        self.module = module

    def read_fabric_preset(self, path):
        try:
            return self.module.formats.read_fabric_preset(path)
        except self.module.Error as error:
            raise BackendError(str(error)) from None


class CliBackend:
    name = "cli"

    def __init__(self, executable):
        self.executable = executable

    def run(self, *arguments):
        completed = subprocess.run([self.executable, "--progress=json", *arguments], capture_output=True, text=True)
        if completed.returncode != 0:
            raise BackendError(completed.stderr.strip() or "flowvid exited with %d" % completed.returncode)
        return completed.stdout

    def read_fabric_preset(self, path):
        # `validate` first so errors name the field; then the file itself is plain JSON.
        self.run("validate", "--lenient", path)
        with open(path, encoding="utf-8") as handle:
            return json.load(handle)


def find_backend(module_paths=(), executable=None):
    """The best available backend: native module, else the CLI. Raises BackendError if neither exists."""
    module_paths = list(module_paths) + [p for p in os.environ.get("FLOWVID_PYTHON_DIR", "").split(os.pathsep) if p]
    module = _import_native(module_paths)
    if module is not None:
        return NativeBackend(module)
    executable = executable or os.environ.get("FLOWVID_CLI") or shutil.which("flowvid")
    if executable:
        return CliBackend(executable)
    raise BackendError(
        "flowvid is not available: build it (bash scripts/bootstrap.sh) and set FLOWVID_PYTHON_DIR to build/python "
        "or FLOWVID_CLI to build/cli/flowvid"
    )
