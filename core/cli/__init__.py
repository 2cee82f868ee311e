"""The headless command line: ``clm <command> ...`` (the top layer: it may import all of ``core``).

Each command is a module ``core/cli/<name>.py`` with ``register(sub)`` (adds its
subparser and ``set_defaults(func=run)``) and ``run(args) -> int``. Input errors
(``CLIError``, ``ValueError``, argparse usage errors) and what the machine refuses (``OSError``,
``MemoryError``) print one line ``clm: error: <message>`` on stderr and exit with code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from core.kinematics.memory import keep_freed_memory

# Command modules, in help order; each has register(sub) and run(args).
COMMANDS = ("presets", "simulate", "evaluate", "design", "compare", "study", "moea", "export", "scale")


class CLIError(Exception):
    """A user-facing error: printed as one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing usage and exiting, so errors stay one line."""

    def error(self, message: str) -> NoReturn:
        raise CLIError(f"{message} (see '{self.prog} --help')")


def path_arg(text: str) -> Path:
    """A file or folder named on the command line (argparse ``type``); refused when empty: ``Path("")`` is the
    current folder, and ``--svg ""`` read ". is a folder" (QA, session 36)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty; name a file")
    return Path(text)


def out_file(text: str | None, overwrite: bool) -> Path | None:
    """The ``--out FILE`` to write, or None to print (no ``--out``, or ``-``: standard output, as ``--design -`` reads
    standard input). Refused: an empty name, a folder, a file in no folder, an existing file without ``--overwrite``
    (lab rehearsal: a student's edited design, replaced), and ``--overwrite`` with nothing to replace."""
    if text is None or text == "-":
        if overwrite:
            raise CLIError("--overwrite replaces an existing --out FILE; without --out FILE the JSON is printed")
        return None
    if not text.strip():
        raise CLIError("--out is empty; name the output file, or leave --out out to print")
    out = Path(text)
    if out.is_dir():
        raise CLIError(f"--out {out} is a folder")
    if out.exists() and not overwrite:
        raise CLIError(f"--out {out} exists; pass --overwrite to replace it, or give another file")
    if not out.parent.is_dir():
        raise CLIError(f"cannot write {out}: there is no folder {out.parent}")
    return out


def version_text() -> str:
    """``clm 0.1.0 (code 809c5bd51018)``: the installed package's version and ``core.CODE_DIGEST``, which study cells
    and ``clm evaluate --json`` record (rehearsal 8: a CI log could not say which CLM had run)."""
    from importlib.metadata import PackageNotFoundError, version

    from core import CODE_DIGEST

    try:
        v = version("clm-studio")
    except PackageNotFoundError:
        v = "(not installed)"
    return f"clm {v} (code {CODE_DIGEST})"


def build_parser() -> argparse.ArgumentParser:
    import importlib

    parser = _Parser(prog="clm", description="CLM Studio headless tools: presets, kinematics, optimization.")
    parser.add_argument("--version", action="version", version=version_text(),
                        help="print the package version and the code digest results record, and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        importlib.import_module(f"core.cli.{name}").register(sub)
    _name_help(parser)
    return parser


def _name_help(parser: argparse.ArgumentParser) -> None:
    """Each (sub)command records its own name, so an argument it does not know points to its own help (``clm
    presets show a b`` pointed to 'clm --help', which lists no argument of ``show``; QA, session 36)."""
    parser.set_defaults(help_prog=parser.prog)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _name_help(child)


def jsonable(value: Any) -> Any:
    """Arrays and numpy scalars -> plain lists and floats; NaN and +-inf -> None (JSON has neither)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "f":
            out = value.astype(object)
            out[~np.isfinite(value)] = None
            return out.tolist()
        return value.tolist()
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def dumps(obj: dict[str, Any]) -> str:
    """JSON text with one top-level key per line (``| head`` shows the summary keys first)."""
    lines = [
        f"  {json.dumps(k)}: {json.dumps(jsonable(v), separators=(',', ':'), allow_nan=False)}" for k, v in obj.items()
    ]
    return "{\n" + ",\n".join(lines) + "\n}"


PRESET_ACTIONS = ("list", "show")


def named_show(argv: list[str]) -> list[str]:
    """``clm presets NAME`` read as ``clm presets show NAME``: a preset's name is the first thing one types, and
    argparse answered "invalid choice: 'stephenson1/X3' (choose from 'list', 'show')"."""
    k = next((j for j, a in enumerate(argv) if not a.startswith("-")), -1)  # the subcommand
    if k >= 0 and argv[k] == "presets" and k + 1 < len(argv) and not argv[k + 1].startswith("-") \
            and argv[k + 1] not in PRESET_ACTIONS:
        return [*argv[: k + 1], "show", *argv[k + 1 :]]
    return argv


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``clm`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    keep_freed_memory()
    try:
        words = named_show(list(sys.argv[1:] if argv is None else argv))
        args, extra = build_parser().parse_known_args(words)
        if extra:  # given before the subcommand: clm's own (review of session 37)
            before = words.index(extra[0]) < words.index(args.command) if args.command in words else False
            raise CLIError(f"unrecognized arguments: {' '.join(extra)} (see '{'clm' if before else args.help_prog} "
                           "--help')")
        return int(args.func(args))
    except (CLIError, ValueError) as e:
        print(f"clm: error: {e}", file=sys.stderr)
        return 2
    except SystemExit as e:  # --help and --version exit through argparse
        return e.code if isinstance(e.code, int) else 0
    except BrokenPipeError:
        # The reader (head, less) went away: stop quietly, like other Unix tools.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except OSError as e:  # a file that cannot be written or read after the checks, a full disk, a network error
        where = f": {e.filename}" if e.filename else ""
        print(f"clm: error: {e.strerror or e}{where}", file=sys.stderr)
        return 2
    except MemoryError as e:  # sizes inside the checked ranges can still outgrow this machine's memory
        print(f"clm: error: not enough memory for this run ({e or 'MemoryError'}); use a smaller population, "
              "budget or number of samples", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


__all__ = ["COMMANDS", "CLIError", "build_parser", "dumps", "jsonable", "main", "out_file"]
