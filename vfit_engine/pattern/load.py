"""A pattern file, whatever its format, read and validated: the one way in for every command."""

from pathlib import Path

from ..errors import InputError
from . import dxf_aama, garmentcode, validate

#: file suffixes and what they hold
FORMATS = {".json": "GarmentCode / Garment-Pattern-Generator specification", ".dxf": "DXF-AAMA pieces"}


def is_pattern(path) -> bool:
    """True when ``path`` names a pattern file by its suffix (a garment mesh is .obj / .ply / .glb)."""
    return Path(path).suffix.lower() in FORMATS


def load(path, seams=None, gathers=False):
    """Read ``path`` (GarmentCode JSON, or DXF-AAMA with its ``seams`` sidecar) and validate it.

    ``gathers``: accept seams that gather one edge onto a much shorter one (:func:`validate.validate`).

    Returns
    -------
    (model.Pattern, list[str])
        The pattern in metres and the reader's and the validation's warnings (a DXF piece with no grain line,
        seams that ease a notable length, ...).

    Raises
    ------
    InputError
        An unreadable or malformed file, or a pattern that cannot be sewn, in one line naming the file, the panel
        and the edge.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".json":
        if seams is not None:
            raise InputError(f"{path}: a GarmentCode pattern carries its own stitches; --seams is for DXF-AAMA pieces")
        pattern = garmentcode.read(path)
    elif suffix == ".dxf":
        if seams is not None and not Path(seams).is_file():
            raise InputError(f"{seams}: no such file (the seams sidecar of {path})")
        pattern = dxf_aama.read(path, seams)
    else:
        known = ", ".join(f"{k} ({v})" for k, v in FORMATS.items())
        raise InputError(f"{path}: not a pattern file; vfit reads {known}")
    # every warning names the file (the validation's do already)
    return pattern, [f"{path}: {w}" for w in pattern.warnings] + validate.validate(pattern, gathers=gathers)
