"""The one exception type for bad head and hairstyle files."""


class HairstyleError(ValueError):
    """A head or hairstyle file (or edit) that cannot be used; the message says why."""
