"""Which body part a pattern panel goes round: the keyword table that reads it from the panel's name or label.

A panel's :class:`Slot` is its kind (torso, skirt, sleeve, leg, collar, cuff, waistband), its side (front,
back, left, right), whether it is a left or right half, and for sleeves, cuffs and legs which limb. It comes
from a mapping the user gives, else from keywords in the panel's name, then its label (GarmentCode's ``body``,
``leg`` ...), then the pattern's file name for a panel named only by its side (``front`` in ``gpg_tee.json``);
a panel named only by its side and sewn to a sleeve is a torso panel. :mod:`vfit_engine.pattern.placement`
wraps each panel round the part its slot names.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from vfit_engine.errors import InputError

#: Kinds of panel, the keywords that name them (searched as substrings of the name's words, in this order)
#: and the part they wrap round ("arm", "leg": the side's arm or leg).
KINDS = (
    ("collar", ("collar", "neckband", "hood")),
    ("cuff", ("cuff",)),
    ("waistband", ("waistband", "wb", "belt")),
    ("sleeve", ("sleeve",)),
    ("skirt", ("skirt", "godet")),
    ("leg", ("pant", "trouser", "short", "leg")),
    ("torso", ("torso", "bodice", "body", "shirt", "tee", "top", "yoke", "dress", "blouse", "jacket")),
)
RING_PART = {"collar": "neck", "cuff": "arm", "waistband": "torso", "sleeve": "arm", "skirt": "hips",
             "leg": "leg", "torso": "torso"}
#: Side words; a kind word's leftover letters are read as sides too (``lfsleeve``: l, f; ``btorso``: b).
SIDES = {"front": "front", "back": "back", "left": "left", "right": "right",
         "f": "front", "b": "back", "l": "left", "r": "right"}


@dataclass(frozen=True)
class Slot:
    """Where a panel goes: its ``kind`` (a :data:`KINDS` name), ``side`` (front, back, left, right), ``half``
    (left, right or None) and ``limb`` (L, R or None: which arm or leg)."""

    kind: str
    side: str = "front"
    half: str | None = None
    limb: str | None = None

    @property
    def part(self):
        p = RING_PART[self.kind]
        return f"{p}.{self.limb}" if p in ("arm", "leg") else p


def _words(text):
    """Lower-case words of a name: split at non-letters and at camelCase humps."""
    text = re.sub(r"([a-z])([A-Z])", r"\1 \2", text or "")
    return [w for w in re.split(r"[^a-z]+", text.lower()) if w]


def slot_from_text(text):
    """The :class:`Slot` that keywords in ``text`` name, or None when they name no kind of panel.

    Sides: whole words (``front``, ``left``, ``f``, ``l`` ...) and the letters left over beside a kind word
    (``lfsleeve``, ``btorso``). No side word: front; left or right alone: a side panel for a torso or skirt
    ring, the limb for a sleeve, cuff or leg.
    """
    words = _words(text)
    sides = [SIDES[w] for w in words if w in SIDES]
    # the first kind of the table named by any word: a sleeve's cuff is a cuff, a skirt's waistband a waistband
    for kind, keys in KINDS:
        for w in words:
            key = next((key for key in keys if key in w), None)
            if key is not None and w not in SIDES:
                rest = w.replace(key, "", 1)
                if rest and all(c in "lrfb" for c in rest):
                    sides += [SIDES[c] for c in rest]
                return _slot(kind, sides)
    return None


def _slot(kind, sides):
    fb = next((s for s in sides if s in ("front", "back")), None)
    lr = next((s for s in sides if s in ("left", "right")), None)
    limb = {"left": "L", "right": "R", None: None}[lr]
    if kind in ("sleeve", "cuff", "leg"):
        return Slot(kind, fb or "front", None, limb or "L")
    if fb is None and lr is not None:
        return Slot(kind, lr)
    return Slot(kind, fb or "front", lr)


def resolve_slots(pattern, mapping=None):
    """{panel: Slot} of every panel; see the module docstring for the order of the rules.

    ``mapping`` values are Slots or text read like a panel name ("sleeve left back", "skirt front").

    Raises
    ------
    InputError
        A panel whose part cannot be told: names the file and the panel and how to give a mapping.
    """
    mapping = dict(mapping or {})
    source_slot = slot_from_text(re.sub(r".*[\\/]", "", pattern.source or ""))
    slots, unknown = {}, []
    for name, panel in pattern.panels.items():
        given = mapping.get(name)
        slot = given if isinstance(given, Slot) else slot_from_text(given) if given else None
        if given and slot is None:
            raise InputError(f"{pattern.source or 'pattern'}: panel {name!r}: mapping {given!r} names no part; "
                             f"use words such as 'torso front', 'sleeve left back', 'skirt left', 'leg right front'")
        if slot is None:
            slot = slot_from_text(name)
        if slot is None and panel.label:
            own = slot_from_text(panel.label)
            if own is not None:
                sides = [SIDES[w] for w in _words(name) if w in SIDES]
                slot = _slot(own.kind, sides) if sides else own
        if slot is None and source_slot is not None:
            sides = [SIDES[w] for w in _words(name) if w in SIDES]
            slot = _slot(source_slot.kind, sides) if sides else None
        if slot is None:
            unknown.append(name)
        slots[name] = slot
    for name in unknown:  # sewn to a sleeve: a torso panel
        sides = [SIDES[w] for w in _words(name) if w in SIDES]
        if sides and any(slots.get(o) is not None and slots[o].kind == "sleeve" for o in _neighbours(pattern, name)):
            slots[name] = _slot("torso", sides)
    for name in unknown:
        if slots[name] is None:
            raise InputError(
                f"{pattern.source or 'pattern'}: panel {name!r}: cannot tell which body part it goes round "
                f"(no keyword in its name or label); give a mapping, e.g. {{{name!r}: 'torso front'}} "
                f"(kinds: {', '.join(k for k, _ in KINDS)}; sides: front, back, left, right)")
    return slots


def _neighbours(pattern, name):
    for st in pattern.stitches:
        if st.a.panel == name:
            yield st.b.panel
        elif st.b.panel == name:
            yield st.a.panel


def slot_kind(pattern, name):
    """Kind of a panel by its own name or label alone (None when they name none)."""
    s = slot_from_text(name) or slot_from_text(pattern.panels[name].label or "")
    return s.kind if s is not None else None
