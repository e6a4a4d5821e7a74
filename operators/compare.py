"""Compare with Cycles: the kernel's camera view against Cycles computing the same model."""

import time

import bpy

from ..addon import bridge, cycles
from ..addon.settings import (
    direct_light_settings,
    envmap_settings,
    shading_settings,
    tracer_settings,
)
from .job import JobOperator, ScenePoll

ERROR_IMAGE = "Classic Bake Error"
KERNEL_IMAGE = "Classic Bake Kernel View"
CYCLES_IMAGE = "Classic Bake Cycles View"


def _metric_settings():
    """HDR-FLIP when its package is installed (the dev environment), else the other metrics."""
    from ..kernels.measure.metrics import MetricSettings

    try:
        import flip_evaluator  # noqa: F401
    except ImportError:
        return MetricSettings(flip=False)
    return MetricSettings()


def compare_job(context, technique: str, samples: int, report):
    """Render the kernel view (yielding progress), then Cycles, then write images and figures."""
    from ..kernels.measure.metrics import compare_with_images
    from ..kernels.progress import scaled
    from ..kernels.shading import direct_light
    from ..kernels.trace import tracer

    props = context.scene.classic_bake
    scene = bridge.snapshot(context)
    if scene.camera is None:
        raise ValueError("The scene needs a camera")
    start = time.perf_counter()
    if technique == "TRACE":
        settings = tracer_settings(props, scene)
        model = cycles.whitted(settings.max_depth)
        steps = tracer.trace_steps(scene, settings)
    elif technique == "TEXTURE":
        from ..kernels.bake import texture_bake

        model = cycles.albedo()
        steps = texture_bake.render_steps(scene)
    elif technique == "BUMP":
        settings = shading_settings(props, scene)
        model = cycles.whitted(settings.max_depth)
        steps = tracer.trace_steps(scene, settings)
    elif technique == "ENVMAP":
        from ..kernels.envmap import envmap

        settings = tracer_settings(props, scene)
        model = cycles.whitted(settings.max_depth)
        steps = envmap.render_steps(scene, envmap_settings(props, [
            o.name for o in context.selected_objects if o.type == "MESH"]), settings)
    else:
        model = cycles.direct()
        steps = direct_light.render_steps(scene, direct_light_settings(props))
    result = yield from scaled(steps, 0.0, 0.7)
    image = result if not hasattr(result, "image") else result.image
    kernel_seconds = time.perf_counter() - start
    yield 0.7
    reference, cycles_seconds = cycles.render_camera(context.scene, model, samples)
    metrics, errors = compare_with_images(image, reference, settings=_metric_settings())
    # --- write back: images and figures ----------------------------------------------------------
    for name, pixels in ((KERNEL_IMAGE, image), (CYCLES_IMAGE, reference),
                         (ERROR_IMAGE, errors.rel_se[..., None])):
        bridge.write_image(name, pixels, image=bpy.data.images.get(name))
    props.compare_rel_mse = metrics.rel_mse
    props.compare_flip = metrics.flip if metrics.flip is not None else -1.0
    props.compare_kernel_seconds = kernel_seconds
    props.compare_cycles_seconds = cycles_seconds
    report({"INFO"}, f"Relative MSE {metrics.rel_mse:.3g} against Cycles at {samples} samples; "
                     f"kernel {kernel_seconds:.2f} s, Cycles {cycles_seconds:.2f} s")


class CLASSICBAKE_OT_compare(ScenePoll, JobOperator, bpy.types.Operator):
    """Render the kernel's view and Cycles' view of the same model, and show their difference"""

    bl_idname = "classic_bake.compare"
    bl_label = "Compare with Cycles"
    bl_options = {"REGISTER"}
    job_label = "Comparing with Cycles"
    needs = ("camera",)

    def start(self, context):
        props = context.scene.classic_bake
        return compare_job(context, props.compare_technique, props.compare_samples, self.report)


CLASSES = (CLASSICBAKE_OT_compare,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
