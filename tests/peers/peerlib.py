"""Shared helpers of bench's independent protocol peers (tests/peers/*.py).

The peers are written from public device facts only, never from bench's Rust codecs: a
misreading of a protocol in bench then shows up as a disagreement instead of being made twice.
Each peer

* serves one device on a loopback TCP port chosen by the OS or on a pseudo-terminal it opens
  itself (the peer keeps the slave end open too, so the master never sees a hang-up between
  clients);
* prints ONE ready line on stdout, a JSON object: {"ready": NAME, "tcp": "127.0.0.1:PORT"} or
  {"ready": NAME, "pty": "/dev/pts/N"}, and nothing else on stdout;
* writes every request it receives (and what it answered) to a JSON-lines log (--log), flushed
  line by line, so a test can read it at any time;
* runs its physics on bench time = wall time x --time-scale;
* exits when its standard input closes (the test that started it ended) or on SIGTERM.

Coupled peers (a bench that behaves like one: the gyro senses the table's rate and the chamber's
air) share their physical state through small state files (`StateFile`): the table and chamber
peers rewrite theirs (`--state FILE`) as their physics advances, stamped with the host's
monotonic clock, and the gyro peer reads them for each sample. No peer reads another's protocol.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import sys
import time
import tty


class Clock:
    """Bench time: seconds since start x scale."""

    def __init__(self, scale: float = 1.0) -> None:
        if not scale > 0:
            raise ValueError(f"time scale must be positive, got {scale}")
        self.scale = scale
        self.t0 = time.monotonic()

    def now(self) -> float:
        return (time.monotonic() - self.t0) * self.scale

    def wall(self, bench_s: float) -> float:
        """Wall seconds for `bench_s` bench seconds."""
        return bench_s / self.scale

    def mono(self, bench_s: float) -> float:
        """The time.monotonic() of bench time `bench_s`."""
        return self.t0 + bench_s / self.scale


class Log:
    """JSON-lines command log; each entry gets the bench time `t`."""

    def __init__(self, path: str | None, clock: Clock) -> None:
        self.clock = clock
        self.f = open(path, "a", encoding="utf-8") if path else None

    def write(self, **entry) -> None:
        if self.f is None:
            return
        entry = {"t": round(self.clock.now(), 4), **entry}
        self.f.write(json.dumps(entry, sort_keys=True) + "\n")
        self.f.flush()


class StateFile:
    """One JSON object a peer publishes for coupled peers, replaced atomically (write to a
    temporary file, then rename), with `mono`: the time.monotonic() the state holds at (the
    host's CLOCK_MONOTONIC, shared by every process of the host). It is the state's own time,
    `Clock.mono(t)`, not the time of writing: a peer descheduled between computing its state
    and writing it would otherwise stamp it late."""

    def __init__(self, path: str | None) -> None:
        self.path = path

    def write(self, mono: float, **state) -> None:
        if not self.path:
            return
        tmp = f"{self.path}.tmp{os.getpid()}"
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"mono": mono, **state}, f)
        os.replace(tmp, self.path)

    @staticmethod
    def read(path: str) -> dict | None:
        """The last state published at `path`, or None if there is none yet."""
        try:
            with open(path, encoding="utf-8") as f:
                return json.load(f)
        except (OSError, ValueError):
            return None


def base_args(description: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--log", help="JSON-lines log of every request (default: none)")
    p.add_argument(
        "--time-scale", type=float, default=1.0, help="bench time per wall time (default 1)"
    )
    return p


def ready(name: str, **where) -> None:
    """Announce where the peer listens: the one line a test waits for."""
    sys.stdout.write(json.dumps({"ready": name, **where}) + "\n")
    sys.stdout.flush()


class Pty:
    """A pseudo-terminal pair in raw mode: the peer serves on `master`; clients open `path`.

    The peer also keeps the slave open, so that the master reads never fail with EIO after a
    client closes the slave (a real serial port does not hang up either).
    """

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)


class PtyStream:
    """Asyncio byte stream on a pty master: `await read()`, `write(bytes)`."""

    def __init__(self, pty: Pty) -> None:
        self.fd = pty.master
        self.loop = asyncio.get_running_loop()
        self.queue: asyncio.Queue[bytes] = asyncio.Queue()
        self.loop.add_reader(self.fd, self._readable)

    def _readable(self) -> None:
        try:
            data = os.read(self.fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if data:
            self.queue.put_nowait(data)

    async def read(self) -> bytes:
        return await self.queue.get()

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.fd, view)
                view = view[n:]
            except BlockingIOError:
                # The client is not reading: a real line would drop bytes too, but a test wants
                # them, so wait for room.
                time.sleep(0.001)


async def run_until_stdin_closes(*tasks) -> None:
    """Run until stdin reaches EOF or SIGTERM/SIGINT arrives; then cancel `tasks`."""
    loop = asyncio.get_running_loop()
    done = loop.create_future()

    def finish(*_):
        if not done.done():
            done.set_result(None)

    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, finish)

    def stdin_readable():
        try:
            data = os.read(sys.stdin.fileno(), 1024)
        except OSError:
            data = b""
        if not data:
            loop.remove_reader(sys.stdin.fileno())
            finish()

    loop.add_reader(sys.stdin.fileno(), stdin_readable)
    await done
    for t in tasks:
        t.cancel()


class LineServer:
    """Serves a line protocol on TCP (loopback, OS-chosen port) or a pty.

    `handler(line: str) -> str | None` gets each request line without its terminator and returns
    the reply line (with terminator) or None for no reply. `terminators` are the bytes that end a
    request (a `\\r` before `\\n` is stripped).
    """

    def __init__(self, handler, terminator: bytes = b"\n", max_line: int = 4096) -> None:
        self.handler = handler
        self.terminator = terminator
        self.max_line = max_line

    def _split(self, buf: bytearray):
        while True:
            i = buf.find(self.terminator)
            if i < 0:
                if len(buf) > self.max_line:
                    buf.clear()
                return
            raw = bytes(buf[:i])
            del buf[: i + len(self.terminator)]
            yield raw.rstrip(b"\r").decode("ascii", errors="replace")

    async def serve_tcp(self, name: str) -> asyncio.AbstractServer:
        async def client(reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
            buf = bytearray()
            try:
                while data := await reader.read(4096):
                    buf += data
                    for line in self._split(buf):
                        reply = self.handler(line)
                        if reply is not None:
                            writer.write(reply.encode("ascii"))
                            await writer.drain()
            except (ConnectionError, asyncio.CancelledError):
                pass
            finally:
                writer.close()

        server = await asyncio.start_server(client, "127.0.0.1", 0)
        host, port = server.sockets[0].getsockname()[:2]
        ready(name, tcp=f"{host}:{port}")
        return server

    async def serve_pty(self, name: str) -> None:
        pty = Pty()
        stream = PtyStream(pty)
        ready(name, pty=pty.path)
        buf = bytearray()
        while True:
            buf += await stream.read()
            for line in self._split(buf):
                reply = self.handler(line)
                if reply is not None:
                    stream.write(reply.encode("ascii"))
