"""Thin operators: read settings, snapshot the scene, call kernels, write back."""

from . import lightmap_uv

_MODULES = (lightmap_uv,)


def register() -> None:
    for module in _MODULES:
        module.register()


def unregister() -> None:
    for module in reversed(_MODULES):
        module.unregister()
