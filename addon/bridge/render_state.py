"""The scene as Cycles renders it, read through the viewport's depsgraph.

Python has only the viewport's evaluated depsgraph (`Context.evaluated_depsgraph_get`), while
Cycles renders from one evaluated with render settings: a Subdivision Surface modifier at its
Render level (Blender's default modifier: 1 in viewports, 2 in renders), modifiers shown in
renders only, objects and collections disabled or hidden in viewports but not in renders,
curves at their render resolution, every particle where viewports show a share.
`render_state` copies those render settings onto their viewport twins while the snapshot reads
the depsgraph, and puts every value back afterwards (on errors too), so the kernels see the
geometry Cycles renders.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import bpy


@contextmanager
def render_state(scene, view_layer=None) -> Iterator[list[str]]:
    """Within the block, `scene`'s viewport settings are its render settings (see the module),
    in `view_layer` (default: the context's) for what view layers hide; restores every value
    on exit. Yields a list of the settings that could not be switched (linked library data:
    left as they are), one line each."""
    switched: list[tuple[object, str, object]] = []
    notes: list[str] = []

    def use(owner, attr: str, value, what: str) -> None:
        old = getattr(owner, attr)
        if old == value:
            return
        try:
            setattr(owner, attr, value)
        except (AttributeError, RuntimeError, TypeError):
            notes.append(f"{what}: its render setting could not be applied (linked data), the "
                         f"viewport's used")
            return
        switched.append((owner, attr, old))

    view_layer = view_layer or bpy.context.view_layer
    shown = []  # objects hidden in the view layer (the eye icon), shown meanwhile
    try:
        for collection in _collections(scene.collection):
            if collection.hide_viewport and not collection.hide_render:
                use(collection, "hide_viewport", False, f"collection '{collection.name}'")
        for layer in _layer_collections(view_layer.layer_collection):
            use(layer, "hide_viewport", False, f"collection '{layer.name}'")
        for obj in scene.objects:
            if obj.hide_viewport and not obj.hide_render:
                use(obj, "hide_viewport", False, f"object '{obj.name}'")
            if not obj.hide_render and obj.hide_get(view_layer=view_layer):
                obj.hide_set(False, view_layer=view_layer)
                shown.append(obj)
            # an object instancing particles, vertices or faces: shown itself as in renders
            use(obj, "show_instancer_for_viewport", obj.show_instancer_for_render,
                f"object '{obj.name}'")
            for mod in obj.modifiers:
                what = f"object '{obj.name}' modifier '{mod.name}'"
                use(mod, "show_viewport", mod.show_render, what)
                if mod.type in ("SUBSURF", "MULTIRES"):
                    use(mod, "levels", mod.render_levels, what)
            for system in getattr(obj, "particle_systems", ()):
                settings, what = system.settings, f"particle settings '{system.settings.name}'"
                use(settings, "display_percentage", 100, what)
                use(settings, "child_percent", settings.rendered_child_count, what)
            data = obj.data
            if obj.type in ("CURVE", "SURFACE", "FONT"):
                for axis in ("u", "v"):
                    render = getattr(data, f"render_resolution_{axis}")
                    if render > 0:  # 0: the viewport resolution renders too
                        use(data, f"resolution_{axis}", render, f"curve '{data.name}'")
            elif obj.type == "META" and data.render_resolution > 0:
                use(data, "resolution", data.render_resolution, f"metaball '{data.name}'")
        settings = scene.render
        if settings.use_simplify:
            use(settings, "simplify_subdivision", settings.simplify_subdivision_render,
                "scene simplify")
            use(settings, "simplify_child_particles", settings.simplify_child_particles_render,
                "scene simplify")
        yield notes
    finally:
        for obj in shown:
            obj.hide_set(True, view_layer=view_layer)
        for owner, attr, old in reversed(switched):
            setattr(owner, attr, old)


def _collections(root) -> Iterator:
    """Every collection under `root` (a scene's master collection), each once."""
    seen, stack = set(), list(root.children)
    while stack:
        collection = stack.pop()
        if collection.name_full not in seen:
            seen.add(collection.name_full)
            yield collection
            stack.extend(collection.children)


def _layer_collections(root) -> Iterator:
    """Every layer collection under `root` (a view layer's), depth first."""
    for child in root.children:
        yield child
        yield from _layer_collections(child)
