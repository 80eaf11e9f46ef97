"""Lockstep's step calls over a socket of their own between the scenario process and its simulator.

A lockstep tick (:mod:`grader.sim.clock`, "Lockstep") is two calls to the simulator. As DDS
service calls (``~/step_clock``, ``~/step_world``) each one serializes a request, wakes the
simulator's receive thread and its executor, serializes a reply, wakes the scenario process's
receive thread and the stepper, which spins an rclpy executor for it. Measured on Lab 3's
``ex3_action`` (2,117 ticks, load ~2.5 on this 2-core machine): the stepper's thread alone spent
1.30 CPU s in those calls and the ticks 5.0-5.3 s of their 10.6-11.9 s of wall time waiting for
the two answers (``call_wall_s``). Over this channel a call is one ``send`` and one blocking
``recv`` on each side: see benchmarks/README.md ("A cheaper lockstep tick") for the numbers after.

The channel is a ``SOCK_SEQPACKET`` socket pair (one datagram per request and per answer, so
nothing needs framing) made by the scenario process (:func:`make_pair`): its end stays there,
not inheritable; the other is handed to the simulator alone (``pass_fds``, ``--step-fd``) and
closed in the scenario process at once. No student process inherits either end, no path names
them, and a jailed process (its own pid namespace) cannot see the simulator's descriptors; a
socket cannot be opened through ``/proc/<pid>/fd`` anyway (unlike a pipe).

In the simulator a thread of its own waits on the socket (asleep, so the quiet checks see it
rest) and hands each request to the executor (``create_task``): the step runs in the executor's
thread between callbacks, exactly where the service's callback ran, and answers the same text.
"""

from __future__ import annotations

import functools
import socket
import threading
from typing import Any, Callable

#: a request: a tick of simulated time, published on ``/clock`` (``~/step_clock`` with ``data`` true)
STEP_CLOCK = b"c"
#: a request: the world's step at that time, its poses published (``~/step_world``)
STEP_WORLD = b"w"
#: the longest answer ("<time, ns> <readers>")
_ANSWER_MAX = 256


class StepChannelError(RuntimeError):
    """The simulator did not answer over the channel (timed out, or its end is closed)."""


def make_pair() -> tuple[socket.socket, socket.socket]:
    """(the scenario process's end, the simulator's end); neither inheritable."""
    return socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)


class StepClient:
    """The stepper's end: one request, one answer, in the calling thread."""

    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock

    def call(self, request: bytes, wait_s: float) -> str:
        self._sock.settimeout(wait_s)
        try:
            self._sock.send(request)
            answer = self._sock.recv(_ANSWER_MAX)
        except OSError as exc:        # socket.timeout included
            raise StepChannelError(f"the simulator did not answer a step within {wait_s:g} s ({exc})") from exc
        if not answer:
            raise StepChannelError("the simulator closed its step channel")
        text = answer.decode()
        if text.startswith("error "):
            raise StepChannelError(f"the simulator failed a step: {text[6:]}")
        return text

    def close(self) -> None:
        self._sock.close()


class StepServer:
    """The simulator's end: ``serve(request) -> answer`` runs in the executor's thread
    (``post``: the executor's ``create_task``)."""

    def __init__(self, fd: int, serve: Callable[[bytes], str], post: Callable[[Callable[[], None]], Any]) -> None:
        self._sock = socket.socket(fileno=fd)
        self._serve = serve
        self._post = post
        self._thread = threading.Thread(target=self._receive, name="step-channel", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _receive(self) -> None:
        while True:
            try:
                request = self._sock.recv(16)
            except OSError:
                return
            if not request:            # the scenario process closed its end
                return
            self._post(functools.partial(self._answer, request))

    def _answer(self, request: bytes) -> None:
        try:
            answer = self._serve(request)
        except Exception as exc:  # noqa: BLE001 - told to the stepper, which gives the lockstep run up
            answer = f"error {type(exc).__name__}: {exc}"
        try:
            self._sock.send(answer.encode())
        except OSError:
            pass

    def close(self) -> None:
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._sock.close()
