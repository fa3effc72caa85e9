"""Headless Blender entry point of the flowvid add-on (docs/blender.md, "Batch").

    blender -b scene.blend --python-exit-code 1 --python scripts/blender_batch.py -- \\
        --preset silk.fabric.json --object Skirt [--calibrate] \\
        [--emitter Fountain --flowlines out/lines.flowlines.json --inputs drawn.flowlines.json \\
         --bank bank.exr --frames 1:48] [--render out/]

Steps run in this order, each only when its options are given: apply a fabric
preset to --object (optionally calibrating it first), bake --emitter's
particles through the scene camera into --flowlines, synthesize with --bank
and show the frames on a plane facing the camera, render --frames into
--render. Any failure prints one line "flowvid batch: error: ..." on stderr
and exits with status 1 (2 for bad arguments), so farm wrappers can rely on
the exit code even without --python-exit-code.
"""
import argparse
import json
import os
import sys


def _arguments(argv):
    parser = argparse.ArgumentParser(prog="blender -b scene.blend --python scripts/blender_batch.py --",
                                     description="Apply fabric presets, bake flow lines and render, headless.")
    parser.add_argument("--preset", help="*.fabric.json to apply")
    parser.add_argument("--object", action="append", default=[], help="object to apply the preset to (repeatable)")
    parser.add_argument("--calibrate", action="store_true", help="calibrate the preset for the object's mesh first")
    parser.add_argument("--emitter", help="object whose particle system becomes output flow lines")
    parser.add_argument("--flowlines", help="flow-line set to write from the particles")
    parser.add_argument("--inputs", help="flow-line set (or SVG) with the input lines the bank was tracked with")
    parser.add_argument("--bank", help="particle bank (*.bank.exr) to synthesize the frames from")
    parser.add_argument("--frames", type=_frame_range,
                        help="A:B (default: the scene's frame range); frames are named by their number, so farm "
                             "tasks rendering chunks of one range join seamlessly")
    parser.add_argument("--background", choices=("median", "loop", "replay", "relit", "none"),
                        help="with --bank: what shows where no line reaches (flowvid edit --background; default median)")
    parser.add_argument("--texture", choices=("whole", "moving"),
                        help="with --bank: what a particle's patch carries (flowvid edit --texture; default whole): "
                             "moving = only the light flames or smoke add, for scenes behind a fire")
    parser.add_argument("--render", help="folder to render the frames into (PNG)")
    parser.add_argument("--addon", help="folder holding flowvid_blender (default: this checkout's blender_addon)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    return parser.parse_args(argv)


def _frame_range(text):
    """--frames A:B, inclusive, A <= B (Blender frame numbers, so 0 and negative are allowed)."""
    try:
        start, end = (int(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError("expected A:B, e.g. 1:48, got %r" % text)
    if start > end:
        raise argparse.ArgumentTypeError("%r: A must not be greater than B" % text)
    return start, end


def _run_up_to(scene, frame):
    """Steps the scene from its first frame to `frame` - 1, so that simulations without a baked cache
    (cloth, particles) reach `frame` in the state a render of the whole range gives them: a farm task
    rendering frames A:B then joins the others' frames. Without this, Blender starts an unbaked cloth
    at rest on frame A (measured: a 4:5 chunk differed from the whole render in the swatch's pixels)."""
    for step in range(scene.frame_start, frame):
        scene.frame_set(step)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    try:
        options = _arguments(argv)
    except SystemExit as exit_request:
        sys.stdout.flush()
        os._exit(2 if exit_request.code else 0)
    here = os.path.dirname(os.path.realpath(__file__))  # through symlinks to the checkout
    sys.path.insert(0, options.addon or os.path.join(os.path.dirname(here), "blender_addon"))
    import bpy

    from flowvid_blender import api

    scene = bpy.context.scene
    summary = {}
    try:
        if options.frames:
            start, end = options.frames
        else:
            start, end = scene.frame_start, scene.frame_end
        if options.preset:
            if not options.object:
                raise api.FlowvidError("--preset needs --object NAME")
            for name in options.object:
                obj = bpy.data.objects.get(name)
                if obj is None:
                    raise api.FlowvidError("no object named %r in %s" % (name, bpy.data.filepath or "the scene"))
                report = api.apply_fabric_preset(obj, options.preset, calibrate=options.calibrate, scene=scene)
                summary.setdefault("applied", {})[name] = {"source": report["source"],
                                                            "not_represented": report["not_represented"]}
                for note in report["not_represented"]:
                    print("flowvid batch: %s: %s" % (name, note), file=sys.stderr)
        if options.emitter:
            emitter = bpy.data.objects.get(options.emitter)
            if emitter is None:
                raise api.FlowvidError("no object named %r" % options.emitter)
            if not options.flowlines:
                raise api.FlowvidError("--emitter needs --flowlines PATH to write")
            summary["flowlines"] = api.bake_flowlines(emitter, scene.camera, start, end, options.flowlines,
                                                      inputs=options.inputs, scene=scene)
        if options.bank:
            if not options.flowlines:
                raise api.FlowvidError("--bank needs --flowlines")
            folder = os.path.join(os.path.dirname(os.path.abspath(options.flowlines)), "synthesized")
            first = api.synthesize(options.bank, options.flowlines, start, end, folder, background=options.background,
                                   texture=options.texture)
            image = api.load_image_sequence(first, start, end - start + 1)
            api.show_on_camera_plane(scene.camera, image, start, end - start + 1, scene=scene)
            summary["synthesized"] = folder
        if options.render:
            _run_up_to(scene, start)
            summary["rendered"] = api.render_frames(os.path.abspath(options.render), start, end, scene=scene)
    except Exception as error:  # noqa: BLE001 - one line for the farm log, exit 1
        print("flowvid batch: error: %s" % error, file=sys.stderr)
        sys.stderr.flush()
        sys.stdout.flush()
        os._exit(1)
    if options.json:
        print(json.dumps(summary))
    sys.stdout.flush()


main()
