"""Pure-Python part of the add-on: no bpy here, so it is tested with plain python3."""
