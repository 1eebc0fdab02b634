"""A sewn pattern's fit per seam and per panel: what a pattern maker reads, and changes (``report.json["pattern"]``).

**Per seam** (one per stitch of the pattern, named by its two edges, :class:`vfit_engine.drape.sew.PatternLabels`):

* ``gap_max_mm``, ``gap_mean_mm``: the distance between the seam's sewn vertex pairs after the drape. A seam is
  ``pulled_open`` when its largest gap is over :data:`SEAM_OPEN_MM` (the pattern issue's "every seam within
  2 mm"): it did not close, or the drape pulls it apart;
* ``stretch_p99_pct``, ``stretch_max_pct``: the strain of the cloth's edges along the seam line, both sides,
  against the flat pattern (``l / l0 - 1`` of each segment between two consecutive pairs, in each panel): a
  seam line the body stretches (a waist seam round hips, an armhole round a shoulder).

The seams are listed worst first: those pulled open by their gap, then the others by their line's largest
stretch.

**Per panel**:

* ``strain_p50_pct``, ``strain_p99_pct``, ``strain_max_pct``: the yarn strain of its cloth edges against the
  flat pattern (the report's strain, :func:`vfit_engine.drape.metrics.yarn_strain`: the max over edges of
  ``MIN_EDGE`` or longer);
* ``contact_pct``: the share of its area (as cut) resting on the body (the ``contact`` fit map: within
  ``CONTACT_MM`` of the skin), each vertex weighing a third of its triangles' area;
* ``regions``: per fit-table region whose tape line crosses it (:func:`vfit_engine.fit.loops.loop_steps`; an
  opening's loop), its share of the garment's line there (``loop_share_pct``, of the draped length), that part
  of the line draped and as cut (``loop_draped_cm``, ``loop_made_cm``) and its **ease**: the region's ease
  (garment girth minus body girth) apportioned to the panels by their share of the line,
  ``ease_cm = region ease x share``. A panel's ease is what widening or narrowing it there changes; its
  ``loop_made_cm`` what it measures there as cut.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.drape.metrics import MIN_EDGE, yarn_strain

#: A seam whose sewn pairs lie farther apart than this (mm) after the drape is pulled open.
SEAM_OPEN_MM = 2.0
#: Seams printed by ``vfit drape PATTERN`` (the worst; the report lists every one).
SEAMS_SHOWN = 5
#: Panels with a smaller share (%) of a region's line are counted, not named, in the printed lines (a sleeve's
#: edge the bust's plane grazes); the report names every one.
SHARE_SHOWN_PCT = 5.0


def _pct(x):
    return round(100.0 * float(x), 3)


def seam_rows(setup, pos):
    """Per stitch (module docstring), worst first: list of dict (``seam``, ``pairs``, ``gap_max_mm``,
    ``gap_mean_mm``, ``stretch_p99_pct``, ``stretch_max_pct``, ``pulled_open``).

    Parameters
    ----------
    setup : DrapeSetup
        Of a sewing pattern (``setup.pattern`` not None).
    pos : (n, 3) float64, m
    """
    pos = np.asarray(pos, dtype=np.float64)
    labels, pairs = setup.pattern, setup.seams
    rows = []
    for k, name in enumerate(labels.seam_names):
        p = pairs[labels.seam_stitch == k]
        if not len(p):
            continue
        gap = 1000.0 * np.linalg.norm(pos[p[:, 0]] - pos[p[:, 1]], axis=1)
        i = np.concatenate([p[:-1, 0], p[:-1, 1]])  # the seam line's segments, side a then side b
        j = np.concatenate([p[1:, 0], p[1:, 1]])
        l0 = np.linalg.norm(setup.rest[j] - setup.rest[i], axis=1)
        ok = l0 > 0
        strain = np.linalg.norm(pos[j[ok]] - pos[i[ok]], axis=1) / l0[ok] - 1.0
        rows.append(dict(seam=name, pairs=int(len(p)), gap_max_mm=round(float(gap.max()), 3),
                         gap_mean_mm=round(float(gap.mean()), 3),
                         stretch_p99_pct=_pct(np.percentile(strain, 99)) if strain.size else 0.0,
                         stretch_max_pct=_pct(strain.max()) if strain.size else 0.0,
                         pulled_open=bool(gap.max() > SEAM_OPEN_MM)))
    return sorted(rows, key=lambda r: (not r["pulled_open"], -r["gap_max_mm"] if r["pulled_open"] else
                                       -r["stretch_max_pct"]))


def _vertex_area(verts, tris):
    """(n,) float64, m^2: a third of the area of every triangle at each vertex."""
    p = verts[tris]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    out = np.zeros(len(verts))
    np.add.at(out, tris.ravel(), np.repeat(area / 3.0, 3))
    return out


def panel_rows(setup, pos, maps, fit_rows):
    """Per panel (module docstring), in the pattern's order: list of dict (``panel``, ``area_m2``,
    ``strain_p50_pct``, ``strain_p99_pct``, ``strain_max_pct``, ``contact_pct``, ``regions``).

    Parameters
    ----------
    setup : DrapeSetup
        Of a sewing pattern.
    pos : (n, 3) float64, m
    maps : dict
        :func:`vfit_engine.fit.maps.fit_maps` of the drape (its ``contact``).
    fit_rows : list of dict
        The fit table (:meth:`vfit_engine.fit.table.FitTable.rows`), whose rows carry their ``panels``.
    """
    pos = np.asarray(pos, dtype=np.float64)
    mesh, labels = setup.garment.mesh, setup.pattern
    edges = mesh.edges()
    l0 = np.linalg.norm(mesh.verts[edges[:, 1]] - mesh.verts[edges[:, 0]], axis=1)
    strain = yarn_strain(mesh, pos)["edge_strain"]
    edge_panel = labels.vertex_panel[edges[:, 0]]
    area = _vertex_area(setup.rest, mesh.triangles())
    contact = np.asarray(maps["contact"]) > 0
    rows = []
    for k, name in enumerate(labels.panel_names):
        sel = (edge_panel == k) & (l0 > 0)
        s, long_ = strain[sel], l0[sel] >= MIN_EDGE
        mine = labels.vertex_panel == k
        total = float(area[mine].sum())
        regions = []
        for r in fit_rows:
            share = next((p for p in r.get("panels") or () if p["panel"] == name), None)
            if share is None or r.get("ease_cm") is None:
                continue
            regions.append(dict(region=r["region"], **{k2: v for k2, v in share.items() if k2 != "panel"},
                                ease_cm=round(r["ease_cm"] * share["loop_share_pct"] / 100.0, 2)))
        rows.append(dict(panel=name, area_m2=round(total, 4),
                         strain_p50_pct=_pct(np.percentile(s, 50)) if s.size else 0.0,
                         strain_p99_pct=_pct(np.percentile(s, 99)) if s.size else 0.0,
                         strain_max_pct=_pct(s[long_].max()) if long_.any() else 0.0,
                         contact_pct=round(100.0 * float(area[mine & contact].sum()) / total, 2) if total > 0 else 0.0,
                         regions=regions))
    return rows


def pattern_block(setup, pos, maps, fit_rows):
    """``report.json["pattern"]``'s figures of a sewn pattern's drape: ``seams`` (:func:`seam_rows`), ``panels``
    (:func:`panel_rows`), ``seams_pulled_open`` (their count) and ``seam_open_bar_mm``; None for a garment mesh."""
    if setup.pattern is None:
        return None
    seams = seam_rows(setup, pos)
    return dict(seam_open_bar_mm=SEAM_OPEN_MM, seams_pulled_open=sum(s["pulled_open"] for s in seams),
                seams=seams, panels=panel_rows(setup, pos, maps, fit_rows))


def worst(block):
    """The batch row's columns of a :func:`pattern_block` (None: a garment mesh): the largest seam gap (mm) and
    its seam, the largest panel strain p99 (%) and its panel."""
    if not block:
        return dict(worst_seam=None, worst_seam_gap_mm=None, worst_panel=None, worst_panel_p99_pct=None)
    seam = max(block["seams"], key=lambda s: s["gap_max_mm"], default=None)
    panel = max(block["panels"], key=lambda p: p["strain_p99_pct"], default=None)
    return dict(worst_seam=seam and seam["seam"], worst_seam_gap_mm=seam and seam["gap_max_mm"],
                worst_panel=panel and panel["panel"], worst_panel_p99_pct=panel and panel["strain_p99_pct"])


def block_lines(block, fit_rows=(), shown=SEAMS_SHOWN):
    """The lines ``vfit drape PATTERN`` prints of a :func:`pattern_block`: the ``shown`` worst seams, every panel,
    and the panels round each fit-table region with their ease there; a unit in every line."""
    seams, n = block["seams"], len(block["seams"])
    out = [f"seams ({block['seams_pulled_open']} of {n} pulled open, gap over {block['seam_open_bar_mm']:g} mm)"
           + (f", the {shown} worst:" if n > shown else ":")]
    for s in seams[:shown]:
        out.append(f"  {s['seam']}: gap max {s['gap_max_mm']:.2f} mm, mean {s['gap_mean_mm']:.2f} mm; line stretch "
                   f"p99 {s['stretch_p99_pct']:.1f} %, max {s['stretch_max_pct']:.1f} %"
                   + ("  PULLED OPEN" if s["pulled_open"] else ""))
    out.append("panels (yarn strain against the flat pattern, %; share of the panel's area on the body, %):")
    for p in block["panels"]:
        out.append(f"  {p['panel']}: strain p50 {p['strain_p50_pct']:.1f} %, p99 {p['strain_p99_pct']:.1f} %, "
                   f"max {p['strain_max_pct']:.1f} %; on the body {p['contact_pct']:.0f} %")
    ease = {p["panel"]: {r["region"]: r["ease_cm"] for r in p["regions"]} for p in block["panels"]}
    rows = [r for r in fit_rows if r.get("panels") and r.get("ease_cm") is not None]
    if rows:
        out.append("panels round each region (its ease, cm, shared by their % of the garment's line there):")
    for r in rows:
        big = [p for p in r["panels"] if p["loop_share_pct"] >= SHARE_SHOWN_PCT]
        rest = len(r["panels"]) - len(big)
        out.append(f"  {r['region']}: " + ", ".join(
            f"{p['panel']} {ease[p['panel']][r['region']]:+.1f} cm ({p['loop_share_pct']:.0f} %)" for p in big)
            + (f" and {rest} more under {SHARE_SHOWN_PCT:g} %{' each' if rest > 1 else ''}" if rest else ""))
    return out
