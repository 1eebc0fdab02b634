"""The fabric benchmarks' shared command line (``bench_cantilever.py``, ``bench_cusick.py``): the material, the
mesh spacing in its range, a closing JSON line; a bad material or spacing is one line on stderr and exit 2."""
import sys


def parse_fabric_args(ap, argv, edge_mm, edge_range, why):
    """Add ``--material``, ``--edge`` (mm, default ``edge_mm``) and ``--json`` to ``ap``, parse ``argv`` and
    resolve the material; ``(args, material)``, or None once the error is printed (the caller exits 2).

    ``edge_range`` (lo, hi) mm bounds ``--edge``; ``why`` says what bounds it (the specimen's size)."""
    from vfit_engine.errors import InputError
    from vfit_engine.sim.materials import resolve_material

    ap.add_argument("--material", default="cotton", help="a preset name or a material JSON file")
    ap.add_argument("--edge", type=float, default=edge_mm, help=f"mesh spacing, mm (default {edge_mm:g})")
    ap.add_argument("--json", action="store_true", help="end with one line of JSON")
    args = ap.parse_args(argv)
    try:
        material = resolve_material(args.material)
        lo, hi = edge_range
        if not lo <= args.edge <= hi:
            raise InputError(f"--edge {args.edge:g} mm: use {lo:g}-{hi:g} mm ({why})")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return None
    return args, material
