"""The check that every output of one drape says each region's verdict alike (issue 33's acceptance).

A drape's fit is said in many places: the rows of ``report.json["fit"]`` (:mod:`vfit_engine.fit.table`), the
printed table, ``fit_summary`` and the printed ``fit:`` line, ``report.json["too_tight"]`` and the printed "too
tight to wear at the ..." lines, the preview's title (:func:`vfit_engine.fit.verdict.tight_line`), ``vfit size``'s
rejection of a size (:func:`vfit_engine.sizes.rejection`) and a batch's flat columns
(:func:`vfit_engine.batch.results.flat_row`). :func:`disagreements` reads them all from one drape's report and
printed text and names every place where one of them says another verdict than the row's, or where the row's
verdict is not the rule's (:func:`vfit_engine.fit.verdict.verdict`) on the row's own figures.

Its users: ``tests/test_verdict.py`` (the demo skirt and a shared garment, in the suite) and
``scripts/verdict_consistency.py`` (the issue's customers and the four shared garments on three bodies each).
It sits on the top floor because it reads the size and batch outputs.
"""
from __future__ import annotations

import re
from types import SimpleNamespace

from vfit_engine.batch.results import KEY_REGIONS, flat_row
from vfit_engine.fit.table import TARGET_NAME
from vfit_engine.fit.verdict import (NOT_COVERED, TIGHT, VERDICTS, base_region, said_names, stretch, tight_line,
                                     verdict)
from vfit_engine.sizes import rejection

_GROUP = re.compile(r"(?:^|, )(" + "|".join(sorted(map(re.escape, VERDICTS), key=len, reverse=True)) + r") at the ")
#: Names no output may give a region: rig bones, sides as a rig spells them, vertex coordinates.
_RIG_NAME = re.compile(r"\.[LR]\b|upperarm|lowerarm|vertices at")


def said_verdicts(line):
    """verdict -> the region names a summary line (``fit_summary``, the preview's title) says it of, as written
    (a pair plural: ``thighs``); the figures in brackets and the notes after ``;`` left out."""
    text = re.sub(r"\s*\([^)]*\)", "", line.split(";")[0])
    starts = list(_GROUP.finditer(text))
    out = {}
    for k, m in enumerate(starts):
        part = text[m.end():starts[k + 1].start() if k + 1 < len(starts) else len(text)]
        names = re.split(r", | and ", part)
        out.setdefault(m.group(1), set()).update(n.strip() for n in names if n.strip())
    return out


def _names(said, name):
    """The verdicts ``said`` (:func:`said_verdicts`) gives the region called ``name`` there (its plural counts)."""
    return {v for v, names in said.items() if name in names or name + "s" in names}


def _table_line(printed, row):
    """The printed table's line of ``row`` (its region, then ``*`` for a key girth or a space), or None."""
    head = row["region"] + ("*" if row.get("key") else " ")
    return next((ln for ln in printed.splitlines() if ln.strip().startswith(head)), None)


def _row_problems(row, name, printed, limit, said_summary, said_title):
    """Where the outputs say another verdict of ``row`` (called ``name`` in a line) than its own
    (:func:`disagreements`)."""
    region, v = row["region"], row["verdict"]
    out = []
    line = _table_line(printed, row)
    if line is None:
        out.append(f"{region}: no line in the printed table")
    else:
        if not line.rstrip().endswith(v):
            out.append(f"{region}: the printed table says {line.split()[-1]!r}, the report {v!r}")
        if ("(estimated)" in line) != bool(row.get("estimated")):
            out.append(f"{region}: the printed table and the report disagree on 'estimated'")
        s = stretch(row)
        shown = None if s is None else format(round(100 * s, 1) + 0.0, ".1f")  # as the table prints it: no -0.0
        if shown is not None and shown not in line.split():
            out.append(f"{region}: the printed table does not show the stretch the verdict reads ({shown} %)")
    if v == NOT_COVERED:
        if row.get("garment_girth_cm") is not None:
            out.append(f"{region}: not covered, yet it has a garment girth")
        if _names(said_summary, name):
            out.append(f"{region}: not covered, yet the summary gives it a verdict")
        return out
    rule = verdict(region, row["girth_strain"], row["ease_cm"], limit, row.get("required_strain"))
    if rule != v:
        out.append(f"{region}: the row says {v!r}, the rule on its own figures {rule!r}")
    if _names(said_summary, name) != {v}:
        out.append(f"{region}: the summary says {sorted(_names(said_summary, name))}, the row {v!r}")
    title = _names(said_title, name)
    if title != ({v} if v in TIGHT else set()):
        out.append(f"{region}: the preview's title says {sorted(title)}, the row {v!r}")
    return out


