"""Interop tests: the client and the emulator with other people's software.

Third-party SDKs (the vendor's ``wlkata-mirobot-python`` 0.1.14, ``mirobot-py``, ``wlkatapython``
in a Python 3.10 venv built once from PyPI) drive the emulator unmodified, and ser2net serves an
emulator's pty over RFC 2217 and raw TCP to the real client. They need those tools installed, so
they run as their own command (README, ``.ci/run``); each skips with the reason when its tool is
missing, and ``MIROBOT_REQUIRE_SER2NET=1`` / ``MIROBOT_REQUIRE_THIRD_PARTY=1`` turn the skips into
failures. ``no_leftover_tasks`` (tests/conftest.py) checks that no task is left behind.
"""

from __future__ import annotations
