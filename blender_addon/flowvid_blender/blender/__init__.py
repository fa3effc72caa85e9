"""Blender-facing part of the add-on (operators, panels, properties)."""
