"""The example programs of mirobot-async (G-code programs and asyncio scripts).

Installed as the package ``mirobot_async._examples`` so that an installed copy has something to
run: ``mirobot demo`` lists and runs them (``mirobot demo square``, ``mirobot demo hello``), and
each script also runs as ``python -m mirobot_async._examples.hello``. In a source checkout they
are the files of ``examples/``.
"""
