"""Compare with Cycles: a technique's camera view against Cycles computing the same model."""

import time

import bpy

from ..addon.bridge import write_back
from ..jobs.techniques import TECHNIQUES
from ..kernels.progress import scaled
from .job import JobOperator, ScenePoll

ERROR_IMAGE = "Classic Bake Error"
KERNEL_IMAGE = "Classic Bake Kernel View"
CYCLES_IMAGE = "Classic Bake Cycles View"
# The techniques a camera view can be compared for, by the panel's enumeration identifier.
COMPARABLE = {t.name.upper(): t for t in TECHNIQUES if t.renders and t.cycles_model is not None}


def _metric_settings():
    """HDR-FLIP when its package is installed (the dev environment), else the other metrics."""
    from ..kernels.measure.metrics import MetricSettings

    try:
        import flip_evaluator  # noqa: F401
    except ImportError:
        return MetricSettings(flip=False)
    return MetricSettings()


def compare_job(context, technique, samples: int):
    """Run the technique's job (its camera view), then Cycles with the matched model, then write
    the three images and the figures."""
    from ..addon.cycles import runner
    from ..kernels.measure.metrics import compare_with_images

    props = context.scene.classic_bake
    start = time.perf_counter()
    # Never "Show in Materials" here: Cycles must render the scene's own materials afterwards.
    values = {**technique.values_from_props(props), "wire": False}
    summary = yield from scaled(technique.start(context, values), 0.0, 0.7)
    if summary.render is None:
        raise ValueError("The scene needs a camera")
    kernel_seconds = time.perf_counter() - start
    yield 0.7
    model = technique.cycles_model(summary.settings)
    reference, cycles_seconds = runner.render_camera(context.scene, model, samples)
    metrics, errors = compare_with_images(summary.render, reference, settings=_metric_settings())
    # --- write back: images and figures ----------------------------------------------------------
    for name, pixels in ((KERNEL_IMAGE, summary.render), (CYCLES_IMAGE, reference),
                         (ERROR_IMAGE, errors.rel_se[..., None])):
        write_back.write_image(name, pixels, image=bpy.data.images.get(name))
    props.compare_rel_mse = metrics.rel_mse
    props.compare_flip = metrics.flip if metrics.flip is not None else -1.0
    props.compare_kernel_seconds = kernel_seconds
    props.compare_cycles_seconds = cycles_seconds
    summary.message = (f"relative MSE {metrics.rel_mse:.3g} against Cycles at {samples} samples; "
                       f"kernel {kernel_seconds:.2f} s, Cycles {cycles_seconds:.2f} s")
    return summary


class CLASSICBAKE_OT_compare(ScenePoll, JobOperator, bpy.types.Operator):
    """Render the kernel's view and Cycles' view of the same model, and show their difference"""

    bl_idname = "classic_bake.compare"
    bl_label = "Compare with Cycles"
    bl_options = {"REGISTER", "UNDO"}  # writes three images and the figures
    job_label = "Comparing with Cycles"
    needs = ("camera",)

    def start(self, context):
        props = context.scene.classic_bake
        return compare_job(context, COMPARABLE[props.compare_technique], props.compare_samples)


CLASSES = (CLASSICBAKE_OT_compare,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
