"""Blender side: registration, the sidebar panel, properties, preferences and the scene bridge.

Modules register their `CLASSES` tuples in order and unregister them in reverse.
"""

from . import panel, preferences, properties

_MODULES = (preferences, properties, panel)


def register() -> None:
    for module in _MODULES:
        module.register()


def unregister() -> None:
    for module in reversed(_MODULES):
        module.unregister()
