"""How it fits: the fit maps against analytic cases, the fit table and its summary, fit.ply, scene.glb and the
preview through ``vfit drape``."""
import json
import re
import struct
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

from test_drape import GARMENTS, needs_shared
from vfit_cli.main import cli
from vfit_engine.fit.maps import fit_maps
from vfit_engine.fit.verdict import VERDICTS, summary_line
from vfit_engine.io.meshdata import mesh_from_faces
from vfit_engine.sim.materials import get_material


def tube(radius, sides, rings, height, y0=0.0, cap=False):
    """A quad tube round the Y axis (vertices ring by ring), optionally closed with two triangle fans."""
    a = 2.0 * np.pi * np.arange(sides) / sides
    ys = y0 + np.linspace(0.0, height, rings)
    verts = [[radius * np.sin(t), y, radius * np.cos(t)] for y in ys for t in a]
    faces = [[r * sides + k, r * sides + (k + 1) % sides, (r + 1) * sides + (k + 1) % sides, (r + 1) * sides + k]
             for r in range(rings - 1) for k in range(sides)]
    if cap:
        n = len(verts)
        verts += [[0.0, ys[0], 0.0], [0.0, ys[-1], 0.0]]
        top = (rings - 1) * sides
        faces += [[n, (k + 1) % sides, k] for k in range(sides)]
        faces += [[n + 1, top + k, top + (k + 1) % sides] for k in range(sides)]
    return np.array(verts, dtype=np.float64), faces


def test_ease_of_a_cylinder_garment_round_a_cylinder_body_is_the_gap():
    """A garment tube of radius R round a closed body cylinder of radius r, vertices in line with the body's:
    ease_mm is R - r everywhere, contact only where the gap is under 5 mm."""
    from vfit_engine.collide.body_mesh import MeshCollider

    bverts, bfaces = tube(0.10, 48, 21, 0.6, y0=-0.3, cap=True)
    body = mesh_from_faces(bverts, bfaces)
    collider = MeshCollider(bverts, body.triangles())
    for gap in (0.003, 0.02):
        gverts, gfaces = tube(0.10 + gap, 48, 5, 0.2, y0=-0.1)
        garment = mesh_from_faces(gverts, gfaces)
        setup = SimpleNamespace(garment=SimpleNamespace(mesh=garment), collider=collider,
                                material=get_material("cotton"))
        maps = fit_maps(setup, gverts)
        assert maps["ease_mm"] == pytest.approx(1000.0 * gap, abs=1e-6)
        assert np.all(maps["contact"] == (1.0 if gap < 0.005 else 0.0))
        assert np.all(maps["strain"] == pytest.approx(0.0, abs=1e-12)) and np.all(maps["shear_deg"] < 1e-6)


def _row(region, verdict, strain=0.0, ease=4.0, need=None):
    row = dict(region=region, verdict=verdict, girth_strain=strain, ease_cm=ease)
    if need is not None:
        row["required_strain"] = need
    return row


def test_summary_line_groups_verdicts_and_pairs():
    rows = [_row("bust", "fitted"), _row("waist", "fitted"), _row("hips", "loose", ease=13.2),
            _row("left sleeve hem", "tight", 0.19, need=0.17), _row("right sleeve hem", "tight", 0.14, need=0.11)]
    assert summary_line(rows) == ("tight at the sleeve hems (+19 %, the body needs >= 17 %), fitted at the bust "
                                  "and waist, loose at the hips (+13 cm ease)")
    assert summary_line([]) == "no region the garment goes round"


def test_ply_vertex_properties_round_trip(tmp_path):
    """fit.ply's float vertex properties read back (by meshio, independently) as written."""
    import meshio

    from vfit_engine.io.ply import write_ply

    verts, faces = tube(0.1, 8, 3, 0.1)
    mesh = mesh_from_faces(verts, faces)
    props = {"strain": np.linspace(-0.1, 0.2, len(verts)), "ease_mm": np.arange(len(verts), dtype=float)}
    for binary in (True, False):
        path = tmp_path / f"fit_{binary}.ply"
        write_ply(path, mesh, properties=props, binary=binary)
        m = meshio.read(path)
        assert np.allclose(m.points, verts)
        for name, values in props.items():
            assert np.allclose(m.point_data[name], values, atol=1e-6)


