"""flowvid for Blender: fabric presets on garments, flow-based video.

The add-on calls the flowvid library (the native `flowvid` module when it was
built for this Blender's Python, otherwise the `flowvid` command-line tool); it
does not re-implement it. core/locate.py finds them from wherever the add-on was
installed; its preferences can name them and test what is found.
`bl_info` serves Blender 3.4-4.1, `blender_manifest.toml` 4.2+ (same version). Code that needs no bpy lives in `core/` and is tested
with plain python3; Blender UI code lives in `blender/`.
"""

bl_info = {
    "name": "flowvid",
    "author": "flowvid developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Physics > Cloth (Fabric Preset, at the top); Properties > Particles > Flow Video",
    "description": "Fabric presets fitted from video, and flow-based video from particle systems",
    "category": "Physics",
}


def register():
    from .blender import registration

    registration.register()


def unregister():
    from .blender import registration

    registration.unregister()
