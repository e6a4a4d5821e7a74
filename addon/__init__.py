"""Blender side: registration, panel, properties, preferences and the scene bridge."""