@pytest.fixture(scope="module")
def suit02(tmp_path_factory):
    """``vfit drape male_casualsuit02.obj --gender male --preview`` (the issue's acceptance command)."""
    if not GARMENTS.is_dir():
        pytest.skip("../shared/assets/garments (MakeHuman clothes) absent")
    out = tmp_path_factory.mktemp("fit") / "o"
    r = CliRunner().invoke(cli, ["drape", str(GARMENTS / "male_casualsuit02" / "male_casualsuit02.obj"),
                                 "--gender", "male", "--preview", "-o", str(out), "--every", "0"])
    assert r.exit_code == 0, r.output
    return out, r.output


def _ply_header(path):
    data = path.read_bytes()
    head = data[:data.index(b"end_header")].decode("ascii")
    return head


def test_drape_writes_fit_maps_scene_preview_and_table(suit02):
    out, output = suit02
    report = json.loads((out / "report.json").read_text())
    n = report["garment_vertices"]
    head = _ply_header(out / "fit.ply")
    assert f"element vertex {n}" in head
    for prop in ("strain", "shear_deg", "ease_mm", "pressure_kpa", "contact"):
        assert f"property float {prop}" in head
    fit = report["fit"]
    regions = {r["region"] for r in fit}
    assert {"chest", "waist", "hips"} <= regions and len(fit) >= 4
    for r in fit:
        assert r["verdict"] in VERDICTS
        assert r["ease_cm"] == pytest.approx(r["garment_girth_cm"] - r["body_girth_cm"], abs=0.02)
        assert r["garment_girth_cm"] > 0 and r["body_girth_cm"] > 0
    assert report["fit_units"]["ease"] == "cm" and report["fit_maps"]["properties"]["pressure_kpa"] == "kPa"
    assert "fit: " + report["fit_summary"] in output
    # scene.glb: a glTF 2.0 binary with the body and the garment
    data = (out / "scene.glb").read_bytes()
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert magic == b"glTF" and version == 2 and length == len(data)
    doc = json.loads(data[20:20 + struct.unpack("<I", data[12:16])[0]])
    assert [nd["name"] for nd in doc["nodes"]] == ["body", "garment"]
    assert "COLOR_0" in doc["meshes"][1]["primitives"][0]["attributes"]
    from PIL import Image

    w, h = Image.open(out / "preview.png").size
    assert w >= 1200 and h >= 600


def test_fit_maps_in_the_ply_are_those_of_the_final_mesh(suit02):
    """The ease in fit.ply is the final garment's distance from the body file's surface (recomputed here with
    the body written beside it), and strain that of final.obj against the garment as given."""
    import meshio

    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.io.mesh import read_mesh

    out, _ = suit02
    fit = meshio.read(out / "fit.ply")
    body = read_mesh(out / "body.obj")
    d, _, _ = MeshCollider(body.verts, body.triangles()).signed_distance(fit.points)
    near = np.abs(d) < 0.04
    assert near.mean() > 0.5
    assert np.allclose(fit.point_data["ease_mm"][near], 1000.0 * d[near], atol=0.01)
    assert np.all(fit.point_data["pressure_kpa"] >= 0) and set(np.unique(fit.point_data["contact"])) <= {0.0, 1.0}
    assert np.all(fit.point_data["pressure_kpa"][fit.point_data["contact"] == 0] == 0)


