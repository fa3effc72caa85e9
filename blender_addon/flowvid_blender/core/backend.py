"""How the add-on reaches the flowvid library.

Preferred: the native pybind11 module `flowvid`, when one built for this
Python's ABI is importable (Debian's Blender uses /usr/bin/python3, which the
build targets). Otherwise (e.g. an official Blender build with its own bundled
Python) the `flowvid` command-line tool is run with `--progress=json`. Which one
is used is decided in library.py (core/locate.py finds them). Both
reach the same library entry points: a render through either gives the same
frames.
"""
import json
import os
import signal
import subprocess
import tempfile


class BackendError(RuntimeError):
    """A flowvid failure, with the message the library or tool gave."""


class NativeBackend:
    name = "native"

    def __init__(self, module):
        self.module = module

    def _call(self, function, *arguments, **options):
        try:
            return function(*arguments, **options)
        except self.module.Error as error:
            raise BackendError(str(error)) from None

    def read_fabric_preset(self, path):
        return self._call(self.module.formats.read_fabric_preset, path)

    def write_fabric_preset(self, path, preset):
        self._call(self.module.formats.write_fabric_preset, path, preset)

    def check_folds(self, preset_path, edge_m):
        """Whether a mesh with edges edge_m long holds the preset's folds: {"fold_length_m", "edge_m",
        "longest_edge_m", "holds_folds"} (flowvid.cloth.check_folds), and the same for the swatch it was fitted
        on: "fitted_edge_m", "fitted_mesh_holds_folds" (None where the preset does not record it)."""
        preset = self.read_fabric_preset(preset_path)
        check = dict(self._call(self.module.cloth.check_folds, preset["parameters"], edge_m))
        fitted_edge_m = preset.get("provenance", {}).get("swatch_edge_length_m")
        check["fitted_edge_m"] = fitted_edge_m if fitted_edge_m and fitted_edge_m > 0 else None
        check["fitted_mesh_holds_folds"] = (
            self._call(self.module.cloth.check_folds, preset["parameters"], fitted_edge_m)["holds_folds"]
            if check["fitted_edge_m"] else None)
        return check

    def write_flowline_set(self, path, flowlines):
        self._call(self.module.flow.write_flowline_set, path, flowlines)

    def read_flowline_set(self, path):
        return self._call(self.module.flow.read_flowline_set, path)

    def synthesize(self, bank, out, frames, edit=False, flowlines="", capture="", background="auto", texture="auto",
                   progress=None, edge_fade=None):
        """flowvid synth (edit=False) or edit, in process; returns the summary `flowvid synth --json` prints.
        edge_fade: px over which the texture fades out at its edge (None: the library's choice, a patch for edits
        of whole textures). progress(stage, fraction, message) -> False cancels (frames written so far stay)."""
        return self._call(self.module.flow.synthesize, bank, out, frames=tuple(frames), edit=edit, flowlines=flowlines,
                          capture=capture, background=background, texture=texture, edge_fade=edge_fade,
                          progress=progress)

    def simulate_swatch(self, experiment, parameters, **options):
        """The library's swatch experiment (flowvid.cloth.simulate_swatch); raises BackendError unless ok."""
        result = self._call(self.module.cloth.simulate_swatch, experiment, parameters, **options)
        if result["status"] != "ok":
            raise BackendError("the library's swatch simulation stopped: %s (%s)" % (result["status"], result["reason"]))
        return result


def _progress_event(line):
    """A --progress=json event ({"event": ...}) as a dict, or None for a line meant for people."""
    try:
        event = json.loads(line)
    except ValueError:
        return None
    return event if isinstance(event, dict) and "event" in event else None


