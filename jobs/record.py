"""What a technique is, in one record: its options, how settings are made, its job, its Cycles model.

Operators, panel sections, scene properties, CLI commands, `compare` and `demo` are all made from
these records (jobs/techniques.py lists them), so a technique's settings are declared once:

* an `Option` names a field of a kernel settings dataclass; its default IS that field's default
  (read from the dataclass), or the option's `auto` value where 0 / -1 means "chosen from the
  scene";
* `Technique.settings(values, scene)` turns option values (from scene properties or from
  command-line arguments, the same dict either way) into the kernel settings;
* `Technique.start(context, values, resolution)` is the job: a step (kernels/progress.py) that
  snapshots the scene, runs the kernels, writes results back into Blender after its last yield
  (so closing it early leaves the scene as it was), and returns a `JobSummary`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

_NO_AUTO = object()


@dataclass(frozen=True)
class Option:
    """One user-facing setting, shown as a scene property and a command-line option.

    | field     | meaning                                                                    |
    |-----------|----------------------------------------------------------------------------|
    | name      | option name: CLI flag `--name` (underscores as dashes), property `prefix_name` |
    | owner     | the kernel settings dataclass whose field holds the default              |
    | field     | that field's name (default: `name`)                                       |
    | label     | the property's label in the panel                                        |
    | help      | one sentence: property description and CLI help                          |
    | auto      | a value meaning "chosen from the scene", used as the default instead      |
    | minimum, maximum, soft_max | the property's and the CLI's accepted range              |
    | choices   | (value, label, description) triples of an enumeration                    |
    | prop      | the scene property's name, where it differs from `prefix_name`            |
    | flag      | the CLI flag, where it differs from `--name`                               |
    | cli       | False: the option exists in the panel only                                 |
    """

    name: str
    owner: type
    label: str
    help: str
    field: str = ""
    auto: Any = _NO_AUTO
    minimum: float | None = None
    maximum: float | None = None
    soft_max: float | None = None
    choices: tuple[tuple[str, str, str], ...] = ()
    prop: str = ""
    flag: str = ""
    cli: bool = True

    @property
    def has_auto(self) -> bool:
        """True when the option has a value meaning "chosen from the scene"."""
        return self.auto is not _NO_AUTO

    @property
    def default(self) -> Any:
        """The option's default: `auto` where given, else the settings dataclass field's."""
        if self.has_auto:
            return self.auto
        spec = {f.name: f for f in dataclasses.fields(self.owner)}[self.field or self.name]
        if spec.default is not dataclasses.MISSING:
            return spec.default
        return spec.default_factory()  # type: ignore[misc]

    @property
    def kind(self) -> type:
        """bool, int, float or str (an enumeration when `choices` are given)."""
        value = self.default
        for kind in (bool, int, float, str):
            if isinstance(value, kind):
                return kind
        raise TypeError(f"option {self.name}: unsupported default {value!r}")

    def prop_name(self, prefix: str) -> str:
        return self.prop or f"{prefix}_{self.name}"

    def cli_flag(self) -> str:
        return self.flag or "--" + self.name.replace("_", "-")

    @property
    def dest(self) -> str:
        return self.cli_flag()[2:].replace("-", "_")


@dataclass
class JobSummary:
    """What a finished job did: what the operator reports, what the command line writes.

    `files` are extra outputs by relative path (EXR unless the name says .png), `metrics` the
    sections of metrics.json (settings, sizes, extra), `result` the technique's typed kernel
    result for callers that want more.
    """

    message: str
    scene: Any = None  # the kernel Scene the job read
    render: np.ndarray | None = None  # (H, W, 3) float32 linear: the camera view, or None
    images: dict[str, Any] = field(default_factory=dict)  # object name -> Blender image written
    attributes: list[str] = field(default_factory=list)  # objects given a colour attribute
    # object name -> (lightmap texels (H, W, 3) linear, mask (H, W) bool)
    lightmaps: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)  # one reason per object not written
    notes: list[str] = field(default_factory=list)  # what the kernels took otherwise than read
    files: dict[str, np.ndarray] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    sizes: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    result: Any = None


@dataclass(frozen=True)
class Technique:
    """One technique's record (see the module docstring).

    | field         | meaning                                                                 |
    |---------------|-------------------------------------------------------------------------|
    | name          | command name and key in `compare` ("trace")                             |
    | label         | panel section and compare menu label ("Ray Tracing")                    |
    | help          | one line: the CLI command's help and the operator's tooltip             |
    | options       | the technique's own options, in panel order                             |
    | settings      | (values, scene) -> kernel settings; scene is None before a snapshot     |
    | start         | (context, values, resolution) -> step returning a JobSummary            |
    | cycles_model  | (summary.settings) -> the matched Cycles model (addon/cycles)           |
    | ladder        | CLI arguments of the quality rungs `compare` runs, cheapest first      |
    | operator      | bl_idname, button label, icon, what the scene needs, undoable          |
    | shared        | options shared with other records (the lightmap options), before its own |
    | cli_extra     | extra argparse arguments (parser) -> None, for CLI-only switches        |
    | renders       | True: the CLI run must write render.exr (the camera view)               |
    | tiles         | what `--tile K/N` splits ("lightmaps", "rows", "faces"; "": none;       |
    |               | jobs/tiles.py)                                                          |
    | tile_prepare  | True: the tiles need `--tile prepare` run first (radiosity: the solve)  |
    | tile_merge    | (OUT/tiles folder, the tiles' metrics.json) -> the whole run's          |
    |               | JobSummary, for tiles `merge` cannot put together alone ("faces")       |
    """

    name: str
    label: str
    help: str
    options: tuple[Option, ...]
    settings: Callable[[dict, Any], Any]
    start: Callable[..., Any]
    operator: OperatorSpec
    cycles_model: Callable[[dict], Any] | None = None
    ladder: tuple[tuple[str, ...], ...] = ()
    shared: tuple[Option, ...] = ()
    cli_extra: Callable[[Any], None] | None = None
    renders: bool = True
    tiles: str = ""
    tile_prepare: bool = False
    tile_merge: Callable[..., Any] | None = None

    @property
    def prefix(self) -> str:
        """The scene properties' prefix ("trace" -> scene.classic_bake.trace_depth)."""
        return self.name.replace("-", "_")

    def all_options(self) -> tuple[Option, ...]:
        """The shared options, then the technique's own."""
        return self.shared + self.options

    def values_from_props(self, props) -> dict:
        """Option values from `scene.classic_bake`."""
        return {o.name: getattr(props, o.prop_name(self.prefix)) for o in self.all_options()}

    def values_from_args(self, args) -> dict:
        """Option values from parsed CLI arguments (panel-only options take their default)."""
        return {o.name: getattr(args, o.dest, o.default) if o.cli else o.default
                for o in self.all_options()}


@dataclass(frozen=True)
class OperatorSpec:
    """The Blender operator made from a record (operators/bake.py)."""

    idname: str
    label: str
    icon: str
    needs: tuple[str, ...] = ()  # "camera", "light", "mesh"
    undo: bool = True
