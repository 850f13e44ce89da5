#!/usr/bin/env python3
"""A fault-injecting TCP proxy for the chaos soak (tests/soak/soak.py).

Listens on a loopback port and forwards each connection to a target. Per connection it draws one fate from a seeded
random generator: pass through, delay (every chunk held back a random time), reset (after a random number of bytes
the connection is closed with RST: SO_LINGER 0), or half-open (after a random number of bytes nothing more is
forwarded either way while both sockets stay open, until the client gives up or HOLD seconds pass). While
--faults-off FILE exists every connection passes through. --latency S holds every chunk S seconds in each direction
(chunks of one direction stay in order and are not held back by each other), as a link of round trip 2 S would; with
the fault shares at 0 it is a plain slow link, for measuring what round trips cost. Writes its port to --ready-file
and, on SIGTERM or SIGINT, the count of each fate as JSON to --stats-file.
"""
import argparse
import asyncio
import json
import random
import signal
import socket
import struct
import sys
from pathlib import Path

FATES = ("pass", "delay", "reset", "half_open")


def parse_args():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--target", required=True, help="HOST:PORT to forward to")
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--ready-file", required=True)
    p.add_argument("--stats-file", required=True)
    p.add_argument("--faults-off", required=True, help="while this file exists, no faults are injected")
    p.add_argument("--delay", type=float, default=0.3, help="share of connections delayed")
    p.add_argument("--reset", type=float, default=0.15, help="share of connections reset")
    p.add_argument("--half-open", type=float, default=0.05, help="share of connections left half-open")
    p.add_argument("--max-delay", type=float, default=0.5, help="longest delay per chunk, seconds")
    p.add_argument("--hold", type=float, default=45.0, help="longest a half-open connection is held, seconds")
    p.add_argument("--latency", type=float, default=0.0, help="one-way delay of every chunk, seconds")
    return p.parse_args()


class Proxy:
    def __init__(self, args):
        self.args = args
        host, port = args.target.rsplit(":", 1)
        self.target = (host, int(port))
        self.rng = random.Random(args.seed)
        self.counts = dict.fromkeys(FATES, 0)

    def draw(self):
        """The fate of one connection and the byte count after which a reset or half-open strikes."""
        if Path(self.args.faults_off).exists():
            return "pass", 0
        r = self.rng.random()
        a = self.args
        if r < a.reset:
            fate = "reset"
        elif r < a.reset + a.half_open:
            fate = "half_open"
        elif r < a.reset + a.half_open + a.delay:
            fate = "delay"
        else:
            fate = "pass"
        return fate, self.rng.randrange(0, 4096)

    async def handle(self, creader, cwriter):
        fate, after = self.draw()
        self.counts[fate] += 1
        try:
            sreader, swriter = await asyncio.open_connection(*self.target)
        except OSError:
            abort(cwriter)  # the coordinator is down: the client sees a reset, as it would without the proxy
            return
        budget = [after]  # bytes left before a reset or half-open strikes, shared by both directions
        struck = asyncio.Event()
        pumps = [asyncio.ensure_future(self.pump(creader, swriter, fate, budget, struck)),
                 asyncio.ensure_future(self.pump(sreader, cwriter, fate, budget, struck))]
        waiter = asyncio.ensure_future(struck.wait())
        await asyncio.wait(pumps + [waiter], return_when=asyncio.FIRST_COMPLETED)
        if struck.is_set() and fate == "half_open":
            for t in pumps:
                t.cancel()
            # Both sockets stay open and silent until the client closes its end or the hold ends.
            try:
                await asyncio.wait_for(creader.read(), timeout=self.rng.uniform(1.0, self.args.hold))
            except (asyncio.TimeoutError, OSError):
                pass
            for w in (cwriter, swriter):
                abort(w)
        elif struck.is_set():  # reset
            for t in pumps:
                t.cancel()
            for w in (cwriter, swriter):
                abort(w)
        else:
            await asyncio.wait(pumps)
            waiter.cancel()
            for w in (cwriter, swriter):
                w.close()

    async def pump(self, reader, writer, fate, budget, struck):
        if self.args.latency > 0:
            writer = Delayed(writer, self.args.latency)
        try:
            while not struck.is_set():
                data = await reader.read(65536)
                if not data:
                    if writer.can_write_eof():
                        writer.write_eof()
                    if isinstance(writer, Delayed):
                        await writer.sender  # what is still held goes out before the connection is closed
                    return
                if fate in ("reset", "half_open"):
                    if len(data) > budget[0]:
                        writer.write(data[: budget[0]])
                        await writer.drain()
                        struck.set()
                        return
                    budget[0] -= len(data)
                elif fate == "delay":
                    await asyncio.sleep(self.rng.uniform(0, self.args.max_delay))
                writer.write(data)
                await writer.drain()
        except (OSError, asyncio.CancelledError):
            return


class Delayed:
    """A stream writer whose writes reach the socket `latency` seconds after they were made, in order."""

    def __init__(self, writer, latency):
        self.writer = writer
        self.latency = latency
        self.queue = asyncio.Queue()
        self.sender = asyncio.ensure_future(self.send())

    async def send(self):
        loop = asyncio.get_running_loop()
        while True:
            due, data = await self.queue.get()
            await asyncio.sleep(max(0.0, due - loop.time()))
            if data is None:
                if self.writer.can_write_eof():
                    self.writer.write_eof()
                return
            self.writer.write(data)
            await self.writer.drain()

    def write(self, data):
        self.queue.put_nowait((asyncio.get_running_loop().time() + self.latency, data))

    async def drain(self):
        pass

    def can_write_eof(self):
        return True

    def write_eof(self):
        self.queue.put_nowait((asyncio.get_running_loop().time() + self.latency, None))

    def get_extra_info(self, name):
        return self.writer.get_extra_info(name)


def abort(writer):
    """Closes with RST (SO_LINGER 0) rather than FIN."""
    sock = writer.get_extra_info("socket")
    try:
        if sock is not None:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        writer.transport.abort()
    except OSError:
        pass


async def main():
    args = parse_args()
    proxy = Proxy(args)
    server = await asyncio.start_server(proxy.handle, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    Path(args.ready_file).write_text(f"{port}\n")
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)
    await stop.wait()
    server.close()
    Path(args.stats_file).write_text(json.dumps(proxy.counts) + "\n")


if __name__ == "__main__":
    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        sys.exit(0)
