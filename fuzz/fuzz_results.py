#!/usr/bin/env python3
"""Summarises a scripts/fuzz.sh run: parses each target's libFuzzer log, its
regression replay and the inputs it saved, updates the per-target records in
results.json (a target not run this time keeps its previous record) and
writes RESULTS.md from them. Standard library only."""

import argparse
import datetime
import json
import os
import re
import subprocess
import sys

CLEAN_SECONDS = 600  # issue #34: a clean run of at least 10 minutes per target

INITED = re.compile(r"#(\d+)\s+INITED\s+(?:exec/s: \d+ )?cov: (\d+) ft: (\d+) corp: (\d+)/")
STATUS = re.compile(r"#(\d+)\s+(?:NEW|REDUCE|pulse|DONE|RELOAD)\s+cov: (\d+) ft: (\d+) corp: (\d+)/")
FORK_STATUS = re.compile(r"#(\d+): cov: (\d+) ft: (\d+) corp: (\d+) exec/s:? (\d+) oom/timeout/crash: (\d+)/(\d+)/(\d+) time: (\d+)s")
DONE = re.compile(r"Done (\d+) runs in (\d+) second")
STAT = re.compile(r"stat::(\w+):\s+(\d+)")
WRITTEN = re.compile(r"Test unit written to (\S+)")
FRAME = re.compile(r"#\d+ 0x[0-9a-f]+ in (.+?) (/\S+?/(formats|libflowvid)/\S+?:\d+)")
KINDS = ("crash", "leak", "timeout", "oom")


def git(*args):
    try:
        return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def clang_version():
    try:
        out = subprocess.run(["clang++", "--version"], capture_output=True, text=True).stdout
        match = re.search(r"clang version (\S+)", out)
        return match.group(1) if match else "?"
    except OSError:
        return "?"


def relative(path):
    """Paths inside the checkout as the checkout names them."""
    path = os.path.abspath(path)
    return os.path.relpath(path) if path.startswith(os.getcwd() + os.sep) else path


def describe_problem(text):
    """What went wrong and where in the readers, from one crash's log text."""
    what = ""
    for pattern in (r"ERROR: AddressSanitizer: ([\w-]+)", r"ERROR: LeakSanitizer: (detected memory leaks)",
                    r"runtime error: (.{0,160})", r"ERROR: libFuzzer: (out-of-memory \((?:malloc\(\d+\)|[^)]*)\))",
                    r"ERROR: libFuzzer: (timeout after \d+ seconds)", r"ERROR: libFuzzer: ([\w -]+)"):
        match = re.search(pattern, text)
        if match:
            what = match.group(1).strip()
            break
    thrown = re.search(r"terminate called after throwing an instance of '([^']+)'\s*(?:what\(\):\s*(.{0,160}))?", text)
    if thrown:
        what = "uncaught " + thrown.group(1) + (": " + thrown.group(2).strip() if thrown.group(2) else "")
    where = ""
    for frame in FRAME.finditer(text):
        function, location = frame.group(1), frame.group(2)
        location = location[location.rfind("/" + frame.group(3) + "/") + 1:]
        function = function.replace("(anonymous namespace)::", "")
        where = f"{location} in {function.split('(')[0][:120]}"
        break
    return what or "unknown", where


