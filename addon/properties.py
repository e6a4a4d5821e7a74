"""Per-scene settings (`scene.classic_bake`), edited in the sidebar: one property per option of
every technique record (jobs/techniques.py), its default the settings dataclass field's."""

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from ..jobs.techniques import TECHNIQUES


def option_property(option):
    """The bpy property of one record option."""
    common = {"name": option.label, "description": option.help}
    default = option.default
    if option.choices:
        return EnumProperty(items=list(option.choices), default=default, **common)
    if option.kind is bool:
        return BoolProperty(default=default, **common)
    limits = {key: value for key, value in (("min", option.minimum), ("max", option.maximum),
                                            ("soft_max", option.soft_max)) if value is not None}
    if option.kind is int:
        return IntProperty(default=default, **{k: int(v) for k, v in limits.items()}, **common)
    if option.kind is float:
        return FloatProperty(default=default, **{k: float(v) for k, v in limits.items()}, **common)
    return StringProperty(default=default, **common)


def option_properties() -> dict:
    """{property name: property} for every option of every technique (shared ones once)."""
    props = {}
    for technique in TECHNIQUES:
        for option in technique.all_options():
            props.setdefault(option.prop_name(technique.prefix), option_property(option))
    return props


COMPARE_PROPERTIES = {
    "compare_technique": EnumProperty(
        name="Technique", description="Which technique's camera view to compare with Cycles",
        items=[(t.name.upper(), t.label, t.help) for t in TECHNIQUES
               if t.renders and t.cycles_model is not None], default="TRACE"),
    "compare_samples": IntProperty(
        name="Cycles Samples", description="Samples of the Cycles render compared with",
        default=64, min=1, max=65536),
    # Results of the last comparison, shown in the panel (read-only in the interface).
    "compare_rel_mse": FloatProperty(name="Relative MSE", default=-1.0),
    "compare_flip": FloatProperty(name="HDR-FLIP", default=-1.0),
    "compare_kernel_seconds": FloatProperty(name="Kernel Seconds", default=0.0),
    "compare_cycles_seconds": FloatProperty(name="Cycles Seconds", default=0.0),
}

CLASSICBAKE_PG_settings = type("CLASSICBAKE_PG_settings", (bpy.types.PropertyGroup,), {
    "__annotations__": {**option_properties(), **COMPARE_PROPERTIES},
    "__doc__": "Classic Bake's per-scene settings",
})

CLASSES = (CLASSICBAKE_PG_settings,)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register() -> None:
    _register_classes()
    bpy.types.Scene.classic_bake = PointerProperty(type=CLASSICBAKE_PG_settings)


def unregister() -> None:
    del bpy.types.Scene.classic_bake
    _unregister_classes()
