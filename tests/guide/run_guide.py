#!/usr/bin/python3
"""Runs every ```sh block of a user-guide page, in order, as a user would.

    run_guide.py PAGE.md REPO_DIR FLOWVID_EXECUTABLE SCRATCH_DIR

The blocks run with bash -euo pipefail in a fresh SCRATCH_DIR holding links
to the checkout's data/, formats/ and scripts/, with a `flowvid` wrapper for
FLOWVID_EXECUTABLE first on PATH (and FLOWVID_CLI set for the add-on). The
page fails when any command exits non-zero; the block, its output and the
command that failed are printed.
"""
import os
import re
import shutil
import subprocess
import sys
import time


def shell_blocks(markdown):
    return re.findall(r"^```sh\n(.*?)^```", markdown, flags=re.MULTILINE | re.DOTALL)


def main():
    page, repo, flowvid, scratch = sys.argv[1:5]
    with open(page) as handle:
        blocks = shell_blocks(handle.read())
    if not blocks:
        sys.exit("%s: no ```sh block to run" % page)
    if os.path.exists(scratch):
        shutil.rmtree(scratch)
    bin_dir = os.path.join(scratch, ".bin")
    os.makedirs(bin_dir)
    for name in ("data", "formats", "scripts"):
        os.symlink(os.path.join(repo, name), os.path.join(scratch, name))
    wrapper = os.path.join(bin_dir, "flowvid")
    with open(wrapper, "w") as handle:
        handle.write('#!/bin/sh\nexec "%s" "$@"\n' % flowvid)
    os.chmod(wrapper, 0o755)
    environment = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ.get("PATH", ""), FLOWVID_CLI=flowvid)
    for number, block in enumerate(blocks, 1):
        started = time.monotonic()
        completed = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=scratch, env=environment,
                                   capture_output=True, text=True)
        print("%s block %d: exit %d in %.1f s" % (os.path.basename(page), number, completed.returncode,
                                                 time.monotonic() - started))
        if completed.returncode != 0:
            print("---- block ----\n%s---- stdout (tail) ----\n%s\n---- stderr (tail) ----\n%s"
                  % (block, completed.stdout[-3000:], completed.stderr[-3000:]))
            sys.exit(1)
    print("%s: %d blocks ran" % (page, len(blocks)))


if __name__ == "__main__":
    main()
