"""The flat pattern drawn as a PNG: its size, every panel drawn inside its own box, seams in one colour."""
import numpy as np
import pytest
from PIL import Image

from vfit_engine.errors import InputError
from vfit_engine.pattern import draw, model


def _rect(name, w, h):
    v = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    return model.Panel(name, v, [model.Edge(i, (i + 1) % 4) for i in range(4)])


def _pattern():
    panels = {"front": _rect("front", 0.5, 0.7), "back": _rect("back", 0.5, 0.7), "sleeve": _rect("sleeve", 0.6, 0.3),
              "cuff": _rect("cuff", 0.25, 0.08)}
    stitches = [model.Stitch(model.EdgeRef("front", 1), model.EdgeRef("back", 3), True),
                model.Stitch(model.EdgeRef("sleeve", 0), model.EdgeRef("cuff", 2), True)]
    return model.Pattern(panels, stitches, source="test.json")


def test_layout_packs_shelves_without_overlap():
    sizes = np.array([[0.5, 0.7], [0.5, 0.7], [0.6, 0.3], [0.25, 0.08], [1.4, 0.2]])
    corners, (w, h) = draw.layout(sizes, row_width=1.2)
    boxes = np.hstack([corners, corners + sizes])
    for i in range(len(sizes)):
        for j in range(i + 1, len(sizes)):
            apart = (boxes[i, 2] + draw.GAP_M <= boxes[j, 0] + 1e-12 or boxes[j, 2] + draw.GAP_M <= boxes[i, 0] + 1e-12
                     or boxes[i, 3] + draw.GAP_M <= boxes[j, 1] + 1e-12
                     or boxes[j, 3] + draw.GAP_M <= boxes[i, 1] + 1e-12)
            assert apart, (i, j)
    assert boxes[:, 2].max() == pytest.approx(w) and -boxes[:, 1].min() == pytest.approx(h)
    assert boxes[:, 2].max() <= max(1.2, 1.4) + 1e-12  # rows no wider than asked (one box wider has its own)


def test_the_picture_has_every_panel_drawn_in_its_box_and_seams_coloured_alike(tmp_path):
    out = draw.draw_pattern(_pattern(), tmp_path / "p.png", width_px=1200)
    img = np.asarray(Image.open(tmp_path / "p.png").convert("RGB")).astype(int)
    assert out["size"] == (1200, img.shape[0]) and img.shape[1] == 1200
    for name, (x0, y0, x1, y1) in out["boxes"].items():
        inside = img[y0 + 2:y1 - 1, x0 + 2:x1 - 1]
        assert (np.abs(inside - draw.FILL_RGB).sum(axis=2) == 0).mean() > 0.5, name  # the panel is filled
        # the box's edge has drawn (non-white) pixels all round: the outline
        assert (img[y0:y1 + 1, x0:x0 + 3] != 255).any(axis=2).mean() > 0.9, name
    # seam 1 (front edge 1 and back edge 3) in its colour in both panels' boxes, seam 2 in sleeve and cuff
    for k, names in ((0, ("front", "back")), (1, ("sleeve", "cuff"))):
        colour = np.array(draw.SEAM_RGB[k + 1])  # seams count from 1
        for name in names:
            x0, y0, x1, y1 = out["boxes"][name]
            region = img[max(0, y0 - 3):y1 + 4, max(0, x0 - 3):x1 + 4]
            assert (np.abs(region - colour).sum(axis=2) == 0).sum() > 50, (k, name)
        for name in set(out["boxes"]) - set(names):
            x0, y0, x1, y1 = out["boxes"][name]
            region = img[y0 + 5:y1 - 5, x0 + 5:x1 - 5]
            assert (np.abs(region - colour).sum(axis=2) == 0).sum() == 0, (k, name)


def test_a_picture_too_narrow_or_empty_is_refused(tmp_path):
    with pytest.raises(InputError, match="too small"):
        draw.draw_pattern(_pattern(), tmp_path / "p.png", width_px=100)
    with pytest.raises(InputError, match="no panels"):
        draw.draw_pattern(model.Pattern({}, [], source="empty.json"), tmp_path / "p.png")
