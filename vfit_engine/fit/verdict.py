"""The fit verdict: one rule that says how a garment fits each body region, and the words that say it.

Every output that says how a garment fits -- the fit table's rows (:mod:`.table`), ``fit_summary``, the
report's ``too_tight``, ``vfit drape``'s and ``vfit size``'s printed lines, the preview's title, the size
``vfit size`` recommends (:mod:`vfit_engine.sizes`) and the batch columns -- reads the verdict this module
gives a row; none judges on its own.

**The rule.** A region's verdict comes from two figures of its row and the fabric's wearable stretch
``L`` (``Material.wearable_stretch``: cotton 10 %, jersey 30 %, denim 5 %):

* the *stretch* ``s`` of the cloth round the region: its ``girth_strain`` (sum l / sum l0 - 1 of the yarn
  edges that run round it, against the garment as given), and for a garment opening (hem, cuff,
  waistband, neckline) the larger of that and ``required_strain``, the stretch the body forces on it to
  go on at all;
* its ``ease_cm``: the garment's girth round the region less the body's.

=======================  =====================================================================
``too tight to wear``    ``s > L``: the body stretches the cloth round it beyond what the fabric gives
``tight``                ``TIGHT_SHARE * L < s <= L``, or an opening the body forces wider at all
                         (``required_strain > 0``): it can be worn, and it is felt
``too loose``            not tight, and ``ease_cm > TOO_LOOSE_EASE_CM`` of the region (a hem's width
                         is its cut, never too loose)
``loose``                not tight, and ``ease_cm > LOOSE_EASE_CM`` of the region
``fitted``               otherwise
=======================  =====================================================================

Stretch decides before ease: cloth stretched round a region is tight there whatever its girth says.
One edge stretched far (a seam, a pinned point) does not make a region too tight: the verdict reads the
cloth round the region as a whole; the peaks stay in ``report.json["strain_by_body_part"]`` and
``fit.ply``'s ``strain``.

A girth the customer gave that the garment does not go round (a skirt and the bust; a waistband that
cannot reach the waist) has its row all the same, with verdict ``not covered`` (:data:`NOT_COVERED`) and no
garment figures: it is no fit verdict and no output counts it as one.

Regions are named as a tailor names them (``chest``, ``left upper arm``, ``waistband``, ``left sleeve
hem``); a row whose body girth the customer did not give (the body model estimated it from the others)
carries ``estimated: true``, and every text marks it "estimated".
"""
from __future__ import annotations

import math

#: The verdicts, tightest first.
VERDICTS = ("too tight to wear", "tight", "fitted", "loose", "too loose")
#: The verdicts that stretch the cloth round the region (a size that has one at any region is too small).
TIGHT = VERDICTS[:2]
#: The row of a girth the customer gave that the garment does not go round (no fit verdict).
NOT_COVERED = "not covered"
#: Tight beyond this share of the fabric's wearable stretch (cotton 10 % -> 3 %).
TIGHT_SHARE = 0.3
#: Loose beyond this ease, cm, by region (openings by their name; ``opening``: one not named here).
LOOSE_EASE_CM = {"bust": 12.0, "chest": 12.0, "underbust": 12.0, "waist": 12.0, "hips": 12.0, "neck": 6.0,
                 "upper arm": 8.0, "thigh": 10.0, "opening": 10.0}
#: Too loose beyond this ease, cm: twice the loose ease at the body's girths (a size and more too big), a
#: waistband or neckline that slips; a hem's width is its cut (never too loose).
TOO_LOOSE_EASE_CM = {**{k: 2.0 * v for k, v in LOOSE_EASE_CM.items()},
                     "hem": math.inf, "sleeve hem": math.inf, "leg hem": math.inf}


def base_region(region):
    """The region's name without its side: ``"left upper arm"`` -> ``"upper arm"``."""
    words = str(region).split(" ", 1)
    return words[1] if words[0] in ("left", "right") and len(words) > 1 else str(region)


def stretch(row):
    """The stretch the rule reads (module docstring): ``girth_strain``, for an opening at least its
    ``required_strain``; None for a row :data:`NOT_COVERED`."""
    if row.get("girth_strain") is None:
        return None
    return max(float(row["girth_strain"]), float(row.get("required_strain") or 0.0))


def verdict(region, girth_strain, ease_cm, limit, required_strain=None):
    """The verdict of a region (module docstring).

    Parameters
    ----------
    region : str
        Its name (a side is ignored): a body girth (``chest``, ``waist``, ``upper arm`` ...) or an opening
        (``waistband``, ``sleeve hem`` ...).
    girth_strain : float
        Stretch of the cloth round it, fraction.
    ease_cm : float
    limit : float
        The fabric's wearable stretch, fraction.
    required_strain : float or None
        An opening's: the stretch the body forces on it (None: not an opening).

    Returns
    -------
    str
        One of :data:`VERDICTS`.
    """
    need = 0.0 if required_strain is None else float(required_strain)
    s = max(float(girth_strain), need)
    if s > limit:
        return "too tight to wear"
    if s > TIGHT_SHARE * limit or need > 0.0:
        return "tight"
    name = base_region(region)
    key = name if name in LOOSE_EASE_CM else "opening"
    if ease_cm > TOO_LOOSE_EASE_CM.get(name, TOO_LOOSE_EASE_CM[key]):
        return "too loose"
    if ease_cm > LOOSE_EASE_CM[key]:
        return "loose"
    return "fitted"


