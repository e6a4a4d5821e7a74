"""Cycles' ray visibility of objects (Object > Visibility > Ray Visibility) as the kernels read
it: the ray kinds an object is hidden from (`hidden_from`, into `ObjectInfo.hidden_from` and
`Light.hidden_from`), and a note for each setting they do not model (`visibility_notes`)."""

from __future__ import annotations

# Cycles' per-object ray visibility (Object Properties > Visibility > Ray Visibility): what a
# mesh can be hidden from, and what a lamp's light can (a lamp object's other flags, camera and
# shadow catcher among them, are unused by Cycles and read False / True in a new file).
RAY_KINDS = {"MESH": ("camera", "diffuse", "glossy", "transmission", "shadow"),
             "LIGHT": ("diffuse", "glossy", "transmission")}


# The ray kinds every technique honours, per object type: a mesh's (`ObjectInfo.hidden_from`:
# the tracer's rays, the rasterised views' coverage, shadow maps' casters, radiosity's shadow
# rays), a lamp's (`Light.hidden_from`: the lobes it lights); others are noted.
MODELLED_KINDS = {"MESH": ("camera", "shadow"), "LIGHT": ("diffuse", "glossy")}
# A mesh's kinds the tracer honours alone (its reflected and refracted rays pass the object);
# the raster views' reflections and radiosity see it.
TRACED_KINDS = {"MESH": ("glossy", "transmission")}


def hidden_from(obj) -> tuple[str, ...]:
    """The ray kinds Cycles hides `obj` from (`RAY_KINDS` of its type whose visible_ flag is
    off); () for the defaults."""
    return tuple(kind for kind in RAY_KINDS.get(obj.type, ())
                 if not getattr(obj, f"visible_{kind}", True))


def visibility_notes(obj, hidden: tuple[str, ...]) -> list[str]:
    """What Cycles' visibility settings of `obj` (the rays it is `hidden` from) change that the
    kernels do not model, one note each; [] for the defaults."""
    traced = [kind for kind in hidden if kind in TRACED_KINDS.get(obj.type, ())]
    others = [kind for kind in hidden if kind not in MODELLED_KINDS.get(obj.type, ())
              and kind not in traced]
    notes = []
    if traced:
        notes.append(f"object '{obj.name}': Cycles hides it from {', '.join(traced)} rays; "
                     f"traced views do too, the other techniques' reflections see it")
    if others:
        notes.append(f"object '{obj.name}': Cycles hides it from {', '.join(others)} rays; "
                     f"not modelled, the kernels' rays of those kinds see it")
    if obj.type == "MESH":
        for flag, what in (("is_holdout", "a holdout"), ("is_shadow_catcher", "a shadow catcher")):
            if getattr(obj, flag, False):
                notes.append(f"object '{obj.name}': {what} in Cycles; not modelled, read as a "
                             f"surface")
    return notes
