"""A windowed Blender (under Xvfb) showing the add-on's panels at the default layout's width (test_panels.py runs it).

xvfb-run blender --factory-startup -noaudio --window-geometry 0 0 1920 1080 --python tests/blender/panels_session.py \
    -- OUT_DIR [EXTRA_LABEL]
For the Fabric Preset panel (a cotton preset loaded and applied) and the Flow Video panel it lays the
panel's draw function out with a recording layout that gives every item the width Blender's layout gives
it (rows share, property split 40/60, icons and text margins), measures each text with blf at the UI scale
and writes OUT_DIR/panels.json: every text with its width and room. Then it saves screenshots of the
Properties editor. EXTRA_LABEL adds a label to the Fabric panel (the test's check that a long one fails).
"""
import json
import os
import shutil
import sys
import tempfile
import traceback

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "blender_addon"))
EXAMPLE = os.path.join(REPO, "formats", "examples", "cotton.fabric.json")

# Blender 3.4's layout constants, in units of the UI scale (interface_intern.h, UI_interface.h):
UNIT = 20.0          # UI_UNIT_X: an icon button, the widget unit
TEXT_MARGIN = 0.4 * UNIT  # UI_TEXT_MARGIN_X, each side of a button's text
SPACE = 8.0          # style->buttonspacex between the items of an unaligned row
PANEL_SPACE = 8.0    # style->panelspace, each side of a panel's content
BOX_PADDING = 0.4 * UNIT  # a box's inner margin, each side (the Fabric Preset block is one)
SPLIT = 0.4          # UI_ITEM_PROP_SEP_DIVIDE: the property label's share of a split row


class Recorder:
    """Enough of bpy.types.UILayout to lay out the add-on's panels: every item gets a width as Blender's
    layout would give it; texts land in `texts` as (what, text, width in pixels, room in pixels)."""

    def __init__(self, width, scale, texts, measure, split=False):
        self.width, self.scale, self.texts, self.measure = width, scale, texts, measure
        self.use_property_split, self.use_property_decorate = split, True
        self.alignment = "EXPAND"
        self.children = []  # (kind, arguments) of a row, laid out when the row is closed by the caller's draw

    # -- containers: a row shares its width among its items; a column gives each its full width
    def _child(self, width):
        child = Recorder(width, self.scale, self.texts, self.measure, self.use_property_split)
        child.use_property_decorate = self.use_property_decorate
        return child

    def column(self, align=False, heading=""):
        return self._child(self.width)

    def box(self):
        return self._child(self.width - 2 * BOX_PADDING * self.scale)

    def split(self, factor=0.5, align=False):
        return _Split(self, factor)

    def row(self, align=False, heading=""):
        return _Row(self, align)

    def separator(self, factor=1.0):
        pass

    # -- items
    def _check(self, what, text, room):
        if text:
            self.texts.append({"what": what, "text": text, "width": self.measure(text), "room": room})

    def label(self, text="", icon="NONE", width=None):
        width = self.width if width is None else width
        room = width - 2 * TEXT_MARGIN * self.scale - (UNIT * self.scale if icon != "NONE" else 0.0)
        self._check("label", text, room)

    def operator(self, idname, text=None, icon="NONE", width=None):
        width = self.width if width is None else width
        if text is None:
            module, name = idname.split(".")
            text = getattr(bpy.types, "%s_OT_%s" % (module.upper(), name)).bl_label
        room = width - 2 * TEXT_MARGIN * self.scale - (UNIT * self.scale if icon != "NONE" else 0.0)
        self._check("operator " + idname, text, room)

    def prop(self, data, name, text=None, icon="NONE", width=None):
        width = self.width if width is None else width
        rna = data.bl_rna.properties[name]
        label = rna.name if text is None else text
        if self.use_property_split:
            # Label right-aligned in the left 40 %, the value in the rest (less the decorator column, if shown).
            value_width = width * (1.0 - SPLIT) - (UNIT * self.scale if self.use_property_decorate else 0.0)
            self._check("label of %s" % name, label, width * SPLIT - 2 * TEXT_MARGIN * self.scale)
        else:
            value_width = width
        if rna.type == "ENUM":
            # Every item may be shown: each must fit beside the drop-down arrow.
            for item in rna.enum_items:
                self._check("item of %s" % name, item.name, value_width - 2 * TEXT_MARGIN * self.scale
                            - UNIT * self.scale)
        elif not self.use_property_split and label:
            self._check("label of %s" % name, label, value_width - 2 * TEXT_MARGIN * self.scale)


