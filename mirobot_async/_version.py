"""The library's version (``mirobot_async.__version__``), in a module of its own so that the
modules that name it (a tape's header) need not import the package root, which imports them."""

__version__ = "0.1.0"
