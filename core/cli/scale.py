"""``clm scale``: a design at another size (every length times a factor, angles kept), as a design JSON."""

from __future__ import annotations

import argparse
import json
import math
import sys

from core.cli import CLIError, out_file
from core.formats.design import design_to_dict
from core.formats.files import atomic_write


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "scale",
        help="a design at another size, as a design JSON",
        description="Multiply every length of a design (links, offsets, pivot positions, the output stage's centre) "
        "by a factor, angles kept: the same motion at another size, every path scaled by the factor. Give the "
        "factor, or the foot path width you want in the leg frame (the stride of the bench trajectory, what 'clm "
        "simulate' prints as the leg frame's path width; the paper's X3 has ~300 mm). Prints the design JSON, or "
        "writes it with --out.",
    )
    from core.cli.simulate import add_source

    add_source(p)
    size = p.add_mutually_exclusive_group(required=True)
    size.add_argument("--factor", type=float, metavar="F", help="multiply every length by F (> 0)")
    size.add_argument("--stride", type=float, metavar="MM", help="scale so that the leg-frame path is MM wide")
    p.add_argument("--out", metavar="FILE",
                   help="write the design JSON here instead of printing it (an existing FILE is kept unless "
                        "--overwrite; '-' prints it)")
    p.add_argument("--overwrite", action="store_true", help="with --out: replace an existing FILE")
    p.set_defaults(func=run)


def _mm(v: float) -> str:
    """A width to 0.01 mm, or to 3 digits below that (a leg scaled to 6.8 um read "0.00 mm": review of session 30)."""
    return f"{v:.2f}" if abs(v) >= 0.01 else f"{v:.3g}"


def run(args: argparse.Namespace) -> int:
    from core.cli.simulate import design_label, extent, load_design, warn_units

    design, preset = load_design(args)
    sol = design.solve(360)
    width = extent(sol.leg[0])["width"] if sol.violation[0] == 0 else None  # a part of a path: no stride
    if args.stride is not None:
        if not (math.isfinite(args.stride) and args.stride > 0):
            raise CLIError(f"--stride must be a positive number of mm, got {args.stride}")
        if width is None:  # which of the two it is (QA: the message named both)
            raise CLIError(f"the design does not assemble over the whole crank cycle (violation "
                           f"{float(sol.violation[0]):.3g} mm), so its foot path has no width to scale from: give "
                           "--factor")
        if width <= 0:
            raise CLIError("the design's foot does not move along x, so its path has no width to scale from: give "
                           "--factor")
        factor = args.stride / width
    else:
        factor = args.factor
    given = "--stride" if args.stride is not None else "--factor"
    try:
        scaled = design.scaled(factor)
    except ValueError as exc:
        raise CLIError(f"{given}: {exc}" + (f" (scale factor {factor:.6g})" if given == "--stride" else "")) from None
    label = design_label(args, preset)
    after = scaled.solve(360)
    if sol.violation[0] == 0 and after.violation[0] != 0:
        # The solver's tolerances are absolute (mm): a leg scaled to microns no longer assembles there (review of
        # session 29: --stride 1e-7 wrote such a design with exit 0 and "width 298.94 -> 0.00 mm").
        way = "larger" if factor < 1 else "smaller"
        raise CLIError(f"{given}: scaled by {factor:.6g} the design no longer assembles (violation "
                       f"{after.violation[0]:.3g} mm: the solver's tolerances are absolute and its lengths bounded): "
                       f"choose a {way} size")
    new = extent(after.leg[0])["width"]
    warn_units(scaled, f"{label} x{factor:.4g}", after)  # lab rehearsal: --stride 0.3 (metres) without a word
    data = {"name": f"{label} x{factor:.4g}", "title": design.mechanism.title, **design_to_dict(scaled),
            "source": f"{label} scaled by {factor:.6g}"
                      + (f" (leg-frame path width {_mm(width)} -> {_mm(new)} mm)" if width and new else "")}
    text = json.dumps(data, indent=2) + "\n"
    out = out_file(args.out, args.overwrite)  # `--design mine.json --out mine.json` replaced the design
    if out is None:
        sys.stdout.write(text)
        return 0
    atomic_write(out, text)
    print(f"wrote {out}: {data['source']}")
    return 0
