"""Long work as steps, so one description serves a modal operator (progress, Esc) and a script (to the end).

A job is a generator. It yields (fraction, text) between pieces of work that need
bpy (each runs on Blender's main thread, between UI events), or Background(function)
for work that needs no bpy (the library, the flowvid tool): a modal operator runs
that in a thread while Blender's UI stays live, and sends its result back into the
generator (or throws its exception there). Plain Python (no bpy).
"""
from .errors import FlowvidError


class Cancelled(FlowvidError):
    """The user cancelled (Esc): whatever the job had changed was put back."""


class Background:
    """Work for a thread: function(progress) -> result, where progress(fraction, text) returns False once
    the user cancelled (pass that on to the library's or the tool's progress callback)."""

    def __init__(self, function, text=""):
        self.function = function
        self.text = text


def always(_fraction, _text=""):
    return True


def run_to_end(job, progress=None):
    """Runs a job in this thread (scripts, `blender -b`, an operator's execute()); returns what it returns.
    progress(fraction, text) -> False cancels at the next step (Cancelled)."""
    progress = progress or always
    value, error = None, None
    while True:
        try:
            item = job.throw(error) if error is not None else job.send(value)
        except StopIteration as finished:
            return finished.value
        value, error = None, None
        if isinstance(item, Background):
            try:
                value = item.function(progress)
            except Exception as raised:  # noqa: BLE001 - handed to the job, as the modal runner does
                error = raised
        elif progress(*item) is False:
            job.close()
            raise Cancelled("cancelled")
