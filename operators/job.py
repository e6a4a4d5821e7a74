"""Two paths for every bake operator: `execute()` blocks (scripts, headless), `invoke()` runs modal.

A subclass implements `start(context)`, returning a step (kernels/progress.py: a generator that
yields progress in [0, 1] and returns a `JobSummary`). The step must change Blender data only
after its last yield (compute first, write at the end), so that Esc — which simply closes the
generator — leaves the scene exactly as it was. The modal path advances the step for a time budget
per timer tick (preferences: "Work per UI Tick"), shows progress in the status bar and the
window's progress cursor, and reports the summary's one line with the time it took.

The modal path is three methods a test can drive without an event loop: `begin(context)` starts
the job (what `invoke` does before it adds the timer), `modal(context, event)` handles one event
(a TIMER event runs `step`, Esc closes the job) and `step(context)` is one tick's work.

After a finished bake the result is where the user looks (`show_results`): each colour attribute
the job wrote becomes its mesh's active and rendered one, and an open Image Editor showing nothing
(or an earlier Classic Bake image) shows the job's first image. With the preference "Save Images"
the job's images are also written as OpenEXR into the preferences' output folder.
"""

from __future__ import annotations

import os
import time

from ..addon import preferences
from ..kernels.geometry.threads import set_core_limit
from ..kernels.progress import advance, drain

TIMER_INTERVAL_S = 0.02  # how often the modal path wakes up to do another slice of work
DEFAULT_TICK_BUDGET_MS = 50.0  # used when the add-on's preferences are not available
IMAGE_PREFIX = "Classic Bake"  # every image the jobs write starts with this, or is a lightmap


def apply_thread_preference(context) -> None:
    """The kernels take at most the preferences' Threads cores (0, or no preferences: all)."""
    prefs = preferences.get(context)
    set_core_limit(prefs.threads if prefs else 0)


class JobOperator:
    """Mixin for `bpy.types.Operator` subclasses; see the module docstring."""

    job_label = "Baking"
    attribute = ""  # the colour attribute the job writes ("" when it writes none)

    def start(self, context):  # pragma: no cover - abstract
        raise NotImplementedError

    def finished(self, context, summary, seconds: float) -> None:
        """Show the results, save them when the preferences ask, report the one line and time."""
        if summary is None:
            return
        show_results(context, summary, self.attribute)
        saved = save_results(context, summary)
        if summary.message:
            where = f"; {len(saved)} images saved to {os.path.dirname(saved[0])}" if saved else ""
            self.report({"INFO"}, f"{self.job_label}: {summary.message} ({seconds:.2f} s){where}")

    # --- blocking path ----------------------------------------------------------------------------

    def execute(self, context):
        began = time.perf_counter()
        apply_thread_preference(context)
        self._leave_edit_mode(context)
        try:
            summary = drain(self.start(context))
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.finished(context, summary, time.perf_counter() - began)
        return {"FINISHED"}

    def _leave_edit_mode(self, context) -> None:
        """Object Mode before the job, so that what it writes into meshes stays there."""
        from ..addon.bridge.object_mode import leave_edit_mode

        for line in leave_edit_mode(context):
            self.report({"INFO"}, f"{self.job_label}: {line}")

    # --- modal path -------------------------------------------------------------------------------

    def invoke(self, context, event):
        import bpy

        # No window to show progress in, or no event loop to send timer events (background
        # Blender, the bpy module): block as a script would.
        if context.window is None or bpy.app.background:
            return self.execute(context)
        status = self.begin(context)
        if status == {"RUNNING_MODAL"}:
            wm = context.window_manager
            self._timer = wm.event_timer_add(TIMER_INTERVAL_S, window=context.window)
            wm.modal_handler_add(self)
        return status

    def begin(self, context) -> set[str]:
        """Start the job and the progress display (no timer: `invoke` adds it)."""
        self._began = time.perf_counter()
        self._timer = None
        apply_thread_preference(context)
        self._leave_edit_mode(context)
        try:
            self._job = self.start(context)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        context.window_manager.progress_begin(0, 100)
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

    def tick_budget_s(self, context) -> float:
        prefs = preferences.get(context)
        return (prefs.tick_budget_ms if prefs else DEFAULT_TICK_BUDGET_MS) / 1000.0

    def step(self, context) -> set[str]:
        """One timer tick's work: advance the job (at least once) until the tick's budget is
        spent."""
        deadline = time.perf_counter() + self.tick_budget_s(context)
        try:
            while True:
                tick = advance(self._job)
                if tick.done:
                    self._finish(context)
                    self.finished(context, tick.result, time.perf_counter() - self._began)
                    return {"FINISHED"}
                context.window_manager.progress_update(int(100 * tick.progress))
                self._status(context, tick.progress)
                if time.perf_counter() >= deadline:
                    return {"RUNNING_MODAL"}
        except ValueError as exc:
            self._finish(context)
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}

    def _status(self, context, progress: float) -> None:
        if context.workspace is not None:
            context.workspace.status_text_set(f"{self.job_label}: {progress:.0%} (Esc to cancel)")

    def _finish(self, context) -> None:
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)


def show_results(context, summary, attribute: str) -> None:
    """Make the job's colour attribute active and rendered on every mesh it wrote, show it in
    solid viewports, and put the job's first image in an Image Editor that shows nothing or an
    earlier Classic Bake image."""
    import bpy

    for name in summary.attributes if attribute else ():
        obj = bpy.data.objects.get(name)
        attrs = getattr(getattr(obj, "data", None), "color_attributes", None)
        if attrs is None or attrs.get(attribute) is None:
            continue
        attrs.active_color_name = attribute
        attrs.render_color_index = attrs.find(attribute)
    screen = getattr(context, "screen", None)
    images = [*summary.images.values()]
    for area in screen.areas if screen is not None else ():
        space = area.spaces.active
        if area.type == "VIEW_3D" and summary.attributes and attribute:
            if space.shading.type == "SOLID":
                space.shading.color_type = "VERTEX"  # the active colour attribute
        elif area.type == "IMAGE_EDITOR" and images:
            shown = space.image
            if shown is None or shown.name.startswith(IMAGE_PREFIX) or shown in images:
                space.image = images[0]


def output_folder(context) -> str | None:
    """The preferences' output folder as an absolute path, or None when images are not saved.

    '//' is the .blend's folder; an unsaved file has none, so its images go to Blender's
    temporary folder."""
    import bpy

    prefs = preferences.get(context)
    if prefs is None or not prefs.save_images:
        return None
    folder = prefs.output_dir or "//"
    if folder.startswith("//") and not bpy.data.filepath:
        return os.path.join(bpy.app.tempdir or os.path.abspath("."), folder[2:])
    return bpy.path.abspath(folder)


def save_results(context, summary) -> list[str]:
    """With "Save Images" on, each of the job's images as OpenEXR in the output folder, named
    after the image; returns the paths written."""
    import bpy
    import numpy as np

    from ..addon.bridge import write_back
    from ..addon.bridge.images import flip_rows

    folder = output_folder(context)
    if folder is None or not summary.images:
        return []
    os.makedirs(folder, exist_ok=True)
    written = []
    for image in summary.images.values():
        width, height = image.size
        rgba = np.empty(width * height * 4, np.float32)
        image.pixels.foreach_get(rgba)
        path = os.path.join(folder, bpy.path.clean_name(image.name) + ".exr")
        write_back.save_image_exr(image, flip_rows(rgba.reshape(height, width, 4))[..., :3], path)
        written.append(path)
    return written


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