def disagreements(report, printed):
    """Every place where one drape's outputs do not give a region one and the same verdict.

    Parameters
    ----------
    report : dict
        The drape's ``report.json`` (``vfit drape``'s, or a size's in a size run: ``fit``, ``fit_summary``,
        ``too_tight``, ``material``, ``body``).
    printed : str
        What the command printed (its table, ``too tight to wear at the ...`` lines and ``fit:`` line).

    Returns
    -------
    list of str
        One sentence per disagreement, naming the region and the two outputs; empty when every output agrees.
    """
    rows = report["fit"]
    limit = float(report["material"]["wearable_stretch"])
    said_summary = said_verdicts(report["fit_summary"])
    said_title = said_verdicts(tight_line(rows))
    out = []
    names = said_names(rows)  # a pair's two sides said apart where their verdicts differ
    for row in rows:
        out += _row_problems(row, names[row["region"]], printed, limit, said_summary, said_title)
    if "fit: " + report["fit_summary"] not in printed:
        out.append("the printed fit: line is not report.json's fit_summary")
    # too tight to wear: report.json's list, the printed lines, the size's rejection
    wear = sorted(r["region"] for r in rows if r["verdict"] == "too tight to wear")
    if sorted(t["region"] for t in report.get("too_tight", [])) != wear:
        out.append(f"too_tight lists {sorted(t['region'] for t in report.get('too_tight', []))}, the rows {wear}")
    for region in wear:
        if f"too tight to wear at the {region}: " not in printed:
            out.append(f"{region}: too tight to wear, and no printed line says so")
    lines = printed.count("too tight to wear at the ") - ("too tight to wear at the " in report["fit_summary"])
    if lines != len(wear):
        out.append(f"{lines} printed 'too tight to wear' lines for {len(wear)} such rows")
    out += _size_and_batch(rows)
    if _RIG_NAME.search(printed) or any(_RIG_NAME.search(r["region"]) for r in rows):
        out.append("a region is named by a rig bone or vertex coordinates, not as a tailor names it")
    out += _given_rows(report, rows)
    return out


def _size_and_batch(rows):
    """``vfit size``'s rejection of this drape as a size, and a batch's flat columns, against the rows."""
    out = []
    tight = [r["region"] for r in rows if r["verdict"] in TIGHT]
    said = rejection(dict(fit=rows))
    if (said is None) != (not tight):
        out.append(f"vfit size's rejection {said!r} and the tight rows {tight} disagree")
    for region in tight:
        if said is not None and region not in said:
            out.append(f"{region}: tight, and vfit size's rejection does not name it")
    task = SimpleNamespace(id="check", garment="", garment_name="", size=None, material="", body_label="",
                           body_key=lambda: "", body={})
    flat = flat_row(dict(fit=rows), task)
    if [f["verdict"] for f in flat["fit"]] != [r["verdict"] for r in rows]:
        out.append("the batch row's fit column says other verdicts than the rows")
    for key in KEY_REGIONS:  # the batch's bust columns hold a man's chest
        names = ("bust", "chest") if key == "bust" else (key,)
        row = next((r for r in rows if r["region"] in names), None)
        if flat.get(f"{key}_verdict") != (row["verdict"] if row else None):
            out.append(f"the batch column {key}_verdict says {flat.get(f'{key}_verdict')!r}, the row "
                       f"{row['verdict'] if row else None!r}")
    return out


def _given_rows(report, rows):
    """Every girth the customer gave has its row, not marked estimated."""
    given = set((report.get("body") or {}).get("targets_cm") or {})
    out = []
    for r in rows:
        if r.get("estimated") and TARGET_NAME.get(base_region(r["region"])) in given:
            out.append(f"{r['region']}: given by the customer, yet marked estimated")
    have = {TARGET_NAME.get(base_region(r["region"])) for r in rows}
    out += [f"{g}: given by the customer and has no row" for g in sorted(given & set(TARGET_NAME.values()) - have)]
    return out


def verdict_line(report):
    """``region verdict, ...`` of a drape's rows, for one line per case."""
    return ", ".join(f"{r['region']} {r['verdict']}" for r in report["fit"])
