"""Thin operators: one per technique record (bake.py), and the comparison with Cycles."""

from . import bake, compare

_MODULES = (bake, compare)


def register() -> None:
    for module in _MODULES:
        module.register()


def unregister() -> None:
    for module in reversed(_MODULES):
        module.unregister()
