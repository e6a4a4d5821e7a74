"""Two paths for every bake operator: `execute()` blocks (scripts, headless), `invoke()` runs modal.

A subclass implements `start(context)`, returning a step (kernels/progress.py: a generator that
yields progress in [0, 1] and returns a `JobSummary`). The step must change Blender data only
after its last yield (compute first, write at the end), so that Esc — which simply closes the
generator — leaves the scene exactly as it was. The modal path advances the step for a time budget
per timer tick (preferences: "Work per UI Tick"), shows progress in the status bar and the
window's progress cursor, and reports the summary's one line with the time it took.
"""

from __future__ import annotations

import time

from ..addon import preferences
from ..kernels.progress import advance, drain

TIMER_INTERVAL_S = 0.02  # how often the modal path wakes up to do another slice of work
DEFAULT_TICK_BUDGET_MS = 50.0  # used when the add-on's preferences are not available


class JobOperator:
    """Mixin for `bpy.types.Operator` subclasses; see the module docstring."""

    job_label = "Baking"

    def start(self, context):  # pragma: no cover - abstract
        raise NotImplementedError

    def finished(self, context, summary, seconds: float) -> None:
        """Report the finished job's one line (and its time)."""
        if summary is not None and summary.message:
            self.report({"INFO"}, f"{self.job_label}: {summary.message} ({seconds:.2f} s)")

    # --- blocking path ----------------------------------------------------------------------------

    def execute(self, context):
        began = time.perf_counter()
        try:
            summary = drain(self.start(context))
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.finished(context, summary, time.perf_counter() - began)
        return {"FINISHED"}

    # --- modal path -------------------------------------------------------------------------------

    def invoke(self, context, event):
        self._began = time.perf_counter()
        try:
            self._job = self.start(context)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(TIMER_INTERVAL_S, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        self._status(context, 0.0)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._job.close()  # stops the generator before it wrote anything
            self._finish(context)
            self.report({"WARNING"}, f"{self.job_label}: cancelled, nothing changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        return self.step(context)

    def step(self, context) -> set[str]:
        """One timer tick's work: advance the job until the tick's budget is spent."""
        prefs = preferences.get(context)
        budget = (prefs.tick_budget_ms if prefs else DEFAULT_TICK_BUDGET_MS) / 1000.0
        deadline = time.perf_counter() + budget
        try:
            while time.perf_counter() < deadline:
                tick = advance(self._job)
                if tick.done:
                    self._finish(context)
                    self.finished(context, tick.result, time.perf_counter() - self._began)
                    return {"FINISHED"}
                context.window_manager.progress_update(int(100 * tick.progress))
                self._status(context, tick.progress)
        except ValueError as exc:
            self._finish(context)
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return {"RUNNING_MODAL"}

    def _status(self, context, progress: float) -> None:
        if context.workspace is not None:
            context.workspace.status_text_set(f"{self.job_label}: {progress:.0%} (Esc to cancel)")

    def _finish(self, context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)


class ScenePoll:
    """Mixin: the operator's poll checks what its scene must hold, named in `needs` (in the order
    given): "camera", "light", "mesh". Each missing one is explained in the status bar."""

    needs: tuple[str, ...] = ()
    _NEEDS = {
        "camera": (lambda scene: scene.camera is not None, "The scene needs a camera"),
        "light": (lambda scene: any(o.type == "LIGHT" for o in scene.objects),
                  "The scene needs a light"),
        "mesh": (lambda scene: any(o.type == "MESH" for o in scene.objects),
                 "The scene has no meshes"),
    }

    @classmethod
    def poll(cls, context):
        scene = context.scene
        if scene is None or not hasattr(scene, "classic_bake"):
            cls.poll_message_set("No scene")
            return False
        for need in cls.needs:
            present, message = cls._NEEDS[need]
            if not present(scene):
                cls.poll_message_set(message)
                return False
        return True