class CliBackend:
    name = "cli"

    def __init__(self, executable):
        self.executable = executable

    def run(self, *arguments, progress=None):
        """Runs `flowvid ARGUMENTS`; returns its stdout. progress(stage, fraction, message) gets the tool's
        --progress=json events as the module's progress gets them; returning False stops the tool as Ctrl-C
        does (it keeps what is whole) and raises BackendError."""
        command = [self.executable, "--progress=json", *[str(a) for a in arguments]]
        with tempfile.TemporaryFile("w+") as stdout:
            process = subprocess.Popen(command, stdout=stdout, stderr=subprocess.PIPE, text=True)
            messages = []  # what the tool says for people: its errors and its log
            for line in process.stderr:
                event = _progress_event(line)
                if event is None:
                    messages.append(line.rstrip("\n"))
                elif progress is not None and event.get("event") == "progress":
                    stage = event.get("stage") or event.get("task", "")
                    if progress(stage, float(event.get("fraction", 0.0)), event.get("detail", "")) is False:
                        process.send_signal(signal.SIGINT)
            code = process.wait()
            if code != 0:
                raise BackendError("\n".join(messages).strip() or "flowvid exited with %d" % code)
            stdout.seek(0)
            return stdout.read()

    def read_fabric_preset(self, path):
        # `validate` first so errors name the field; then the file itself is plain JSON.
        self.run("validate", "--lenient", path)
        with open(path, encoding="utf-8") as handle:
            return json.load(handle)

    def read_flowline_set(self, path):
        # An artist's SVG drawing, as the library reads it: through `convert`.
        if not path.lower().endswith(".svg"):
            return self.read_fabric_preset(path)
        with tempfile.TemporaryDirectory() as folder:
            converted = os.path.join(folder, "drawn.flowlines.json")
            self.run("convert", path, converted)
            with open(converted, encoding="utf-8") as handle:
                return json.load(handle)

    def _write_json(self, path, document):
        # Written beside the target, validated by the tool, then renamed over it.
        folder = os.path.dirname(os.path.abspath(path))
        handle, temporary = tempfile.mkstemp(prefix=".flowvid-", suffix=os.path.basename(path), dir=folder)
        try:
            with os.fdopen(handle, "w", encoding="utf-8") as stream:
                json.dump(document, stream, indent=2)
            self.run("validate", temporary)
            os.replace(temporary, path)
        finally:
            if os.path.exists(temporary):
                os.unlink(temporary)

    def write_fabric_preset(self, path, preset):
        self._write_json(path, preset)

    def check_folds(self, preset_path, edge_m):
        """As NativeBackend.check_folds, through `flowvid info --json --mesh-edge-mm`."""
        check = json.loads(self.run("info", "--json", "--mesh-edge-mm", repr(1e3 * edge_m), preset_path))
        fitted_edge_mm = check["fitted_edge_mm"]
        return {"fold_length_m": 1e-3 * check["fold_length_mm"], "edge_m": 1e-3 * check["mesh_edge_mm"],
                "longest_edge_m": 1e-3 * check["longest_edge_mm"], "holds_folds": check["mesh_holds_folds"],
                "fitted_edge_m": 1e-3 * fitted_edge_mm if fitted_edge_mm is not None else None,
                "fitted_mesh_holds_folds": check["fitted_mesh_holds_folds"]}

    def write_flowline_set(self, path, flowlines):
        self._write_json(path, flowlines)

    def synthesize(self, bank, out, frames, edit=False, flowlines="", capture="", background="auto", texture="auto",
                   progress=None, edge_fade=None):
        """As NativeBackend.synthesize, through `flowvid synth|edit --json`."""
        arguments = ["edit" if edit else "synth", "--bank", bank, "--out", out, "--frames", "%d:%d" % tuple(frames),
                     "--background", background, "--texture", texture, "--json"]
        arguments += ["--edge-fade", "%g" % edge_fade] if edge_fade is not None else []
        arguments += ["--flowlines", flowlines] if flowlines else []
        arguments += ["--capture", capture] if capture else []
        return json.loads(self.run(*arguments, progress=progress))

    def simulate_swatch(self, experiment, parameters, rows=12, cols=12, integrator="implicit_euler", substeps=10,
                        initial_bow=1.0, progress=None):
        """As NativeBackend.simulate_swatch, through `flowvid swatch` (same defaults, same frames): the
        parameters go in a minimal preset, the experiment and the frames as JSON files. progress(frame,
        frame_count) -> False stops the tool (SIGINT) and raises BackendError."""
        count = experiment["frame_count"]
        with tempfile.TemporaryDirectory(prefix="flowvid-swatch-") as folder:
            preset_path = os.path.join(folder, "swatch.fabric.json")
            experiment_path = os.path.join(folder, "experiment.swatch_experiment.json")
            out = os.path.join(folder, "frames.swatch_frames.json")
            values = {key: {"value": float(entry["value"] if isinstance(entry, dict) else entry)}
                      for key, entry in parameters.items()}
            with open(preset_path, "w", encoding="utf-8") as stream:
                json.dump({"format": "flowvid.fabric", "version": "1.1", "name": "swatch", "parameters": values,
                           "provenance": {"method": "manual", "created_utc": "1970-01-01T00:00:00Z"}}, stream)
            with open(experiment_path, "w", encoding="utf-8") as stream:
                # flowvid.swatch_experiment 1.0 (formats/specs/swatch_experiment.md): the experiment's own keys
                # under the format's header; the frames come back as flowvid.swatch_frames 1.0.
                json.dump(dict({"format": "flowvid.swatch_experiment", "version": "1.0"}, **experiment), stream)
            try:
                self.run("swatch", "--preset", preset_path, "--experiment", experiment_path, "--out", out,
                         "--grid", "%dx%d" % (rows, cols), "--integrator", integrator, "--substeps", substeps,
                         "--initial-bow", initial_bow,
                         progress=None if progress is None else
                         lambda _stage, fraction, _m: progress(round(fraction * count), count))
            except BackendError:
                if not os.path.isfile(out):  # a blow-up writes its frames and status: reported below
                    raise
            with open(out, encoding="utf-8") as stream:
                result = json.load(stream)
        if result["status"] != "ok":
            raise BackendError("the library's swatch simulation stopped: %s (%s)" % (result["status"], result["reason"]))
        result["frames"] = [[tuple(p) for p in frame] for frame in result["frames"]]
        return result
