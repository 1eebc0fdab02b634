"""The cantilever bending test (ASTM D1388) of a fabric on the cloth solver, against Peirce's bending length.

    python benchmarks/bench_cantilever.py --material cotton [--edge 5] [--json]
    python benchmarks/bench_cantilever.py --material my_fabric.json --edge 10 --json

Prints each try (overhang, tip angle) and the result; with ``--json`` the last line is one JSON object:
``bending_length_m`` (the overhang at 41.5 degrees / 2), ``peirce_m`` (c = (B / (w g))^(1/3) of the
material), ``relative_error``, ``overhang_m``, ``angle_deg``, ``edge_m``, ``time_s`` and the last try's figures.
The method is :mod:`vfit_engine.textile.cantilever`'s.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))  # _fabric_args, also when loaded by path (tests)


def main(argv=None):
    from _fabric_args import parse_fabric_args

    from vfit_engine.textile.cantilever import bending_length

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parsed = parse_fabric_args(ap, argv, 5.0, (0.5, 25.0), "the strip is 25 mm wide")
    if parsed is None:
        return 2
    args, material = parsed
    r = bending_length(material, args.edge / 1000.0)
    for t in r["tries"]:
        print(f"overhang {100 * t['overhang_m']:6.2f} cm -> tip {t['angle_deg']:5.2f} deg below the edge")
    print(f"{material.name}: bending length {100 * r['bending_length_m']:.2f} cm (Peirce {100 * r['peirce_m']:.2f} cm, "
          f"{100 * r['relative_error']:+.1f} %) at {args.edge:g} mm spacing; {r['vertices']} vertices, "
          f"step {1e3 * r['dt_s']:.3f} ms, {r['time_s']:.1f} s")
    if args.json:
        out = {k: v for k, v in r.items() if k != "tries"}
        out.update(material=material.name, tries=r["tries"])
        print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
