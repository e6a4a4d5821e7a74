"""Thin operators: read settings, snapshot the scene, call kernels, write back."""

from . import bump, compare, envmap, lightmap_uv, radiosity, shadowmap, texture, trace

_MODULES = (lightmap_uv, texture, trace, envmap, bump, shadowmap, radiosity, compare)


def register() -> None:
    for module in _MODULES:
        module.register()


def unregister() -> None:
    for module in reversed(_MODULES):
        module.unregister()
