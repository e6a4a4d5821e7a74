"""The scripted pipeline: the command line, its outputs, charts and reports (needs the pip bpy
module for commands that open scenes; charts and reports are plain Python)."""