def test_the_ease_column_is_an_independent_tape_round_the_shirts_torso_loop(suit02, body_model):
    """The chest (his chest plane, under the armpits), waist and hips rows of the suit against tests/tape.py:
    the planes re-derived from the definitions, final.obj and body.obj cut by trimesh, the cloth's loops round
    the torso kept where nearer the torso than the arms (at the chest the plane runs through the shirt's
    armholes), scipy's hull: the ease to 2 mm (issue 33 asks 5 mm; 0.05 mm or better on the four shared
    garments)."""
    import trimesh

    from tape import cloth_torso_tape, tape_measure
    from vfit_engine.io.mesh import read_mesh

    out, _ = suit02
    rows = {r["region"]: r for r in json.loads((out / "report.json").read_text())["fit"]}
    body, cloth = read_mesh(out / "body.obj"), read_mesh(out / "final.obj")
    bverts = body.verts[:13380]
    girths, planes = tape_measure(bverts, body_model.body_quads, chest=True, planes=True)
    body_mesh = trimesh.Trimesh(body.verts, body.triangles(), process=False)
    cloth_mesh = trimesh.Trimesh(cloth.verts, cloth.triangles(), process=False)
    for region, key in (("chest", "bust"), ("waist", "waist"), ("hips", "hips")):
        tape = cloth_torso_tape(cloth_mesh, body_mesh, planes[key])
        assert rows[region]["ease_cm"] == pytest.approx(100 * (tape - girths[key]), abs=0.2), region
    # the chest's loop there runs round both sleeves (the table before issue 33 took in their roots: at the bust
    # band's plane it read 7.4 cm of ease on this shirt where the tape reads 4.8)
    y = planes["bust"]
    path = cloth_mesh.section(plane_origin=[0, y, 0], plane_normal=[0, 1, 0])
    widest = max(np.ptp(np.asarray(d)[:, 0]) for d in path.discrete)
    assert widest > 0.5 and rows["chest"]["garment_girth_cm"] < 100 * (girths["bust"] + 0.08)


@needs_shared
@pytest.mark.slow
def test_sleeve_hems_of_the_female_suit_are_tight(tmp_path):
    """Acceptance: female_casualsuit01's sleeve hems are smaller round than the arms: the table calls them tight
    with the stretch they need, and the summary line says so."""
    out = tmp_path / "o"
    r = CliRunner().invoke(cli, ["drape", str(GARMENTS / "female_casualsuit01" / "female_casualsuit01.obj"),
                                 "-o", str(out), "--every", "0", "--map", "ease"])
    assert r.exit_code == 0, r.output
    report = json.loads((out / "report.json").read_text())
    hems = [row for row in report["fit"] if row["region"].endswith("sleeve hem")]
    assert len(hems) == 2
    for row in hems:
        # the body needs more than cotton's 10 %: too tight to wear (the rule: vfit_engine.fit.verdict)
        assert row["verdict"] == "too tight to wear" and row["required_strain"] > 0.1
        assert row["girth_strain"] >= row["required_strain"] - 0.01
    assert report["fit_summary"].startswith("too tight to wear at the sleeve hems")
    assert {t["region"] for t in report["too_tight"]} >= {"left sleeve hem", "right sleeve hem"}
    assert "the body needs >= " in report["fit_summary"]
    assert {row["region"]: row["verdict"] for row in report["fit"]}["bust"] not in VERDICTS[:2]


def test_a_region_the_garment_goes_round_with_room_is_not_stretched_by_it():
    """The stretch a region puts on the cloth round it: the line's, where the garment as made is shorter round it
    than the body plus 2 pi times the drape's skin (the body stretches it); no more than 0 where it is longer (it
    goes round without stretching: other cloth stretches that line), whatever the line reads."""
    from vfit_engine.drape.settings import DrapeSettings
    from vfit_engine.fit.table import region_stretch

    room = 2 * np.pi * DrapeSettings().contact.skin
    assert region_stretch(0.05, 1.00, 1.02) == 0.05  # made smaller than the body
    assert region_stretch(0.05, 1.00 + room - 1e-6, 1.00) == 0.05  # less room than the cloth's gap
    assert region_stretch(0.05, 1.00 + room, 1.00) == 0.0
    assert region_stretch(0.037, 0.539, 0.400) == 0.0  # the collar of the issue: 14 cm longer than the neck
    assert region_stretch(-0.02, 1.10, 1.00) == -0.02  # bunched stays bunched
    assert region_stretch(0.05, 1.03, 1.00, gap=0.005) == 0.05  # a wider gap leaves 3 cm no room


