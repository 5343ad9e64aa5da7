"""The 3D views in a browser (the ``view`` extra: viser and yourdfpy).

- :mod:`~mirobot_async._view.command`: ``mirobot view`` (the live twin and teach pendant; its
  ``--replay`` form scrubs a run that happened: :mod:`~mirobot_async._view.replay`);
- :mod:`~mirobot_async._view.watch`: ``arm.view()``, the view of a script's own connection
  (``mirobot run --view``, ``mirobot monitor --view``).

Only the modules that draw import viser; the pure ones (:mod:`~mirobot_async._view.preview`,
:mod:`~mirobot_async._view.script_lines`, :mod:`~mirobot_async._view.program`,
:mod:`~mirobot_async._view.timeline`, :mod:`~mirobot_async._view.teach`) are unit-tested alone.
"""
