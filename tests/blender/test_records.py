"""The technique records: one declaration of each option feeds the scene property, the CLI option
and the kernel settings, so their defaults cannot disagree (jobs/record.py)."""

import dataclasses

import bpy
import pytest

from classic_bake.jobs.techniques import TECHNIQUES
from classic_bake.pipeline.arguments import technique_values
from classic_bake.pipeline.commands import COMMANDS

OPTIONS = [(t, o) for t in TECHNIQUES for o in t.all_options()]


def _field_default(option):
    spec = {f.name: f for f in dataclasses.fields(option.owner)}[option.field or option.name]
    return spec.default


@pytest.mark.parametrize("technique, option", OPTIONS,
                         ids=[f"{t.name}-{o.name}" for t, o in OPTIONS])
def test_property_and_cli_defaults_are_the_settings_default(addon, technique, option):
    props = bpy.context.scene.classic_bake
    prop_value = getattr(props, option.prop_name(technique.prefix))
    if not option.has_auto:
        assert option.default == _field_default(option)  # no "auto" value: the dataclass's own
    if isinstance(option.default, float):
        assert prop_value == pytest.approx(option.default, rel=1e-6, abs=1e-12)
    else:
        assert prop_value == option.default
    if option.cli:
        assert technique_values(technique, [])[option.name] == option.default


@pytest.mark.parametrize("technique", TECHNIQUES, ids=[t.name for t in TECHNIQUES])
def test_every_record_has_its_operator_panel_and_command(addon, technique):
    assert technique.name in COMMANDS
    category, name = technique.operator.idname.split(".")
    assert hasattr(getattr(bpy.ops, category), name)
    assert hasattr(bpy.types, f"CLASSICBAKE_PT_{technique.prefix}")
    # The defaults make valid kernel settings (scene-dependent ones are made after a snapshot).
    if technique.name not in ("trace", "bump"):
        technique.settings(technique.values_from_props(bpy.context.scene.classic_bake), None)


def test_cli_flags_reach_the_settings():
    from classic_bake.jobs.techniques import BY_NAME

    record = BY_NAME["radiosity"]
    values = technique_values(record, ["--patches", "37", "--no-final-gather", "--solver",
                                       "progressive", "--lightmap-size", "64"])
    settings = record.settings(values, None)
    assert (settings.patch_budget, settings.final_gather, settings.solver) == (37, False, "progressive")
    assert values["lightmap_size"] == 64