def test_the_neck_with_ease_is_not_tight(suit02):
    """Issue 33: the shirt's neck row read "tight" (3.7 %) with +15 cm of ease on the issue's customer: its line in
    the neck's plane is the collar standing clear of the neck, held open by the shoulders, longer as made than the
    neck. The neck does not stretch it: not tight; every body region whose garment as made goes round it with room
    reads no stretch. (The default man of the module's drape has the same collar, 7.8 cm longer than his neck: it
    read 1.6 % there before, his upper arms and thighs 1.5-1.6 %.)"""
    from vfit_engine.drape.settings import DrapeSettings

    out, _ = suit02  # the default man: his neck row is the same collar as the customer's of the issue
    report = json.loads((out / "report.json").read_text())
    rows = {r["region"]: r for r in report["fit"]}
    neck = rows["neck"]
    assert neck["ease_cm"] > 5 and neck["garment_made_cm"] - neck["body_girth_cm"] > 5  # 7.8 cm on him
    assert neck["girth_strain"] <= 0.0 and neck["verdict"] not in ("tight", "too tight to wear")
    assert not re.search(r"\bneck\b", report["fit_summary"].split("fitted")[0])  # not among the tight ones
    room = 100 * 2 * np.pi * DrapeSettings().contact.skin
    for r in report["fit"]:
        if r.get("garment_made_cm") is not None and r["garment_made_cm"] - r["body_girth_cm"] >= room:
            assert r["girth_strain"] <= 0.0 and r["verdict"] not in ("tight", "too tight to wear"), r


def test_every_output_of_the_default_man_says_the_same_verdict(suit02):
    """Issue 33's acceptance on a shared garment drape to the end (the preview drawn): the one checker
    (vfit_engine.verdict_check) finds no output giving a region another verdict than its row."""
    from vfit_engine.verdict_check import disagreements

    out, printed = suit02
    assert not disagreements(json.loads((out / "report.json").read_text()), printed)


def _obj(path, scale=1.0):
    """Vertices (m) and polygons of an OBJ from its ``v`` and ``f`` lines alone."""
    verts, polys = [], []
    for line in Path(path).read_text(encoding="utf-8-sig").splitlines():
        if line.startswith("v "):
            verts.append([float(t) for t in line.split()[1:4]])
        elif line.startswith("f "):
            polys.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    return scale * np.asarray(verts), polys


def _top_boundary_loop(polys, pos):
    """The garment's closed boundary loop (its edges each in one polygon) whose middle is highest: a top's
    neckline."""
    from collections import Counter

    count = Counter(tuple(sorted((p[k], p[(k + 1) % len(p)]))) for p in polys for k in range(len(p)))
    nbr = {}
    for a, b in (e for e, c in count.items() if c == 1):
        nbr.setdefault(a, []).append(b)
        nbr.setdefault(b, []).append(a)
    loops, seen = [], set()
    for start in nbr:
        if start in seen:
            continue
        loop, prev, cur = [start], None, start
        seen.add(start)
        while True:
            nxt = [n for n in nbr[cur] if n != prev and n not in seen]
            if not nxt:
                break
            prev, cur = cur, nxt[0]
            seen.add(cur)
            loop.append(cur)
        loops.append(np.asarray(loop))
    return max(loops, key=lambda lp: pos[lp, 1].mean())


