#!/usr/bin/env python3
"""Fuzzing the Python module's entry points (issue #34): every corpus file, every
regression input and structure-aware mutations of the corpus (made by
flowvid_fuzz_replay with fuzz/structure_mutator.cpp, the mutator the libFuzzer
targets use) go to each function of the `flowvid` module that reads a file
(formats.read_fabric_preset, formats.validate_fabric_preset,
flow.read_flowline_set, flow.validate_flowline_set) and, parsed by Python's
json module, to the functions that take a document (formats.write_fabric_preset,
flow.write_flowline_set), plus odd paths (missing, a folder, NUL bytes, very
long names).

Passing means: every call returns, or raises flowvid.Error, flowvid.IoError or
flowvid.ValidationError exactly (RuntimeError, KeyError, ... escaping is a bug),
and no call crashes the interpreter, hangs (10 s) or runs out of memory (4 GiB).
Calls run in a worker process; when it dies, the case it was running is
reported and the worker restarts after it. Standard library only.

  python_replay.py --replay PATH/flowvid_fuzz_replay --corpus fuzz/corpus
                   --regressions fuzz/regressions --mutations N --scratch DIR
"""

import argparse
import json
import os
import shutil
import subprocess
import sys

CASE_SECONDS = 10
ADDRESS_SPACE = 4 << 30

# Which corpus folders feed which functions (every file also goes to every
# reader once: a file of another kind must be refused with flowvid's error).
PATH_FUNCTIONS = ["formats.read_fabric_preset", "formats.validate_fabric_preset", "flow.read_flowline_set",
                  "flow.validate_flowline_set"]
DOCUMENT_FUNCTIONS = {"fabric_json": "formats.write_fabric_preset", "flowlines_json": "flow.write_flowline_set"}
MUTATED_TARGETS = ["fabric_json", "flowlines_json", "flowlines_svg"]


def make_cases(args):
    """(function, kind, path) for every call: kind 'path' passes the path, 'document' the parsed JSON."""
    files = []
    for root in (args.corpus, args.regressions):
        for target in sorted(os.listdir(root)):
            folder = os.path.join(root, target)
            if os.path.isdir(folder):
                files += [(target, os.path.join(folder, name)) for name in sorted(os.listdir(folder))]
    mutations = os.path.join(args.scratch, "mutations")
    shutil.rmtree(mutations, ignore_errors=True)
    for target in MUTATED_TARGETS:
        folder = os.path.join(mutations, target)
        subprocess.run([args.replay, "mutate", args.corpus, target, str(args.mutations), folder], check=True)
        files += [(target, os.path.join(folder, name)) for name in sorted(os.listdir(folder))]
    cases = []
    for target, path in files:
        for function in PATH_FUNCTIONS:
            cases.append((function, "path", path))
        if target in DOCUMENT_FUNCTIONS:
            cases.append((DOCUMENT_FUNCTIONS[target], "document", path))
    odd = os.path.join(args.scratch, "odd")
    os.makedirs(odd, exist_ok=True)
    for path in ["", "/", odd, os.path.join(odd, "missing.fabric.json"), "/dev/null", "/dev/zero/x", "a\0b.svg",
                 "x" * 5000 + ".flowlines.json", "/proc/self/mem", "../../etc/passwd"]:
        for function in PATH_FUNCTIONS:
            cases.append((function, "odd-path", path))
    return cases


# ---- Worker -------------------------------------------------------------------

def worker(case_file, progress_file, start, scratch):
    import faulthandler
    import resource

    faulthandler.enable()
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY or soft > ADDRESS_SPACE:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, hard))
    import flowvid

    allowed = (flowvid.Error, flowvid.IoError, flowvid.ValidationError)
    cases = json.load(open(case_file))
    out_path = os.path.join(scratch, "written")
    progress = open(progress_file, "w")
    failures = 0
    for index in range(start, len(cases)):
        function, kind, path = cases[index]
        progress.write(f"{index}\n")
        progress.flush()
        module, name = function.split(".")
        call = getattr(getattr(flowvid, module), name)
        faulthandler.dump_traceback_later(CASE_SECONDS, exit=True)
        try:
            if kind == "document":
                try:
                    with open(path, "rb") as f:
                        document = json.loads(f.read().decode("utf-8", "replace"))
                except (ValueError, RecursionError):
                    continue  # Python's own parser refused it: nothing to hand over
                suffix = ".fabric.json" if "fabric" in name else ".flowlines.json"
                call(out_path + suffix, document)
            else:
                call(path)
        except BaseException as error:  # noqa: B902 - anything but flowvid's own is the bug looked for
            if type(error) in allowed:
                continue
            what = (f"MemoryError (over {ADDRESS_SPACE >> 30} GiB)" if isinstance(error, MemoryError) else
                    f"{type(error).__module__}.{type(error).__name__} escaped: {str(error)[:300]}")
            print(f"FUZZ FAILURE: {what} in {function}({kind} {path})", flush=True)
            failures += 1
        finally:
            faulthandler.cancel_dump_traceback_later()
    progress.write("done\n")
    progress.flush()
    sys.exit(1 if failures else 0)


# ---- Parent -------------------------------------------------------------------

def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--replay", help="flowvid_fuzz_replay (makes the mutations)")
    parser.add_argument("--corpus")
    parser.add_argument("--regressions")
    parser.add_argument("--mutations", type=int, default=150)
    parser.add_argument("--scratch", required=True)
    parser.add_argument("--worker", nargs=2, metavar=("CASES", "START"))
    args = parser.parse_args()
    os.makedirs(args.scratch, exist_ok=True)
    case_file = os.path.join(args.scratch, "cases.json")
    progress_file = os.path.join(args.scratch, "progress.txt")
    if args.worker:
        worker(args.worker[0], progress_file, int(args.worker[1]), args.scratch)
        return 0

    try:
        import flowvid  # noqa: F401 - fail early and clearly when the module is missing
    except ImportError as error:
        print(f"python_replay: cannot import flowvid ({error}); set PYTHONPATH to the build's python folder")
        return 1
    cases = make_cases(args)
    json.dump(cases, open(case_file, "w"))
    failures = 0
    start = 0
    while start < len(cases):
        if os.path.exists(progress_file):
            os.remove(progress_file)
        result = subprocess.run([sys.executable, __file__, "--scratch", args.scratch, "--worker", case_file, str(start)],
                                capture_output=True, text=True)
        sys.stdout.write(result.stdout)
        lines = open(progress_file).read().split() if os.path.exists(progress_file) else []
        if lines and lines[-1] == "done":
            if result.returncode != 0:
                failures += result.stdout.count("FUZZ FAILURE")
            break
        # The worker died during a case: say which, then go on after it.
        failures += result.stdout.count("FUZZ FAILURE")
        index = int(lines[-1]) if lines else start
        function, kind, path = cases[index]
        if "Timeout" in result.stderr:
            how = f"timeout (over {CASE_SECONDS} s)"
        elif result.returncode < 0:
            how = f"crash (signal {-result.returncode})"
        else:
            how = f"worker exit status {result.returncode}"
        print(f"FUZZ FAILURE: {how} in {function}({kind} {path})")
        print("  " + "\n  ".join(result.stderr.strip().splitlines()[-12:]))
        failures += 1
        start = index + 1
    print(f"python entry points: {len(cases)} calls, {failures} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