def parse_target(run_dir, crashes_dir, target):
    log_path = os.path.join(run_dir, "fuzz.log")
    text = open(log_path, errors="replace").read() if os.path.exists(log_path) else ""
    record = {"log": relative(log_path)}
    inited = INITED.search(text)
    statuses = STATUS.findall(text)
    forks = FORK_STATUS.findall(text)
    if inited:
        record.update(cov_start=int(inited.group(2)), ft_start=int(inited.group(3)), corpus_start=int(inited.group(4)))
    if forks:
        first, last = forks[0], forks[-1]
        record.setdefault("cov_start", int(first[1]))
        record.setdefault("ft_start", int(first[2]))
        record.setdefault("corpus_start", int(first[3]))
        record.update(executions=int(last[0]), cov_end=int(last[1]), ft_end=int(last[2]), corpus_end=int(last[3]),
                      seconds=int(last[8]))
    elif statuses:
        last = statuses[-1]
        record.update(executions=int(last[0]), cov_end=int(last[1]), ft_end=int(last[2]), corpus_end=int(last[3]))
    done = DONE.search(text)
    if done:
        record.update(executions=int(done.group(1)), seconds=int(done.group(2)))
    stats = dict(STAT.findall(text))
    if "number_of_executed_units" in stats:
        record["executions"] = int(stats["number_of_executed_units"])
    if "new_units_added" in stats:
        record["new_units"] = int(stats["new_units_added"])
    if "peak_rss_mb" in stats:
        record["peak_rss_mb"] = int(stats["peak_rss_mb"])
    wall = os.path.join(run_dir, "wall_seconds")
    if os.path.exists(wall):
        record["wall_seconds"] = int(open(wall).read().strip() or 0)
        record.setdefault("seconds", record["wall_seconds"])
    status_file = os.path.join(run_dir, "exit_status")
    record["exit_status"] = int(open(status_file).read().strip()) if os.path.exists(status_file) else None
    if record.get("seconds"):
        record["exec_per_s"] = round(record.get("executions", 0) / max(record["seconds"], 1))
    if "new_units" not in record and "corpus_end" in record and "corpus_start" in record:
        record["new_units"] = max(record["corpus_end"] - record["corpus_start"], 0)

    # The inputs it saved, each with the problem its log reports.
    artifacts = []
    pieces = WRITTEN.split(text)  # text, path, text, path, ...
    described = {}
    for i in range(1, len(pieces), 2):
        described[os.path.basename(pieces[i])] = describe_problem(pieces[i - 1])
    target_crashes = os.path.join(crashes_dir, target)
    for name in sorted(os.listdir(target_crashes)) if os.path.isdir(target_crashes) else []:
        kind = name.split("-")[0]
        if kind not in KINDS or name.endswith(".log"):
            continue
        what, where = described.get(name, ("", ""))
        replay_log = os.path.join(target_crashes, name + ".log")
        if os.path.exists(replay_log):  # scripts/fuzz.sh replays each saved input alone
            what, where = describe_problem(open(replay_log, errors="replace").read())
        artifacts.append({"file": relative(os.path.join(target_crashes, name)), "kind": kind, "what": what, "where": where})
    for kind, key in zip(KINDS, ("crashes", "leaks", "timeouts", "ooms")):
        record[key] = sum(1 for a in artifacts if a["kind"] == kind)
    if forks:  # -fork counts what it ignored
        last = forks[-1]
        record["ooms"] = max(record["ooms"], int(last[5]))
        record["timeouts"] = max(record["timeouts"], int(last[6]))
        record["crashes"] = max(record["crashes"], int(last[7]))
    if record["exit_status"] not in (0, None) and not artifacts:
        what, where = describe_problem(text)
        artifacts.append({"file": "", "kind": "crash", "what": what + f" (exit status {record['exit_status']})", "where": where})
        record["crashes"] += 1
    record["artifacts"] = artifacts

    regressions = []
    reg_file = os.path.join(run_dir, "regressions.txt")
    if os.path.exists(reg_file):
        for line in open(reg_file):
            line = line.rstrip("\n")
            if line:
                passed = line.startswith("pass ")
                regressions.append({"passed": passed, "line": line[5:]})
    record["regressions_total"] = len(regressions)
    record["regressions_passed"] = sum(1 for r in regressions if r["passed"])
    record["regression_failures"] = [r["line"] for r in regressions if not r["passed"]]
    return record


def cell(value, default="–"):
    return default if value is None else str(value)


def arrow(record, key):
    start, end = record.get(key + "_start"), record.get(key + "_end")
    if start is None or end is None:
        return "–"
    return f"{start} → {end} (+{end - start})"


