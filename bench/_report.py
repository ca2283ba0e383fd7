"""The header every ``bench/RESULTS_*.md`` opens with: date, command, machine (and code).

    from _report import header
    lines = ["# Title (`bench/bench_x.py`)", "", *header(), "", table...]
    lines = [..., *header(code=True), ...]      # a fourth line: the commit measured

:func:`emit` prints the report's lines and writes them to the results file.

A script that saves its figures (JSON) and can write the report again from them saves
:func:`record` beside the figures and heads the report with :func:`recorded_header`: the
report written again carries the run's date, command and machine, not today's.

The machines are shared: the machine line carries the load average when the file is
written, so that a contended run reads as one.
"""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import subprocess
import sys
from pathlib import Path

__all__ = ["header", "command", "machine", "cpu_model", "now", "code_state", "record",
           "recorded_header", "emit", "NOT_RECORDED"]

#: What :func:`recorded_header` says of a line the saved data lack.
NOT_RECORDED = "not recorded with the figures"

ROOT = Path(__file__).resolve().parent.parent


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


def code_state(root: Path = ROOT) -> str:
    """The commit of ``root`` and its uncommitted files under ``mirrorgraph/``.

    Read-only git calls (``--no-optional-locks``: a bench running beside a commit does
    not take the index lock); ``"unknown"`` outside a git checkout.
    """
    try:
        rev = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, check=True).stdout.strip()
        st = subprocess.run(["git", "--no-optional-locks", "-C", str(root), "status",
                             "--porcelain", "--", "mirrorgraph"],
                            capture_output=True, text=True, check=True).stdout.splitlines()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    changed = [x[3:] for x in st if x.strip()]
    return rev + (f" plus uncommitted changes to {', '.join(changed)}" if changed else "")


def header(*, started: str | None = None, argv: list[str] | None = None,
           script: str | None = None, cmd: str | None = None, note: str = "",
           bullet: str = "*", machine_line: str | None = None,
           code: bool | str = False) -> list[str]:
    """The lines ``date``, ``command``, ``machine`` (and ``code``) of a results file.

    Args:
        started: the date (default: now); argv, script: as :func:`command`; cmd: the
            command line itself, where the script builds its own.
        note: appended to the machine line (e.g. how many jobs ran at once).
        bullet: the list marker (``*`` or ``-``).
        machine_line: the machine line as recorded with the figures (a report written
            again from saved data); default :func:`machine` now.
        code: ``True``: a fourth line, the commit measured (:func:`code_state`); a string:
            that line's text as recorded.
    """
    line = (machine_line or machine()) + (f"; {note}" if note else "")
    lines = [f"{bullet} date: {started or now()}",
             f"{bullet} command: `{cmd or command(argv, script)}`",
             f"{bullet} machine: {line}"]
    if code:
        state = code_state() if code is True else code
        lines.append(f"{bullet} code: mirrorgraph at commit {state}")
    return lines


def record(*, argv: list[str] | None = None, script: str | None = None, cmd: str | None = None,
           code: bool = False) -> dict[str, str]:
    """``{"date", "command", "machine"}`` (and ``"code"``) of this run, as :func:`header`
    writes them: to save with the figures (arguments as :func:`header`'s)."""
    out = {"date": now(), "command": cmd or command(argv, script), "machine": machine()}
    if code:
        out["code"] = code_state()
    return out


def recorded_header(meta: dict, *, note: str = "", bullet: str = "*") -> list[str]:
    """:func:`header`'s lines from a run's saved :func:`record` (``meta``): its date,
    command, machine and code; :data:`NOT_RECORDED` for those ``meta`` lacks (never the
    date or machine of the day the report is written again)."""
    return header(started=meta.get("date") or NOT_RECORDED,
                  cmd=meta.get("command") or NOT_RECORDED,
                  machine_line=meta.get("machine") or NOT_RECORDED, note=note, bullet=bullet,
                  code=meta.get("code") or False)


def emit(lines: list[str], out: str | Path | None) -> str:
    """The report's ``lines`` printed and, with ``out``, written there (one trailing
    newline); returns the text."""
    text = "\n".join(lines) + "\n"
    print(text)
    if out:
        Path(out).write_text(text)
    return text