def test_the_neckline_with_room_at_its_own_place_is_not_tight(suit02):
    """Issue 33: an opening reads the stretch of its draped loop over its length as made, and the neckline read
    "tight" (3.4 % with +4.8 cm of ease on the issue's customer): the shoulders hold the collar open, the neck
    does not stretch it. An opening is now judged by the rule of the body regions against the body's tape in
    its own plane (not the smallest within +-3 cm, up the neck): longer as made than that tape plus 2 pi times
    the drape's skin, it reads no stretch. Checked against a tape of our own (trimesh's section of body.obj in
    the plane of the draped neckline, scipy's hull) on the default man, whose neckline loop is stretched
    (0.3 % before: read as its stretch)."""
    import trimesh
    from scipy.spatial import ConvexHull

    from vfit_engine.drape.settings import DrapeSettings

    out, _ = suit02
    report = json.loads((out / "report.json").read_text())
    pos, polys = _obj(out / "final.obj")
    rest, _ = _obj(GARMENTS / "male_casualsuit02" / "male_casualsuit02.obj", scale=0.1)  # MakeHuman: dm
    loop = _top_boundary_loop(polys, pos)
    length = lambda p: float(np.linalg.norm(p - np.roll(p, -1, axis=0), axis=1).sum())  # noqa: E731
    made, draped = length(rest[loop]), length(pos[loop])
    centre = pos[loop].mean(axis=0)
    normal = np.linalg.svd(pos[loop] - centre)[2][2]
    bv, bp = _obj(out / "body.obj")
    tris = [[p[0], p[k], p[k + 1]] for p in bp for k in range(1, len(p) - 1)]
    cut = trimesh.Trimesh(bv, tris, process=False).section(plane_origin=centre, plane_normal=normal)
    u = np.cross(normal, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    frame = np.stack([u, np.cross(normal, u)])
    here = []
    for ring in cut.discrete:
        flat = (ring - centre) @ frame.T
        angle = np.unwrap(np.arctan2(flat[:, 1], flat[:, 0]))
        if abs(angle[-1] - angle[0]) > np.pi:  # winds round the neckline's middle: the neck, not an arm
            here.append(ConvexHull(flat).area)
    assert here, "no body loop round the neckline in its plane"
    room = 2 * np.pi * DrapeSettings().contact.skin
    assert draped > made and max(here) < made - room  # stretched, with room round the body at its own place
    row = next(r for r in report["fit"] if r["region"] == "neckline")
    assert row["garment_girth_cm"] == pytest.approx(100 * draped, abs=0.05)
    assert row["body_girth_here_cm"] == pytest.approx(100 * max(here), abs=0.5)
    assert row["girth_strain"] <= 0.0 and row["verdict"] not in VERDICTS[:2]


@pytest.mark.parametrize("name, value, other", [("ease", 50.0, 0.0), ("pressure", 0.0, 4.0), ("strain", 0.15, 0.0)])
def test_preview_garment_pixels_take_the_maps_colour(name, value, other):
    """A garment whose map is one value everywhere is drawn in that value's colour of the map (shaded: the
    pixels' hue, not their brightness, is compared), and a different value gives a different picture."""
    from vfit_engine.fit.outputs import PICTURE_MAPS, map_colours, map_range
    from vfit_engine.preview import render_image

    spec = PICTURE_MAPS[name]
    mat = get_material("cotton")
    vmin, vmax, _ = map_range(name, mat)
    verts, faces = tube(0.15, 32, 8, 0.6)
    mesh = mesh_from_faces(verts, faces)
    n = len(verts)

    def draw(v):
        return render_image(None, None, verts, mesh.triangles(), np.full(n, v), label=spec["label"],
                            unit=spec["unit"], cmap=spec["cmap"], vmin=vmin, vmax=vmax,
                            views=("front",), size=(600, 400)).astype(float) / 255.0

    img = draw(value)
    want = map_colours({spec["key"]: np.array([value])}, name, mat)[0]
    px = img.reshape(-1, 3)
    lit = px[(px.max(axis=1) > 0.05) & (np.ptp(px, axis=1) > 0.05)]  # coloured pixels, not white/grey/black
    chroma = lambda c: (c - c.mean(axis=-1, keepdims=True)) / (np.linalg.norm(c - c.mean(axis=-1, keepdims=True),
                                                                              axis=-1, keepdims=True) + 1e-9)
    match = np.linalg.norm(chroma(lit) - chroma(want), axis=1) < 0.15
    assert match.sum() > 0.05 * img.shape[0] * img.shape[1]
    assert np.abs(draw(other) - img).max() > 0.2


def test_a_chest_at_the_armpits_counts_only_the_cloth_below_them(body_model):
    """A man whose chest is taken just under his armpits (180 cm, chest 106: the arms join the torso 26 mm
    above his bust points): his chest row counts the cloth from 2 cm below its plane up to where the arms
    join, not the armhole edges above; his waist row the full band. A ring of edges stepping up through the
    plane: those above the armpit level are left out."""
    from vfit_engine.body.resolve import resolve_body
    from vfit_engine.fit.table import BAND, FitTable, _Plane, _round_edges

    table = FitTable(resolve_body(body_model, targets={"height": 1.80, "bust": 1.06}, gender="male"), body_model)
    chest = next(p for name, _, p, *_ in table.regions if name == "chest")
    above = table._above["chest"]
    assert 0.0 <= above < BAND and table._above["waist"] == BAND
    sections = table.measurer.sections
    assert sections.apart(table.body_verts, [chest.height, chest.height + above]).all()
    assert not sections.apart(table.body_verts, [chest.height + above + 0.001])[0]
    # eight short edges round the plane at heights -15 .. +18 mm
    ys = chest.height + np.linspace(-0.015, 0.018, 8)
    pos = np.array([[x, y, 0.0] for y in ys for x in (-0.001, 0.001)])
    edges = np.arange(16).reshape(8, 2)
    eq = np.array([[1.0, 0.0, -1.0], [-1.0, 0.0, -1.0], [0.0, 1.0, -1.0], [0.0, -1.0, -1.0]])  # |x|, |z| <= 1 m
    plane = _Plane(np.array([0.0, chest.height, 0.0]), (0.0, 1.0, 0.0))
    assert _round_edges(edges, pos, plane, eq).tolist() == [True] * 8
    kept = _round_edges(edges, pos, plane, eq, above=above)
    assert kept.tolist() == (ys - chest.height <= above).tolist() and 0 < kept.sum() < 8


def test_strain_scale_starts_at_zero_and_marks_the_wearable_stretch():
    """The strain picture's scale: 0 and any compression in the plain cloth colour (compression is not drawn as a
    load), yellow at the fabric's wearable stretch (marked on the bar), red at twice it; it follows the fabric."""
    from vfit_engine.fit.outputs import map_colours, map_range
    from vfit_engine.preview import CLOTH_RGB

    for name, w in (("cotton", 0.10), ("jersey", 0.30)):
        mat = get_material(name)
        assert map_range("strain", mat) == (0.0, 2 * w, ((w, f"{100 * w:g} % wearable"),))
        rgb = map_colours({"strain": np.array([-0.2, -0.01, 0.0, w, 2 * w, 3 * w])}, "strain", mat)
        assert np.allclose(rgb[:3], CLOTH_RGB)
        assert rgb[3, 0] > 0.9 and rgb[3, 1] > 0.8 and rgb[3, 2] < 0.3  # yellow
        assert rgb[4, 0] > 0.8 and rgb[4, 1] < 0.2 and np.allclose(rgb[4], rgb[5])  # red, and beyond
    assert map_range("pressure", get_material("cotton")) == (0.0, 4.0, ())


def test_display_mesh_fans_each_polygon_round_its_centre():
    """The picture's mesh: each n-gon becomes 2n triangles round its centre through its edges' midpoints, covering
    the same area; midpoints and centres carry the means of their corners' values, the corners their own."""
    from vfit_engine.fit.outputs import display_mesh

    verts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], dtype=np.float64)
    mesh = mesh_from_faces(verts, [[0, 1, 2, 3], [1, 4, 2]])
    values = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    v, t, val = display_mesh(mesh, verts, values)
    ne = mesh.edges().shape[0]
    assert t.shape == (2 * 4 + 2 * 3, 3) and len(v) == 5 + ne + 2
    assert np.array_equal(val[:5], values)
    mids = v[5:5 + ne]
    e = mesh.edges()
    assert np.allclose(mids, 0.5 * (verts[e[:, 0]] + verts[e[:, 1]])) and np.allclose(val[5:5 + ne], values[e].mean(1))
    assert np.allclose(v[-2:], [[0.5, 0.5, 0], [4 / 3, 1 / 3, 0]]) and np.allclose(val[-2:], [1.5, 7 / 3])
    area = 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)
    assert area.sum() == pytest.approx(1.5) and np.all(area > 0)
    normal = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2]
    assert np.all(normal > 0)  # the polygons' winding kept