def uncovered_row(name, side, body_m, key):
    """The row of a girth the customer gave (``body_m``, m) that the garment does not go round."""
    return dict(region=f"{side} {name}".strip(), body_girth_cm=round(100.0 * body_m, 2), garment_girth_cm=None,
                ease_cm=None, girth_strain=None, max_strain=None, pressure_kpa_max=None, verdict=NOT_COVERED,
                key=key, estimated=False)


def too_tight(rows, limit=None):
    """``report.json["too_tight"]``: the rows whose verdict is ``too tight to wear``, most stretched first.

    Returns
    -------
    list of dict
        ``region``, ``stretch`` (the rule's), ``girth_strain``, ``max_strain``, ``required_strain`` (openings),
        ``estimated`` and (given) ``fabric_limit``.
    """
    out = []
    for r in rows:
        if r.get("verdict") != "too tight to wear":
            continue
        t = dict(region=r["region"], stretch=round(stretch(r), 5), girth_strain=r["girth_strain"],
                 max_strain=r.get("max_strain"), estimated=bool(r.get("estimated")))
        if r.get("required_strain") is not None:
            t["required_strain"] = r["required_strain"]
        if limit is not None:
            t["fabric_limit"] = float(limit)
        out.append(t)
    return sorted(out, key=lambda t: -t["stretch"])


def is_tight(row):
    """True when the row's verdict stretches the cloth (:data:`TIGHT`)."""
    return row.get("verdict") in TIGHT


def said_names(rows):
    """region -> the name a line says it by: without its side (``thigh``, a pair said once) where both sides
    have one verdict, with it (``right thigh``) where they differ, so no name is given two verdicts."""
    verdicts = {}
    for r in rows:
        verdicts.setdefault(base_region(r["region"]), set()).add(r["verdict"])
    return {r["region"]: base_region(r["region"]) if len(verdicts[base_region(r["region"])]) == 1 else r["region"]
            for r in rows}


def summary_line(rows):
    """One line for people, verdict by verdict, tightest first, e.g. ``too tight to wear at the chest (+12 %),
    tight at the sleeve hems (+5 %, the body needs >= 4 %), fitted at the waist and hips, loose at the thighs
    (+13 cm ease); estimated (not given): chest``; tight regions say how far the cloth round them is stretched
    (an opening also the stretch the body forces on it), loose ones their ease."""
    groups = {v: {} for v in VERDICTS}
    estimated, uncovered = [], []
    said = said_names(rows)
    for r in rows:
        base = said[r["region"]]
        if r["verdict"] == NOT_COVERED:
            if base not in uncovered:
                uncovered.append(base)
            continue
        if r.get("estimated") and base_region(r["region"]) not in estimated:
            estimated.append(base_region(r["region"]))  # a pair's girth is estimated once
        tight = r["verdict"] in TIGHT
        figure = max(r["girth_strain"], 0.0) if tight else r["ease_cm"]
        g = groups[r["verdict"]].setdefault(base, [0, -math.inf, 0.0])
        g[0] += 1
        g[1] = max(g[1], figure)
        g[2] = max(g[2], r.get("required_strain") or 0.0)
    parts = []
    for v, g in groups.items():
        if not g:
            continue
        names = []
        for base, (count, figure, need) in g.items():
            label = _plural(base) if count > 1 else base
            if v in TIGHT:
                label += f" (+{100 * figure:.0f} %" + (f", the body needs >= {100 * need:.0f} %)" if need > 0 else ")")
            elif v in ("loose", "too loose"):
                label += f" (+{figure:.0f} cm ease)"
            names.append(label)
        parts.append(f"{v} at the {join(names)}")
    notes = [f"not covered: the {join(uncovered)} (given; the garment does not go round it)"] if uncovered else []
    notes += [f"estimated (not given): {join(estimated)}"] if estimated else []
    return "; ".join([", ".join(parts) if parts else "no region the garment goes round"] + notes)


def tight_line(rows):
    """The regions a customer feels, for the preview's title: ``too tight to wear at the chest, tight at the
    waistband``, or ``nothing tight`` (the verdicts of the rows, as :func:`summary_line` says them)."""
    parts = []
    said = said_names(rows)
    for v in TIGHT:
        names = list(dict.fromkeys(said[r["region"]] for r in rows if r["verdict"] == v))
        if names:
            parts.append(f"{v} at the {join(names)}")
    return ", ".join(parts) if parts else "nothing tight"


def join(words):
    """``a``, ``a and b``, ``a, b and c``."""
    words = list(words)
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def _plural(name):
    return {"hips": "hips", "bust": "bust", "chest": "chest", "waist": "waist"}.get(name, name + "s")
