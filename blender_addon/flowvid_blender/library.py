"""How the add-on reaches the flowvid library: one backend (core/backend.py),
found once per session, from a development checkout's build folders when the
environment names none. Raises FlowvidError."""
import os

from .core import backend as backend_module
from .core.backend import BackendError
from .core.errors import FlowvidError


_BACKEND = None


def _checkout_build(pattern):
    """In a development checkout: the most recently built file matching build*/PATTERN, else None."""
    import glob

    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    built = sorted(glob.glob(os.path.join(repo, "build*", pattern)), key=os.path.getmtime)
    return built[-1] if built else None


def get_backend():
    """The flowvid library (native module, else CLI); cached."""
    global _BACKEND
    if _BACKEND is None:
        candidates = []
        if not os.environ.get("FLOWVID_PYTHON_DIR"):
            module = _checkout_build(os.path.join("python", "flowvid*.so"))
            candidates = [os.path.dirname(module)] if module else []
        try:
            _BACKEND = backend_module.find_backend(module_paths=candidates, executable=_checkout_tool())
        except BackendError as error:
            raise FlowvidError(str(error)) from None
    return _BACKEND


def _checkout_tool():
    return None if backend_module.find_tool() else _checkout_build(os.path.join("cli", "flowvid"))
