"""Fresh episode processes without paying the imports each time: a fork server.

An environment's episode must be the first simulation in its process (episode_process), and
starting Python and importing foldbot, SciPy and OpenCV took about half of a reset (1.0 of
1.9 s). The fork server is one child of the environment's process that imports the entry's
module once and never simulates; each episode is a `fork` of it, so it starts with every module
loaded and no simulation run, as a fresh process would. Linux only (fork, pidfd); where either
is missing, `ForkServer.available()` says so and the caller starts a fresh interpreter instead.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import select
import signal
import socket
import subprocess
import sys
import threading

_SERVER = "from foldbot.envs.fork_server import serve; serve"
"""What the server runs (`python -c`), given its control socket's descriptor and the entry."""
START_TIMEOUT_S = 120.0
"""Longest wall time (s) the server may take to import the entry's module and fork a child."""

_SERVERS: dict[tuple[int, str], ForkServer] = {}
"""The started servers, by (the process that started it, entry)."""
_SERVERS_LOCK = threading.Lock()


def serve(fd: int, entry: str) -> None:
    """The server: import `entry` ("module:function"), then for each socket descriptor sent
    over the control socket `fd`, fork a child that runs function(descriptor) and exits, and
    reply with the child's pid (8 bytes); until the caller closes the control socket."""
    module, name = entry.split(":")
    function = getattr(importlib.import_module(module), name)
    signal.signal(signal.SIGCHLD, signal.SIG_IGN)  # the kernel reaps the children
    control = socket.socket(fileno=fd)
    while True:
        try:
            message, fds, _flags, _address = socket.recv_fds(control, 1, 1)
        except OSError:
            break
        if not message or not fds:  # the caller went away
            break
        pid = os.fork()
        if pid == 0:  # the child: serve one episode, never return into the loop
            code = 1
            try:
                control.close()
                signal.signal(signal.SIGCHLD, signal.SIG_DFL)
                function(fds[0])
                code = 0
            finally:
                sys.stderr.flush()
                os._exit(code)
        os.close(fds[0])
        control.sendall(pid.to_bytes(8, "little"))


class ChildProcess:
    """A process the fork server made: not our child, so watched through a pidfd rather than
    waited on (its exit status goes to the server, which discards it: `exit_code` is None)."""

    exit_code = None

    def __init__(self, pid: int) -> None:
        self.pid = pid
        try:
            self._pidfd: int | None = os.pidfd_open(pid)
        except ProcessLookupError:  # already gone
            self._pidfd = None

    def ended(self, timeout: float = 0.0) -> bool:
        """Whether it has ended, waiting up to `timeout` s for it to."""
        if self._pidfd is None:
            return True
        ready, _, _ = select.select([self._pidfd], [], [], timeout)
        return bool(ready)

    def kill(self) -> None:
        if not self.ended():
            with contextlib.suppress(ProcessLookupError):
                signal.pidfd_send_signal(self._pidfd, signal.SIGKILL)

    def close(self) -> None:
        """Release the pidfd (the process itself is left as it is)."""
        if self._pidfd is not None:
            os.close(self._pidfd)
            self._pidfd = None


class ForkServer:
    """A started fork server for `entry` ("module:function", called with a socket descriptor in
    each child). Thread-safe; belongs to the process that made it (a forked caller makes its
    own: `for_entry`)."""

    @staticmethod
    def available() -> bool:
        """Whether this platform can run one (fork, descriptor passing and pidfds)."""
        return all(
            hasattr(m, a) for m, a in ((os, "fork"), (os, "pidfd_open"), (socket, "send_fds"))
        )

    @classmethod
    def for_entry(cls, entry: str) -> ForkServer:
        """This process's server for `entry`, started on first use and again if it has died."""
        with _SERVERS_LOCK:
            key = (os.getpid(), entry)
            server = _SERVERS.get(key)
            if server is None or server._process.poll() is not None:
                server = _SERVERS[key] = cls(entry)
            return server

    def __init__(self, entry: str) -> None:
        ours, theirs = socket.socketpair()
        with theirs:
            self._process = subprocess.Popen(
                [sys.executable, "-c", f"{_SERVER}({theirs.fileno()}, {entry!r})"],
                pass_fds=[theirs.fileno()],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,  # Bullet's banner, in every child
            )
        self._control = ours
        self._control.settimeout(START_TIMEOUT_S)
        self._lock = threading.Lock()

    def spawn(self, fd: int) -> ChildProcess:
        """A fresh child running the entry on (a duplicate of) socket descriptor `fd`."""
        with self._lock:
            try:
                socket.send_fds(self._control, [b"s"], [fd])
                reply = b""
                while len(reply) < 8:
                    chunk = self._control.recv(8 - len(reply))
                    if not chunk:
                        raise OSError("the fork server closed its socket")
                    reply += chunk
            except OSError as exc:  # includes a timeout
                self._process.kill()
                raise RuntimeError(
                    f"the fork server gave no child ({exc}); exit code {self._process.wait(5.0)}"
                ) from None
        return ChildProcess(int.from_bytes(reply, "little"))


class InterpreterProcess:
    """A child started as a fresh interpreter (where no fork server can run), with
    ChildProcess's interface."""

    def __init__(self, entry: str, fd: int) -> None:
        module, name = entry.split(":")
        self._popen = subprocess.Popen(
            [sys.executable, "-c", f"from {module} import {name} as f; f({fd})"],
            pass_fds=[fd],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,  # Bullet's banner
        )
        self.pid = self._popen.pid

    @property
    def exit_code(self) -> int | None:
        return self._popen.poll()

    def ended(self, timeout: float = 0.0) -> bool:
        try:
            self._popen.wait(timeout)
        except subprocess.TimeoutExpired:
            return False
        return True

    def kill(self) -> None:
        self._popen.kill()

    def close(self) -> None:
        self.ended(5.0)


def start(entry: str, fd: int) -> ChildProcess | InterpreterProcess:
    """A fresh process running `entry` ("module:function") on socket descriptor `fd`, that has
    run no simulation before: forked from this process's fork server where the platform allows,
    else a new interpreter."""
    if ForkServer.available():
        return ForkServer.for_entry(entry).spawn(fd)
    return InterpreterProcess(entry, fd)
