#!/usr/bin/env python3
"""Run Klipper's klippy.py in batch mode so that its output file holds every message.

Usage: klippy_drained.py KLIPPY_DIR [klippy.py's arguments...]

Why: in batch mode (-o FILE) Klipper's host hands each MCU message to its serial
queue, whose own thread (chelper/serialqueue.c) writes it to the file. At the end
of the input klippy exits, and serialqueue_exit() stops that thread at once: what
it has not written yet (its "ready" and "upcoming" queues) is freed, never written.
On an idle machine the thread keeps up; on a busy one it does not. Measured here
(2 cores, 8 busy loops and a disk writer beside it, the toggle program of
klipper_batch.py, 30 runs): 28 runs exited with bytes still queued, 4 of them with
the whole stream (6,486 bytes: not one step in the file). CI saw it as a stream
that ended moves early (an IndexError on the rests, 2026-12).

This launcher changes nothing in Klipper's code: before Klipper's own disconnect
it waits until the queue reports nothing ready and nothing upcoming, then lets
klippy go on exactly as it would. If the queue does not drain within
DRAIN_LIMIT_S, it says so on stderr and exits with status 3, so a truncated file
is never taken for Klipper's output.
"""

from __future__ import annotations

import os
import re
import sys
import time

# the thread writes a run's ~10 kB in ms once it gets a core; the environment may
# shorten the wait (the launcher's own tests do)
DRAIN_LIMIT_S = float(os.environ.get("ABBE_KLIPPY_DRAIN_S", "120"))
POLL_S = 0.01
EXIT_NOT_DRAINED = 3

_QUEUED = re.compile(r"\b(ready_bytes|upcoming_bytes)=(\d+)")


def queued_bytes(stats: str) -> int:
    """Bytes the serial queue still holds, from SerialReader.stats()'s text
    (its ready_bytes + upcoming_bytes fields; both must be present)."""
    fields = dict(_QUEUED.findall(stats))
    if set(fields) != {"ready_bytes", "upcoming_bytes"}:
        raise ValueError(f"serial queue stats without ready_bytes/upcoming_bytes: {stats!r}")
    return int(fields["ready_bytes"]) + int(fields["upcoming_bytes"])


def main() -> int:
    if len(sys.argv) < 2:
        sys.stderr.write(__doc__.split("\n\n")[1] + "\n")
        return 2
    klippy_dir = os.path.abspath(sys.argv[1])
    sys.path.insert(0, klippy_dir)
    import serialhdl  # Klipper's, from KLIPPY_DIR

    disconnect = serialhdl.SerialReader.disconnect

    def give_up(why: str) -> None:
        # os._exit, not an exception: klippy runs its disconnect handlers under a bare
        # `except` that logs and goes on, which would exit 0 with the file incomplete
        sys.stderr.write(f"klippy_drained: {why}: the output file may be incomplete\n")
        sys.stderr.flush()
        os._exit(EXIT_NOT_DRAINED)

    def drained_disconnect(reader):
        if reader.serialqueue is not None:
            deadline = time.monotonic() + DRAIN_LIMIT_S
            try:
                left = queued_bytes(reader.stats(0.0))
                while left and time.monotonic() < deadline:
                    time.sleep(POLL_S)
                    left = queued_bytes(reader.stats(0.0))
            except ValueError as exc:
                give_up(str(exc))
            if left:
                give_up(f"the serial queue still holds {left} bytes after {DRAIN_LIMIT_S:.0f} s")
        disconnect(reader)

    serialhdl.SerialReader.disconnect = drained_disconnect
    sys.argv = [os.path.join(klippy_dir, "klippy.py")] + sys.argv[2:]
    import klippy  # Klipper's main module, run as `python klippy.py ...` would

    klippy.main()
    return 0


if __name__ == "__main__":
    sys.exit(main())