class _Row(Recorder):
    """Items of a row share its width: icon-only buttons take one unit, the rest share what is left."""

    def __init__(self, parent, align):
        super().__init__(parent.width, parent.scale, parent.texts, parent.measure, parent.use_property_split)
        self.use_property_decorate = parent.use_property_decorate
        self.align = align
        self.items = []

    def _defer(self, kind, *arguments, **options):
        self.items.append((kind, arguments, options))
        self._layout()

    def label(self, text="", icon="NONE"):
        self._defer("label", text=text, icon=icon)

    def operator(self, idname, text=None, icon="NONE"):
        self._defer("operator", idname, text=text, icon=icon)

    def prop(self, data, name, text=None, icon="NONE"):
        self._defer("prop", data, name, text=text, icon=icon)

    def _layout(self):
        # Recomputed as items arrive: only the last layout's texts are kept.
        if not hasattr(self, "_start"):
            self._start = len(self.texts)
        del self.texts[self._start:]
        fixed = [(k, a, o) for k, a, o in self.items if k == "operator" and o.get("text") == ""]
        shared = [item for item in self.items if item not in fixed]
        gaps = 0.0 if self.align else SPACE * self.scale * (len(self.items) - 1)
        each = (self.width - gaps - UNIT * self.scale * len(fixed)) / max(len(shared), 1)
        for kind, arguments, options in shared:
            getattr(Recorder, kind)(self, *arguments, width=each, **options)


class _Split:
    def __init__(self, parent, factor):
        self.parent, self.factor, self.used = parent, factor, 0

    def _next(self):
        share = self.factor if self.used == 0 else 1.0 - self.factor
        self.used += 1
        return self.parent._child(self.parent.width * share)

    def row(self, align=False):
        return _Row(self._next(), align)

    def column(self, align=False):
        return self._next()

    def label(self, text="", icon="NONE"):
        self._next().label(text=text, icon=icon)


def properties_area():
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "PROPERTIES":
                return window, area, [r for r in area.regions if r.type == "WINDOW"][0]
    raise RuntimeError("no Properties editor in the default layout")


def measure_text(text):
    from flowvid_blender.blender import measure

    return measure.text_width(text)


def lay_out(draw, settings, region, extra=None):
    scale = bpy.context.preferences.system.ui_scale
    # The panel's content: the region less the panels' margins on both sides and the scrollbar.
    width = region.width - 2 * PANEL_SPACE * scale - 2 * 6 * scale
    texts = []
    layout = Recorder(width, scale, texts, measure_text)
    if draw.__name__ == "draw_fabric":
        layout = layout.box()  # as cloth_panel_top draws it
    draw(layout, settings)
    if extra:
        layout.label(text=extra)
    return {"region_width": region.width, "content_width": width, "ui_scale": scale, "texts": texts}


def scene_setup(folder):
    import flowvid_blender

    flowvid_blender.register()
    obj = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    obj.modifiers.new("Cloth", "CLOTH")
    obj.modifiers.new("Particles", "PARTICLE_SYSTEM")
    preset = os.path.join(folder, "cotton.fabric.json")
    shutil.copy(EXAMPLE, preset)
    assert bpy.ops.flowvid.load_fabric_preset(filepath=preset) == {"FINISHED"}
    assert bpy.ops.flowvid.apply_fabric_preset() == {"FINISHED"}
    bpy.context.scene.flowvid.emitter = obj
    return obj


def main():
    arguments = sys.argv[sys.argv.index("--") + 1:]
    out, extra = arguments[0], (arguments[1] if len(arguments) > 1 else None)
    folder = tempfile.mkdtemp(prefix="flowvid_panels_")
    state = {"step": 0}
    result = {}

    def step():
        try:
            from flowvid_blender.blender import panels

            window, area, region = properties_area()
            space = area.spaces.active
            if state["step"] == 0:
                obj = scene_setup(folder)
                space.context = "PHYSICS"
                result["fabric"] = lay_out(panels.draw_fabric, obj.flowvid, region, extra)
            elif state["step"] == 1:
                with bpy.context.temp_override(window=window, area=area, region=region):
                    bpy.ops.screen.screenshot_area(filepath=os.path.join(out, "fabric-preset-panel.png"))
                space.context = "PARTICLES"
                result["flow_video"] = lay_out(panels.draw_flow_video, bpy.context.scene.flowvid, region)
            elif state["step"] == 2:
                # The add-on's panel comes after Blender's particle panels: scroll to the end.
                with bpy.context.temp_override(window=window, area=area, region=region):
                    for _ in range(20):
                        bpy.ops.view2d.scroll_down(deltay=200)
            elif state["step"] == 3:
                with bpy.context.temp_override(window=window, area=area, region=region):
                    bpy.ops.screen.screenshot_area(filepath=os.path.join(out, "flow-video-panel.png"))
                result["blender"] = bpy.app.version_string
                with open(os.path.join(out, "panels.json"), "w") as handle:
                    json.dump(result, handle, indent=1)
                shutil.rmtree(folder, ignore_errors=True)
                bpy.ops.wm.quit_blender()
                return None
            state["step"] += 1
            return 1.0  # let the editor redraw before the next step
        except Exception:  # noqa: BLE001 - a failure ends Blender with code 1
            traceback.print_exc()
            os._exit(1)

    bpy.app.timers.register(step, first_interval=1.0)


main()
