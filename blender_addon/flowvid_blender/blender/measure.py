"""Text widths as Blender's UI draws them (the widget font at the current UI scale), in pixels."""
import blf
import bpy


def ui_scale():
    return bpy.context.preferences.system.ui_scale


def text_width(text):
    style = bpy.context.preferences.ui_styles[0].widget
    try:
        blf.size(0, style.points * ui_scale(), 72)  # Blender 3.x: size, dpi
    except TypeError:
        blf.size(0, style.points * ui_scale())  # 4.0+: no dpi
    return blf.dimensions(0, text)[0]
