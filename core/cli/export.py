"""``clm export``: a design as drawings for fabrication (DXF with one layer per link, and SVG)."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from core.cli import CLIError, path_arg
from core.formats.drawing import HOLE, PLATE, Plates, cutting_warnings, drawing, dxf, svg
from core.formats.files import atomic_write


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="write a design as DXF (one layer per link, pivot holes, dimensions, a parts sheet to cut) and SVG",
        description="Draw a design (a preset or a design JSON file) at one crank angle for fabrication: DXF with "
        "one layer per link, pivot holes at joint centres, ground pivots marked and link lengths dimensioned in "
        "mm, and a parts sheet under it (each link a plate outline with its holes, laid flat: what a laser cuts); "
        "SVG with the linkage and its foot path. Holes that overlap or leave a thin web are warned about.",
    )
    from core.cli.simulate import add_source

    add_source(p)
    p.add_argument("--dxf", type=path_arg, metavar="OUT", help="DXF file to write")
    p.add_argument("--svg", type=path_arg, metavar="OUT", help="SVG file to write")
    p.add_argument("--angle", type=float, default=0.0, help="crank angle in degrees from the crank phase (default 0)")
    p.add_argument("--hole", type=float, default=HOLE, metavar="MM",
                   help=f"pivot hole diameter in mm, your pins' (default {HOLE:g})")
    p.add_argument("--width", type=float, default=None, metavar="MM",
                   help=f"link plate width in mm on the DXF's parts sheet (default {PLATE:g} hole diameters)")
    from core.cli.simulate import add_mode

    add_mode(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from core.cli.simulate import design_label, load_design, warn_units

    if args.dxf is None and args.svg is None:
        raise CLIError("nothing to write: give --dxf and/or --svg")
    if args.dxf is not None and args.svg is not None and args.dxf.resolve() == args.svg.resolve():
        raise CLIError(f"--dxf and --svg name the same file {str(args.dxf)!r}: the SVG would replace the DXF")
    if not math.isfinite(args.angle):
        raise CLIError(f"--angle must be a finite number of degrees, got {args.angle}")
    try:
        plates = Plates(args.hole, args.width)
    except ValueError as exc:
        raise CLIError(f"--hole/--width: {exc}") from None
    if plates.hole < 0.5:  # lab rehearsal: --hole 0.005 (metres) drew 5 um pins without a word
        print(f"clm: warning: --hole {plates.hole:g}: a pivot hole under 0.5 mm; it is read in mm (values in m need "
              "scaling)", file=sys.stderr)
    design, preset = load_design(args)
    warn_units(design, design_label(args, preset))  # before the hole advice a design in m would draw
    d = drawing(design, math.radians(math.fmod(args.angle, 360.0)))  # 1e8 deg: sin/cos of a huge angle lost it
    for out, kind in ((args.dxf, "dxf"), (args.svg, "svg")):
        if out is None:
            continue
        _check_output(out, kind, args.design)
        folder = out.parent
        if not folder.is_dir():
            raise CLIError(f"cannot write {out}: there is no folder {folder}")
        if not os.access(folder, os.W_OK):
            raise CLIError(f"cannot write {out}: the folder {folder} is not writable")
    if args.dxf is not None:
        atomic_write(args.dxf, dxf(d, plates))
        print(f"wrote {args.dxf} ({len(d.links)} links, {len(d.ground)} ground pivots; parts sheet: "
              f"{plates.plate:g} mm plates, {plates.hole:g} mm holes)")
    if args.svg is not None:
        atomic_write(args.svg, svg(d, plates=plates))
        print(f"wrote {args.svg}")
    for w in cutting_warnings(d, plates):
        print(f"clm: warning: {w.text}{' (--hole)' if w.overlap else ''}", file=sys.stderr)
    return 0


def _check_output(out: Path, kind: str, design: Path | None) -> None:
    """Refuse an output that would replace what the user made (lab rehearsal: ``--svg mine.json`` overwrote the
    design drawn, ``--svg runs/a/result.json`` the run): a folder, a name that is not ``.{kind}``, or the ``--design``
    file."""
    if out.is_dir():
        raise CLIError(f"--{kind} {out} is a folder; give a file in it, e.g. {out / ('leg.' + kind)}")
    if out.suffix.lower() != f".{kind}":
        raise CLIError(f"--{kind} {out}: {KINDS[kind]} file's name ends in .{kind}; give e.g. {_named(out, kind)}")
    if design is not None and str(design) != "-" and out.resolve() == design.resolve():
        raise CLIError(f"--{kind} {out} is the design drawn; give another file")


KINDS = {"dxf": "a DXF", "svg": "an SVG"}


def _named(out: Path, kind: str) -> str:
    """``out``'s name ending in .{kind}: mine.json -> mine.svg, a.svg.bak -> a.svg (not a.svg.svg); a name that is
    only an extension (.svg, .dxf: a hidden file to the system) -> leg.svg, another hidden one .mine -> mine.svg."""
    stem = out.name.removesuffix(out.suffix).rstrip(".")
    if not stem or stem.startswith("."):  # ..json leaves nothing
        bare = stem.lstrip(".")
        stem = "leg" if not bare or bare.lower() in EXTENSIONS else bare
    return stem if Path(stem).suffix.lower() == f".{kind}" else f"{stem}.{kind}"


EXTENSIONS = {"svg", "dxf", "json", "png", "csv", "html", "toml", "txt", "pdf"}
