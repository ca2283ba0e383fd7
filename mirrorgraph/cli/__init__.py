"""Command-line interface: a thin layer over the Python API; this package assembles it.

    mirrorgraph calibrate KEYPOINTS|VIDEO [--intrinsics FILE] --out calibration.json
    mirrorgraph detect VIDEO --out keypoints.json [--format openpose] [--every N ...]
    mirrorgraph synth --out DIR [--frames N --noise PX --outliers R ...]
    mirrorgraph demo
    mirrorgraph export calibration.json --to pose2sim|anipose OUT.toml
    mirrorgraph report calibration.json [KEYPOINTS] --out DIR
    mirrorgraph batch MANIFEST [--scheduler ADDRESS] [--workers N] [--out-dir DIR] [--summary FILE.json]
    mirrorgraph calibrate-rig RIG.toml --out calibration.toml [--with-virtual]
    mirrorgraph synth-rig KIND --out DIR
    mirrorgraph view CALIBRATION [--joints3d FILE] [--video FILE] [--save OUT.rrd]
    mirrorgraph live SOURCE [--intrinsics FILE | --image-size WxH] --jsonl OUT.jsonl [--view]

Every error that input can cause ends in one line ``error: ...`` on stderr and
exit status 2 (1 for an unexpected internal error; ``--debug`` shows its
traceback): I/O errors (a full disk, a missing folder) and damaged archives
included. Every output is checked before the work starts and moves into place at
the end of the run (:func:`mirrorgraph.io.atomic.staged_outputs`): a failed run
leaves the user's files as they were. Python's warnings are one ``warning:`` line.

What a run says: its summary on stdout, each warning once on stderr (neither under
``--quiet``: the warnings stay in the JSON the run writes), progress bars on stderr only when it is a terminal
(:mod:`mirrorgraph.progress`), and a last line naming what was written.
``calibrate --out c.json`` also keeps the run its figures are drawn from in
``c.report.npz`` (named in ``c.json``, see :mod:`mirrorgraph.report.store`), so
that ``report`` later draws the very figures ``calibrate --report`` draws.

One module per family of commands, each adding its parsers (``add_parsers``)
and running them (``cmd_*``): :mod:`.calibrate`, :mod:`.video` (``detect`` and
the video options), :mod:`.synth` (``synth``, ``demo``), :mod:`.report`
(``report``, ``export``), :mod:`.batch`, :mod:`.rig` (``calibrate-rig``,
``synth-rig``), :mod:`.view` (``view``, and ``--view`` of the calibrations), :mod:`.live`
(``live``); what they share (argument types, common options, how a run
speaks) is in :mod:`.args`; which module has which command, and each command's
one-line help, in :mod:`.commands`. Here: :func:`build_parser`, :func:`main` and the
exit statuses. A run imports the module of its own command only (``mirrorgraph
--help`` none of them): the others are listed by name and help.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
import zipfile
import zlib
from collections.abc import Collection

from .._version import __version__
from ..errors import MirrorgraphError
from ..progress import end_open_lines
from .args import error_message
from .commands import COMMANDS, HELP, MODULES

__all__ = ["EXIT_INPUT", "EXIT_INTERNAL", "build_parser", "main"]

EXIT_INPUT = 2
EXIT_INTERNAL = 1


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors, like every other error of the CLI."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(EXIT_INPUT, f"error: {self.prog}: {message} (see '{self.prog} --help')\n")


def build_parser(commands: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The ``mirrorgraph`` parser: every command with its options; or, given ``commands``,
    the options of those only (and of their modules' other commands), the others by name
    and help (:data:`.commands.COMMANDS`), their modules not imported."""
    parser = _Parser(
        prog="mirrorgraph",
        description="Calibrate a planar mirror's virtual camera from the people in the "
                    "video, and turn mirror videos into 3D motion.")
    parser.add_argument("--version", action="version", version=f"mirrorgraph {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    wanted = set(MODULES) if commands is None else {COMMANDS[c][0] for c in commands}
    for module in MODULES:
        if module in wanted:
            importlib.import_module(f"{__name__}.{module}").add_parsers(sub)
        else:
            for name, (of, _) in COMMANDS.items():
                if of == module:
                    sub.add_parser(name, help=HELP[name])
    return parser


def _command(argv: list[str]) -> str | None:
    """The command ``argv`` runs: its first word that is not an option (the parser's own
    options, ``--help`` and ``--version``, take no value), if it is one."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in COMMANDS else None


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mirrorgraph`` command; returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    command = _command(argv)
    # no command (--help, --version, a usage error): every command by name only
    parser = build_parser([command] if command else [])
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:          # --help, --version, or a usage error
        return exc.code if isinstance(exc.code, int) else EXIT_INPUT
    try:
        try:
            return _run(args)
        finally:
            end_open_lines()           # an error printed next starts on a line of its own
    except MirrorgraphError as exc:
        print(f"error: {error_message(exc)}", file=sys.stderr)
        return EXIT_INPUT
    except FileNotFoundError as exc:
        print(f"error: {exc.filename}: no such file or folder", file=sys.stderr)
        return EXIT_INPUT
    except (PermissionError, IsADirectoryError, NotADirectoryError) as exc:
        print(f"error: {exc.filename}: {exc.strerror}", file=sys.stderr)
        return EXIT_INPUT
    except BrokenPipeError:  # e.g. `mirrorgraph ... | head`: the reader left
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:   # a full disk, a quota, an I/O error: the file and the cause
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_INPUT
    except (zipfile.BadZipFile, zlib.error) as exc:
        print(f"error: a .npz file is damaged (not a complete zip archive: {exc})",
              file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("interrupted: nothing written (a run's files move into place at its end)",
              file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - last line of defence of the CLI
        if getattr(args, "debug", False):
            raise
        print(f"internal error: {type(exc).__name__}: {exc} (rerun with --debug and "
              "please report it)", file=sys.stderr)
        return EXIT_INTERNAL


def _run(args) -> int:
    """Run the command; Python's warnings (NumPy's on overflow or a division by zero)
    never reach the terminal one by one: a run that raised them says so in one
    ``warning:`` line (``--debug`` shows them all, where they were raised)."""
    if getattr(args, "debug", False):
        return int(args.func(args) or 0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)    # NumPy's floating-point ones
        code = int(args.func(args) or 0)      # an error: its one line, not the warnings
    if caught and not getattr(args, "quiet", False):
        first = caught[0]
        text = str(first.message).splitlines()[0] if str(first.message) else ""
        print(f"warning: {len(caught)} Python warning{'s' * (len(caught) != 1)} (the first: "
              f"{first.category.__name__}: {text}): a figure may be off; rerun with --debug "
              "to see where, and please report it", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