def write_markdown(path, data, readers):
    lines = [
        "# Fuzzing results",
        "",
        "Written by `scripts/fuzz.sh` (from `fuzz/results.json`); do not edit by hand. One row per target: its",
        "latest recorded run. A clean run for the record (issue #34) is a full run (not `--ci`, not",
        f"`--keep-going`) of at least {CLEAN_SECONDS} s with no crash, leak, timeout or OOM and every regression passing.",
        "",
        "Setup: libFuzzer with AddressSanitizer and UndefinedBehaviorSanitizer (`-fno-sanitize-recover`), the",
        "readers (`flowvid_formats`) instrumented too, `-O1`; limits `-rss_limit_mb=1024 -malloc_limit_mb=1024",
        "-timeout=10 -max_len=65536`; libFuzzer's mutations mixed with the structure-aware ones of",
        "`fuzz/structure_mutator.cpp`. *cov* and *ft* are libFuzzer's edge-coverage and feature counts at the start",
        "(the corpus) and the end of the run; *new units* are the inputs it added for new coverage (a",
        "`--keep-going` run uses libFuzzer's `-fork` mode, which counts both differently: compare runs of one",
        "mode). The regressions are `fuzz/regressions/<target>/*` and, in full runs, the generated issue #34",
        "reproducers.",
        "",
        "| target | reads | date (UTC) | commit | mode | seconds | executions | exec/s | cov | ft | new units "
        "| regressions | crashes | leaks | timeouts | OOMs | clean ≥ 10 min |",
        "|---|---|---|---|---|---:|---:|---:|---|---|---:|---|---:|---:|---:|---:|---|",
    ]
    problems = []
    for target in data["order"]:
        record = data["targets"].get(target)
        reader = readers.get(target, record.get("reader", "") if record else "")
        if not record:
            lines.append(f"| {target} | {reader} | not run yet | | | | | | | | | | | | | | no |")
            continue
        regressions = (f"{record['regressions_passed']}/{record['regressions_total']}"
                       if record.get("regressions_total") else "–")
        lines.append(
            f"| {target} | {reader} | {record['date']} | {record['commit']} | {record['mode']} | {cell(record.get('seconds'))} "
            f"| {cell(record.get('executions'))} | {cell(record.get('exec_per_s'))} | {arrow(record, 'cov')} "
            f"| {arrow(record, 'ft')} | {cell(record.get('new_units'))} | {regressions} | {record['crashes']} "
            f"| {record['leaks']} | {record['timeouts']} | {record['ooms']} | {'**yes**' if record['clean'] else 'no'} |")
        for artifact in record["artifacts"]:
            where = f" at `{artifact['where']}`" if artifact["where"] else ""
            saved = f"; input `{artifact['file']}`" if artifact["file"] else ""
            problems.append(f"- **{target}** ({record['date']}): {artifact['kind']}: {artifact['what']}{where}{saved}")
        for failure in record["regression_failures"]:
            problems.append(f"- **{target}** ({record['date']}): regression FAILS: {failure}")
    lines += ["", "## Problems found by the latest runs", ""]
    lines += problems or ["None."]
    lines += ["", "## Reproducing", "",
              "    bash scripts/fuzz.sh 600                      # every target, 10 minutes each (the record)",
              "    bash scripts/fuzz.sh 60 fabric_json           # one target",
              "    bash scripts/fuzz.sh --keep-going 300         # hunt: go on after crashes",
              "    build-fuzz/fuzz/fuzz_<target> INPUT           # replay one input under ASan/UBSan",
              "    build/tests/flowvid_fuzz_replay run <target> INPUT   # the same in the g++ build",
              ""]
    with open(path, "w") as out:
        out.write("\n".join(lines))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", required=True)
    parser.add_argument("--crashes", required=True)
    parser.add_argument("--data", required=True)
    parser.add_argument("--markdown", required=True)
    parser.add_argument("--seconds", type=int, required=True)
    parser.add_argument("--build-seconds", type=int, default=0)
    parser.add_argument("--mode", default="full")
    parser.add_argument("--keep-going", type=int, default=0)
    parser.add_argument("--targets", nargs="*", default=[])
    args = parser.parse_args()

    data = {"targets": {}}
    if os.path.exists(args.data):
        try:
            data = json.load(open(args.data))
        except ValueError:
            pass
    data["order"] = args.targets or sorted(data["targets"])
    readers = {}
    targets_tsv = os.path.join(args.runs, "targets.tsv")
    if os.path.exists(targets_tsv):
        for line in open(targets_tsv):
            if "\t" in line:
                name, reader = line.rstrip("\n").split("\t", 1)
                readers[name] = reader

    commit = git("rev-parse", "--short", "HEAD") or "?"
    # The code under test changed since the commit (the corpus and these results do not count).
    if git("status", "--porcelain", "--", "formats", "fuzz", "tests/fuzz", "libflowvid/python", ":!fuzz/RESULTS.md",
           ":!fuzz/results.json", ":!fuzz/corpus", ":!fuzz/fuzz_results.py"):
        commit += " + uncommitted changes"
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    mode = args.mode + (" keep-going" if args.keep_going else "")
    clang = clang_version()
    ran = sorted(d for d in os.listdir(args.runs) if os.path.isdir(os.path.join(args.runs, d)))
    summary = []
    for target in ran:
        record = parse_target(os.path.join(args.runs, target), args.crashes, target)
        record.update(date=date, commit=commit, mode=mode, seconds_requested=args.seconds, clang=clang,
                      build_seconds=args.build_seconds, reader=readers.get(target, ""))
        problems = record["crashes"] + record["leaks"] + record["timeouts"] + record["ooms"]
        record["clean"] = (args.mode == "full" and not args.keep_going and problems == 0 and record["exit_status"] == 0
                           and not record["regression_failures"] and (record.get("seconds") or 0) >= CLEAN_SECONDS)
        data["targets"][target] = record
        summary.append(f"  {target:18} {cell(record.get('executions')):>9} execs {cell(record.get('seconds')):>4} s  "
                       f"cov {arrow(record, 'cov'):22} new units {cell(record.get('new_units')):>4}  "
                       f"regressions {record['regressions_passed']}/{record['regressions_total']}  "
                       f"crash/leak/timeout/oom {record['crashes']}/{record['leaks']}/{record['timeouts']}/{record['ooms']}")
    os.makedirs(os.path.dirname(os.path.abspath(args.data)), exist_ok=True)
    with open(args.data, "w") as out:
        json.dump(data, out, indent=1, sort_keys=True)
        out.write("\n")
    write_markdown(args.markdown, data, readers)
    print("\n".join(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
