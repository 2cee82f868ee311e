"""``clm presets``: list the named designs, or show one as a design JSON."""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from typing import Any

from core.cli import out_file
from core.formats.design import design_to_dict
from core.formats.files import atomic_write
from core.kinematics import presets


def preset_dict(p: presets.Preset) -> dict[str, Any]:
    """A preset in the design JSON format plus its name, title and source."""
    d = design_to_dict(p.design())
    return {"name": p.name, "title": p.mechanism.title, **d, "source": p.source}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "presets",
        help="list presets, or show one as JSON",
        description="List the named designs (paper rows, reference walkers), or show one as a design JSON "
        "that 'clm simulate --design' reads back.",
    )
    p.add_argument("--json", action="store_true", help="list every preset as JSON")
    p.add_argument("--wide", action="store_true", help="print every source whole (in a terminal they are cut to "
                                                        "its width)")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    # Its own dest: the subcommand's default would overwrite `clm presets --json list`'s flag.
    actions.add_parser("list", help="list presets (the default)").add_argument(
        "--json", dest="list_json", action="store_true", help="list every preset as JSON"
    )
    show = actions.add_parser("show", help="print one preset as a design JSON")
    show.add_argument("name", help="preset name, e.g. stephenson1/X3")
    # Taken, as every other command takes --json after its arguments (rehearsal 8): show prints JSON anyway.
    show.add_argument("--json", dest="show_json", action="store_true", help="print it as JSON (always does)")
    show.add_argument("--out", metavar="FILE",
                      help="write it to FILE (only once the name is found; an existing FILE is kept unless "
                           "--overwrite; '-' prints it): 'show NAME > FILE' empties FILE first, even for a mistyped "
                           "name")
    show.add_argument("--overwrite", action="store_true", help="with --out: replace an existing FILE")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.action == "show":
        text = json.dumps(preset_dict(presets.get(args.name)), indent=2)
        out = out_file(args.out, args.overwrite)
        if out is None:
            print(text)
            return 0
        atomic_write(out, text + "\n")
        print(f"wrote {out}")
        return 0
    items = sorted(presets.PRESETS.values(), key=lambda p: p.name)
    if args.json or getattr(args, "list_json", False):
        print(json.dumps([preset_dict(p) for p in items], indent=2))
        return 0
    # In a terminal each line is cut to its width: the paper's RTCLM rows carry 300-character sources (what was
    # replaced, ours against the paper's heights) that wrapped the table unreadably. Piped, nothing is cut.
    width = None if args.wide or not sys.stdout.isatty() else shutil.get_terminal_size((120, 24)).columns
    print(listing(items, width))
    return 0


def listing(items: list[presets.Preset], width: int | None = None) -> str:
    """The table of presets; with ``width``, each source cut to fit (ending in "…") and a last line saying how to
    see them whole."""
    rows = [("NAME", "MECHANISM", "SOURCE")] + [(p.name, p.mechanism.name, p.source) for p in items]
    w0, w1 = (max(len(r[i]) for r in rows) for i in (0, 1))
    room = None if width is None else max(width - w0 - w1 - 4, 20)
    lines, cut = [], False
    for name, mech, source in rows:
        if room is not None and len(source) > room:
            source, cut = source[: room - 1].rstrip() + "…", True
        lines.append(f"{name:<{w0}}  {mech:<{w1}}  {source}".rstrip())
    if cut:
        lines.append("(sources cut to the terminal's width: 'clm presets --wide' prints them whole)")
    return "\n".join(lines)
