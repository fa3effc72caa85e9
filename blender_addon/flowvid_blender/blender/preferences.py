"""Add-on preferences: where the flowvid tool and native module are, and a Test button saying what is found."""
import bpy
from bpy.props import StringProperty

from .. import library


def _changed(_self, _context):
    library.reset()


class FLOWVID_OT_test_library(bpy.types.Operator):
    """Look for the flowvid module and tool as the add-on will, and say what was found and which is used"""
    bl_idname = "flowvid.test_library"
    bl_label = "Test"
    bl_options = {"REGISTER", "INTERNAL"}

    def execute(self, context):
        found = library.discover()
        lines = []
        if found["module"]:
            lines.append("Module: %s (%s)" % (found["module_version"] or "no version", found["module"]))
        else:
            lines.append("Module: none for Python %s" % found["python"])
        lines += ["Module not usable: %s" % error for error in found["module_errors"]]
        lines.append("Tool: %s (%s)" % (found["tool_version"], found["tool"]) if found["tool"] else "Tool: none")
        backend = {"native": "the module, in Blender's Python", "cli": "the flowvid tool"}.get(found["backend"])
        lines.append("Uses: %s" % backend if backend else "Uses: nothing: flowvid is not available")
        prefs = library.preferences()
        if prefs is not None:
            prefs.last_test = "\n".join(lines)
        for line in lines:
            self.report({"INFO"}, line)
        if found["backend"] is None:
            self.report({"ERROR"}, "flowvid is not available: set the tool or module path")
            return {"CANCELLED"}
        return {"FINISHED"}


class FlowvidPreferences(bpy.types.AddonPreferences):
    bl_idname = library.ADDON_PACKAGE

    tool_path: StringProperty(name="flowvid Tool", subtype="FILE_PATH", update=_changed,
                              description="The flowvid command-line tool (empty: the one installed with the add-on, "
                                          "else `flowvid` on the PATH)")
    module_dir: StringProperty(name="Native Module", subtype="DIR_PATH", update=_changed,
                               description="Folder holding the flowvid Python module built for Blender's Python "
                                           "(empty: the one in the add-on's zip, else the installed one)")
    last_test: StringProperty(name="Last test", description="What Test found, one line per item")

    def draw(self, _context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "tool_path")
        layout.prop(self, "module_dir")
        row = layout.row()
        row.operator(FLOWVID_OT_test_library.bl_idname, icon="CHECKMARK")
        if self.last_test:
            box = layout.box()
            for line in self.last_test.split("\n"):
                box.label(text=line)


classes = (FLOWVID_OT_test_library, FlowvidPreferences)
