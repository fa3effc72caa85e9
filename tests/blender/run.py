"""Headless Blender test runner.

blender -b --factory-startup -noaudio --python-exit-code 1 --python tests/blender/run.py -- TEST...
Each TEST is a function test_<name> in tests/blender/test_*.py modules; an
exception makes Blender exit with code 1.
"""
import importlib.util
import os
import sys
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))


def _load_tests():
    tests = {}
    for name in sorted(os.listdir(HERE)):
        if name.startswith("test_") and name.endswith(".py"):
            spec = importlib.util.spec_from_file_location(name[:-3], os.path.join(HERE, name))
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            for attr in dir(module):
                if attr.startswith("test_"):
                    tests[attr[len("test_"):]] = getattr(module, attr)
    return tests


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    tests = _load_tests()
    selected = argv or sorted(tests)
    failed = 0
    for name in selected:
        if name not in tests:
            print("blender test: no test named %r (have: %s)" % (name, ", ".join(sorted(tests))))
            failed += 1
            continue
        try:
            tests[name]()
            print("blender test %s: passed" % name)
        except Exception:
            traceback.print_exc()
            print("blender test %s: FAILED" % name)
            failed += 1
    if failed:
        raise SystemExit(1)


main()
