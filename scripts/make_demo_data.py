#!/usr/bin/python3
"""Regenerates data/demo/: the bundled captures `flowvid demo` runs on.

The cloth captures are the head of public captures in ../shared/captures
(Blender-made synthetic footage, see its README), cut to the frames the demo
needs so a clean clone stays small: capture.json's frame count and pin paths
are cut to match, frames, masks and the background are copied, truth/ is
left behind (no fit may read it). The waterfall clip is copied whole: its
capture.json records its origin and licence (CC0). Run from the repository root: /usr/bin/python3
scripts/make_demo_data.py [SHARED_CAPTURES_DIR].
"""
import json
import os
import shutil
import sys

# demo name -> (public capture, frames kept)
CUTS = {
    "cotton-static": ("cloth-cotton-static-1", 1),
    "cotton-waving": ("cloth-cotton-waving-1", 24),
    "cotton-waving-effect": ("cloth-cotton-waving-wind", 30),
}


def cut(source, target, frames):
    with open(os.path.join(source, "capture.json")) as f:
        capture = json.load(f)
    if capture["frames"]["count"] < frames:
        sys.exit(f"{source}: has {capture['frames']['count']} frames, the demo needs {frames}")
    capture["frames"]["count"] = frames
    for pin in capture["swatch"]["pins"]:
        pin["positions"] = pin["positions"][:frames]
    if os.path.exists(target):
        shutil.rmtree(target)
    for folder in ("frames", "masks"):
        os.makedirs(os.path.join(target, folder))
    first = capture["frames"]["first"]
    for k in range(first, first + frames):
        for key in ("frames", "masks"):
            pattern = capture["frames"]["pattern"] if key == "frames" else capture["masks"]
            name = pattern % k
            shutil.copyfile(os.path.join(source, name), os.path.join(target, name))
    if "background" in capture:
        shutil.copyfile(os.path.join(source, capture["background"]), os.path.join(target, capture["background"]))
    temporary = os.path.join(target, "capture.json.tmp")
    with open(temporary, "w") as f:
        json.dump(capture, f, indent=1)
        f.write("\n")
    os.replace(temporary, os.path.join(target, "capture.json"))


# demo name -> public video capture, copied whole after checking its licence
CLIPS = {"waterfall": "video-waterfall-cascade"}


def copy_clip(source, target):
    with open(os.path.join(source, "capture.json")) as f:
        licence = json.load(f).get("source", {}).get("licence", "")
    if "CC0" not in licence:
        sys.exit(f"{source}: licence {licence!r} does not allow bundling; pick a CC0 clip")
    if os.path.exists(target):
        shutil.rmtree(target)
    shutil.copytree(source, target)
    for root, folders, files in os.walk(target):  # the shared copy is read-only
        for name in folders + files:
            os.chmod(os.path.join(root, name), 0o755 if name in folders else 0o644)
    os.chmod(target, 0o755)


def main():
    shared = sys.argv[1] if len(sys.argv) > 1 else "../shared/captures"
    for name, (capture, frames) in CUTS.items():
        cut(os.path.join(shared, capture), os.path.join("data", "demo", name), frames)
        print(f"data/demo/{name}: {frames} frames of {capture}")
    for name, capture in CLIPS.items():
        copy_clip(os.path.join(shared, capture), os.path.join("data", "demo", name))
        print(f"data/demo/{name}: {capture}, whole")


if __name__ == "__main__":
    main()
