"""Blender side: registration, the sidebar panel, properties, preferences, the scene bridge
(addon/bridge) and the Cycles side (addon/cycles).

Modules register their `CLASSES` tuples in order and unregister them in reverse. The interface
modules are imported when registering, so importing the bridge alone does not build them.
"""


def _modules():
    from . import panel, preferences, properties

    return (preferences, properties, panel)


def register() -> None:
    for module in _modules():
        module.register()


def unregister() -> None:
    for module in reversed(_modules()):
        module.unregister()
