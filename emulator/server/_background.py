"""A virtual Mirobot served from a background thread of this process (tests, notebooks)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from .loop import EmulatorServer
from .options import FirmwareLike, ServerOptions

if TYPE_CHECKING:
    from types import TracebackType

__all__ = ["VirtualMirobot"]


class VirtualMirobot:
    """A virtual Mirobot served from a background thread of this process.

    ::

        with VirtualMirobot(ServerOptions(firmware="classic", time_scale=0)) as robot:
            port = serial.serial_for_url(robot.path, 115200)
            robot.command("drop-ok 1")

    :attr:`path` is the pty's path, or ``socket://HOST:PORT`` with ``ServerOptions(listen=...)``.
    The firmware runs in the server thread: read :attr:`firmware` only for a quick look.
    """

    def __init__(
        self,
        options: ServerOptions | None = None,
        *,
        firmware_factory: Callable[[], FirmwareLike] | None = None,
    ) -> None:
        self.options = options or ServerOptions()
        self._server = EmulatorServer(self.options, firmware_factory=firmware_factory)
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self.result: str | None = None

    @property
    def path(self) -> str:
        """What clients open: the pty's path or ``socket://HOST:PORT``."""
        assert self._server.path is not None, "not started"
        return self._server.path

    @property
    def firmware(self) -> FirmwareLike | None:
        """The firmware model (for a quick look only: it runs in the server thread)."""
        return self._server.firmware

    @property
    def server(self) -> EmulatorServer:
        """The server (its counters: ``split_writes``, ``ports_opened``, ``firmware_errors``)."""
        return self._server

    def start(self) -> str:
        """Open the port and serve it from a daemon thread; return the address."""
        path = self._server.open()  # builds the firmware: errors surface in the caller
        self._thread = threading.Thread(target=self._run, name="mirobot-emulator", daemon=True)
        self._thread.start()
        return path

    def _run(self) -> None:
        try:
            self.result = self._server.serve()
        except BaseException as exc:  # reported by stop()
            self._error = exc

    def command(self, text: str, timeout: float = 5.0) -> str:
        """Run a control command in the server thread; return its answer (``ack ...``).

        Raises :class:`TimeoutError` if no answer comes within ``timeout`` seconds.
        """
        done = threading.Event()
        answers: list[str] = []

        def reply(answer: str) -> None:
            answers.append(answer)
            done.set()

        self._server.submit(text, reply)
        if not done.wait(timeout):
            raise TimeoutError(f"no answer to {text!r} within {timeout} s")
        return answers[0]

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the server thread (waiting up to ``timeout`` s) and release the port."""
        self._server.request_stop()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        self._server.close()
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def __enter__(self) -> VirtualMirobot:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
