"""How the add-on reaches the flowvid library: one backend (core/backend.py),
found once per session from the add-on's preferences, the environment, what
the zip carries and the layouts around it (core/locate.py). Raises FlowvidError."""
import sys

from .core import locate
from .core.backend import CliBackend, NativeBackend
from .core.errors import FlowvidError

# The add-on's own package: "flowvid_blender" installed as an add-on, "bl_ext.<repository>.flowvid_blender" as
# a Blender 4.2+ extension; its preferences are registered under this name.
ADDON_PACKAGE = __package__

_BACKEND = None


def preferences():
    """The add-on's preferences, or None (scripts that import the add-on without enabling it)."""
    try:
        import bpy
    except ImportError:
        return None
    addon = bpy.context.preferences.addons.get(ADDON_PACKAGE)
    return addon.preferences if addon is not None else None


def _preferred():
    prefs = preferences()
    return (prefs.module_dir, prefs.tool_path) if prefs is not None else ("", "")


def find_tool():
    """The flowvid tool's real path, or None."""
    module = sys.modules.get("flowvid")
    found = locate.tool_paths(_preferred()[1], getattr(module, "__file__", None))
    return found[0] if found else None


def discover():
    """What can be found now: {"backend": "native"|"cli"|None, "module", "module_version", "module_errors",
    "tool", "tool_version", "python"}. Imports the module when one matches this Python."""
    module_dir, _tool = _preferred()
    module, module_path, errors = locate.import_module(locate.module_dirs(module_dir))
    tool = find_tool()
    return {
        "backend": "native" if module is not None else ("cli" if tool else None),
        "module": module_path,
        "module_version": getattr(module, "__version__", None),
        "module_errors": errors,
        "tool": tool,
        "tool_version": locate.tool_version(tool) if tool else None,
        "python": "%d.%d.%d" % sys.version_info[:3],
    }


def reset():
    """Forget the backend (the preferences changed); a module already imported stays (Python cannot unload it)."""
    global _BACKEND
    _BACKEND = None


def get_backend():
    """The flowvid library (native module, else CLI); cached."""
    global _BACKEND
    if _BACKEND is None:
        module_dir, _tool = _preferred()
        module, _path, errors = locate.import_module(locate.module_dirs(module_dir))
        if module is not None:
            _BACKEND = NativeBackend(module)
        else:
            tool = find_tool()
            if not tool:
                raise FlowvidError(
                    "flowvid is not available: neither the native module (for Python %d.%d) nor the flowvid tool was "
                    "found%s. Set their paths in Edit > Preferences > Add-ons > flowvid (Test shows what is found), or "
                    "install flowvid (cmake --install) so that `flowvid` is on the PATH"
                    % (sys.version_info[0], sys.version_info[1], "; " + "; ".join(errors) if errors else ""))
            _BACKEND = CliBackend(tool)
    return _BACKEND
