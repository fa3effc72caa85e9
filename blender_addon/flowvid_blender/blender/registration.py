"""Registers the add-on's classes symmetrically."""
import bpy

from . import operators, panels, preferences, properties

classes = preferences.classes + properties.classes + operators.classes + panels.classes


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    properties.register_properties()
    panels.register_menus()


def unregister():
    panels.unregister_menus()
    properties.unregister_properties()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
