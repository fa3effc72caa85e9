"""Modal operators over core/jobs.py: progress in the status bar and on the cursor, Esc cancels.

An operator that mixes in JobOperator defines job(context) (a core.jobs generator) and
done(context, result) -> message. invoke() with a window runs it modally: a timer
advances the job one step per tick, Background work runs in a thread (the library
and the tool keep Blender's UI live; their progress callbacks return False once Esc
was pressed, which stops them: flowvid.Cancelled in the module, SIGINT for the tool).
execute() -- scripts, `blender -b`, EXEC_DEFAULT -- runs the job to the end."""
import threading

from ..core import jobs

TIMER_S = 0.1


class _Thread:
    def __init__(self, background, job_operator):
        self.result = None
        self.error = None
        self.operator = job_operator
        self.thread = threading.Thread(target=self._run, args=(background.function,), daemon=True)
        self.thread.start()

    def _run(self, function):
        try:
            self.result = function(self.operator._progress_from_thread)
        except Exception as error:  # noqa: BLE001 - thrown into the job on the main thread
            self.error = error

    def done(self):
        return not self.thread.is_alive()


class JobOperator:
    """Mixin for bpy.types.Operator subclasses (see the module docstring)."""

    progress_title = "flowvid"

    def job(self, context):
        raise NotImplementedError

    def done(self, context, result):
        return str(result)

    # -- to the end (no window) ---------------------------------------------------------------------------------

    def execute(self, context):
        from .operators import fail

        try:
            result = jobs.run_to_end(self.job(context))
            self.report({"INFO"}, self.done(context, result))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001 - shown in the UI
            return fail(self, error)

    # -- modal ----------------------------------------------------------------------------------------------------

    def invoke(self, context, event):
        if context.window is None:
            return self.execute(context)
        self._job = self.job(context)
        self._thread = None
        self._value, self._error = None, None
        self._cancel = False
        self._fraction, self._text = 0.0, "starting"
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(TIMER_S, window=context.window)
        wm.modal_handler_add(self)
        self._show(context)
        return {"RUNNING_MODAL"}

    def _progress_from_thread(self, fraction, text=""):
        # Called from the worker thread: only plain attributes here, the timer shows them.
        self._fraction, self._text = fraction, text or self._text
        return not self._cancel

    def _show(self, context):
        context.window_manager.progress_update(int(100 * min(max(self._fraction, 0.0), 1.0)))
        if context.workspace is not None:
            context.workspace.status_text_set("%s: %d%% %s (Esc cancels)" % (
                self.progress_title, 100 * self._fraction, self._text))

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)

    def modal(self, context, event):
        from .operators import fail

        if event.type == "ESC" and event.value == "PRESS":
            self._cancel = True
            self._text = "cancelling"
        if event.type != "TIMER" and not self._cancel:
            return {"PASS_THROUGH"}
        if self._thread is not None:
            if not self._thread.done():
                self._show(context)
                return {"RUNNING_MODAL"}
            self._value, self._error = self._thread.result, self._thread.error
            self._thread = None
        if self._cancel:
            self._job.close()  # its finally blocks put back what it changed
            self._end(context)
            self.report({"WARNING"}, "%s cancelled" % self.progress_title)
            return {"CANCELLED"}
        try:
            if self._error is not None:
                error, self._error = self._error, None
                item = self._job.throw(error)
            else:
                item = self._job.send(self._value)
            self._value = None
        except StopIteration as finished:
            self._end(context)
            self.report({"INFO"}, self.done(context, finished.value))
            return {"FINISHED"}
        except Exception as error:  # noqa: BLE001
            self._end(context)
            return fail(self, error)
        if isinstance(item, jobs.Background):
            self._text = item.text or self._text
            self._thread = _Thread(item, self)
        else:
            self._fraction, self._text = item
        self._show(context)
        return {"RUNNING_MODAL"}
