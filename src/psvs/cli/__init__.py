"""The ``psvs`` command: one module per command (``<command>_cmd``), run by :func:`psvs.cli.main.main`."""
import lazy_loader as _lazy

# The package's public face: the command's entry point (``psvs.cli.main.main``, the ``psvs`` script).
__getattr__, __dir__, __all__ = _lazy.attach(__name__, submodules=["main"])
