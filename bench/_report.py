"""The header every ``bench/RESULTS_*.md`` opens with: date, command, machine.

    from _report import header
    lines = ["# Title (`bench/bench_x.py`)", "", *header(), "", table...]

The machines are shared: the machine line carries the load average when the file is
written, so that a contended run reads as one.
"""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import sys
from pathlib import Path

__all__ = ["header", "command", "machine", "cpu_model", "now"]


def now() -> str:
    """The local date and time to the second, ISO 8601."""
    return datetime.datetime.now().isoformat(timespec="seconds")


def command(argv: list[str] | None = None, script: str | None = None) -> str:
    """The command that ran: ``python bench/SCRIPT ARGS`` (default: this process's)."""
    name = script or Path(sys.argv[0]).name
    args = sys.argv[1:] if argv is None else list(argv)
    return " ".join(["python", f"bench/{name}", *map(shlex.quote, args)])


def cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo``)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "?"


def machine() -> str:
    """Platform, processor, cores, Python and the load average now (1/5/15 min)."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return (f"{platform.platform()}, {cpu_model()}, {os.cpu_count()} CPUs, Python "
            f"{platform.python_version()}; load average at the end {load[0]:.2f} / "
            f"{load[1]:.2f} / {load[2]:.2f} (1/5/15 min)")


def header(*, started: str | None = None, argv: list[str] | None = None,
           script: str | None = None, cmd: str | None = None, note: str = "",
           bullet: str = "*") -> list[str]:
    """The three lines ``date``, ``command``, ``machine`` of a results file.

    Args:
        started: the date (default: now); argv, script: as :func:`command`; cmd: the
            command line itself, where the script builds its own.
        note: appended to the machine line (e.g. how many jobs ran at once).
        bullet: the list marker (``*`` or ``-``).
    """
    line = machine() + (f"; {note}" if note else "")
    return [f"{bullet} date: {started or now()}",
            f"{bullet} command: `{cmd or command(argv, script)}`",
            f"{bullet} machine: {line}"]
