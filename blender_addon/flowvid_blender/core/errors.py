"""The add-on's one error type for artists (bpy-free, so core/ can raise it)."""


class FlowvidError(RuntimeError):
    """A failure with a message meant for the artist."""
