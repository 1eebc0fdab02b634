"""``vfit size``: the size run (EN 13402 centres, grading), the recommendation rule, the command."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli
from vfit_engine.fit.verdict import NOT_COVERED, VERDICTS

GARMENTS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments"
SUIT = GARMENTS / "male_casualsuit02" / "male_casualsuit02.obj"
needs_shared = pytest.mark.skipif(not GARMENTS.is_dir(), reason="../shared/assets/garments (MakeHuman clothes) absent")


def run(*args):
    return CliRunner().invoke(cli, ["size", *map(str, args)])


def one_line_error(result, code):
    assert result.exit_code == code, result.output
    lines = [ln for ln in result.output.splitlines() if ln.startswith("Error")]
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    return lines[0]


# -- the rule, on synthetic fit tables

def row(region, verdict, key=True, ease=3.0, strain=0.01):
    return dict(region=region, body_girth_cm=90.0, garment_girth_cm=90.0 + ease, ease_cm=ease, girth_strain=strain,
                max_strain=strain, pressure_kpa_max=0.0, verdict=verdict, key=key)


def size(name, *rows, status="settled", message=None):
    return dict(size=name, status=status, message=message, fit=list(rows) if status in ("settled", "not settled")
                else None)


def test_recommend_the_smallest_size_with_every_region_at_least_fitted():
    from vfit_engine.sizes import recommend

    sizes = [size("XS", row("chest", "tight", ease=-2.1, strain=0.05), row("waist", "tight")),
             size("S", row("chest", "tight", ease=-0.4, strain=0.04), row("waist", "fitted")),
             size("M", row("chest", "fitted"), row("waist", "fitted"), row("hips", "loose", ease=14)),
             size("L", row("chest", "loose", ease=13), row("waist", "loose", ease=13))]
    name, reason = recommend(sizes)
    assert name == "M"
    assert reason.startswith("M: the smallest size with every region at least fitted")
    assert "S is tight at the chest (ease -0.4 cm, stretched 4.0 %)" in reason
    # the order the sizes come in does not matter; a dict from try_sizes is taken as well
    assert recommend({"sizes": sizes[::-1]})[0] == "M"


def test_recommend_every_size_tight_gives_the_largest_saying_so():
    from vfit_engine.sizes import recommend

    name, reason = recommend([size(s, row("chest", "tight", ease=-1.0 * i), row("hips", "fitted"))
                              for i, s in enumerate(("S", "M", "L"))])
    assert name == "L"
    assert "every size tried is tight somewhere" in reason and "still tight at the chest (ease -2.0 cm" in reason


def test_a_tight_region_anywhere_rejects_a_size_and_says_where():
    """Every region of the table decides (issue 33): an upper arm or a sleeve hem too small rejects the size as the
    chest does, and the rejection names it; a region not covered (no verdict) rejects nothing."""
    from vfit_engine.fit.verdict import uncovered_row
    from vfit_engine.sizes import recommend, rejection

    arm = row("left upper arm", "too tight to wear", key=False, ease=1.4, strain=0.17)
    sizes = [size("XS", row("chest", "fitted"), arm),
             size("S", row("chest", "fitted"), row("left sleeve hem", "tight", key=False, strain=0.05)),
             size("M", row("chest", "loose", ease=13), uncovered_row("neck", "", 0.40, False))]
    name, reason = recommend(sizes)
    assert name == "M" and "S is tight at the left sleeve hem (ease +3.0 cm, stretched 5.0 %)" in reason
    assert rejection(sizes[0]) == "tight at the left upper arm (too tight to wear, ease +1.4 cm, stretched 17.0 %)"
    assert rejection(sizes[2]) is None


def test_recommend_passes_over_sizes_without_a_verdict():
    from vfit_engine.sizes import recommend

    sizes = [size("S", status="diverged", message="simulation diverged at frame 12"),
             size("M", row("chest", "fitted"), status="not settled", message="not settled within 300 frames"),
             size("L", row("chest", "loose", ease=13))]
    name, reason = recommend(sizes)
    assert name == "M"
    assert "S not judged (diverged" in reason and "M judged on its last frame" in reason
    assert "the smallest size tried" in reason
    assert recommend([size("S", status="failed", message="x")])[0] is None


def test_size_names_and_centres():
    from vfit_engine.errors import InputError
    from vfit_engine.sizes import SIZE_NAMES, parse_sizes, size_centres

    assert parse_sizes(" m,xs ,L") == ["XS", "M", "L"]
    for bad in ("S,XXL", "", ",,"):
        with pytest.raises(InputError):
            parse_sizes(bad)
    for gender in ("female", "male", 0.8):
        c = size_centres(gender)
        assert tuple(c) == SIZE_NAMES
        for key in ("bust", "waist", "hips"):  # each a step larger than the last
            assert np.all(np.diff([c[s][key] for s in SIZE_NAMES]) > 0)
    assert size_centres("male")["M"] == {"bust": 0.98, "waist": 0.86, "hips": 0.98}


def test_the_size_of_the_garment_as_given_is_the_centre_nearest_its_body(body_model, measurer):
    from vfit_engine.body.resolve import default_body
    from vfit_engine.sizes import garment_size

    male = garment_size(default_body(body_model, "male"), "male", measurer)
    female = garment_size(default_body(body_model, "female"), "female", measurer)
    # his chest under the armpits, ISO 8559-1's (97.25 within 3 cm above the nipples; before that 96.65)
    assert (male["size"], male["measure"]) == ("M", "chest") and abs(male["body_cm"] - 98.82) < 0.1
    assert (female["size"], female["measure"]) == ("S", "bust") and abs(female["body_cm"] - 84.49) < 0.1


def test_a_size_body_is_the_size_centre_at_the_height_asked(body_model, measurer):
    from vfit_engine.sizes import size_body

    b = size_body(body_model, "male", "L", 1.80)
    m = measurer.measure(b.verts, names=("height", "bust", "waist", "hips"), mass=False, gender="male").values
    for k, want in (("height", 1.80), ("bust", 1.06), ("waist", 0.94), ("hips", 1.05)):
        assert abs(m[k] - want) < 0.001, k
    assert b.has_helpers  # the .mhclo bindings need them


# -- grading

@needs_shared
def test_grade_is_the_drape_set_up_graded_rest_and_places_on_its_size_body(body_model):
    from vfit_engine.drape import prepare_drape
    from vfit_engine.sizes import grade, size_body
    from vfit_engine.garment.garment import load_garment

    g = load_garment(SUIT)
    s = size_body(body_model, "male", "S", 1.80)
    graded = grade(g, s, body_model)
    # the same rest shape as the drape set-up's made-to-measure mode
    assert np.allclose(graded.verts, prepare_drape(g, s, body_model, pin="none", rest="graded").rest, atol=1e-12)
    assert graded.verts is not g.verts and graded.mesh.face_verts is g.mesh.face_verts
    assert graded.binding() is not None
    # the graded garment sits on its size body as the garment as given sits on its own: its binding
    # places it as the file gives it (it is not refitted) and on the same body it is not moved
    setup = prepare_drape(graded, s, body_model, reference=s, pin="none")
    assert setup.info["placement"]["placed"] == "file" and setup.info["placement"]["file_gap_mm"] < 30
    assert setup.info["transfer"]["identity"]


# -- a size that does not settle or diverges

@needs_shared
def test_a_diverged_size_has_a_status_and_no_verdict(body_model, monkeypatch):
    import vfit_engine.sizes as sizes
    from vfit_engine.drape import DrapeDiverged
    from vfit_engine.sizes import try_sizes

    def diverge(setup, settings=None, on_frame=None):
        raise DrapeDiverged("simulation diverged at frame 3 (a vertex at 99 m/s); last good frame 2", frame=3)

    monkeypatch.setattr(sizes, "run_drape", diverge)  # the name the size run calls
    res = try_sizes(SUIT, {"gender": "male"}, sizes=["M"], workers=1, model=body_model)
    (m,) = res["sizes"]
    assert m["status"] == "diverged" and m["fit"] is None and "diverged at frame 3" in m["message"]
    assert res["recommended"] is None and res["reason"].startswith("no size could be judged")
    r = run(SUIT, "--sizes", "M", "--workers", "1", "--quiet")
    assert "no size could be judged" in one_line_error(r, 3)


# -- the command

def test_help_lists_the_rule_and_imports_no_numba():
    r = CliRunner().invoke(cli, ["size", "--help"])
    assert r.exit_code == 0 and "--sizes" in r.output and "smallest size whose every region is at least" in r.output
    code = ("import sys\nfrom click.testing import CliRunner\nfrom vfit_cli.main import cli\n"
            "assert CliRunner().invoke(cli, ['size', '--help']).exit_code == 0\n"
            "print('numba' in sys.modules, 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


@pytest.mark.parametrize("args, needle", [
    (["--sizes", "S,XXL"], "unknown size 'XXL'"),
    (["--sizes", ","], "no size given"),
    (["--body", "nowhere.obj", "--waist", "80"], "either --body or measurement options"),
    (["--json", "fit.txt"], "use one of .json"),
])
def test_bad_options_exit_2_with_one_line(tmp_path, args, needle):
    garment = tmp_path / "g.obj"
    garment.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert needle in one_line_error(run(garment, *args), 2)


def test_a_missing_garment_exits_2(tmp_path):
    assert "garment file not found" in one_line_error(run(tmp_path / "nothing.obj"), 2)


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    """``vfit size male_casualsuit02.obj --gender male --height 180 --bust 98 --workers 2 --json``: all five
    sizes, in processes; (result, JSON)."""
    out = tmp_path_factory.mktemp("size") / "fit.json"
    r = run(SUIT, "--gender", "male", "--height", 180, "--bust", 98, "--workers", 2, "--json", out)
    assert r.exit_code == 0, r.output
    return r, json.loads(out.read_text()), out.parent


@needs_shared
@pytest.mark.slow
def test_the_acceptance_sizes_and_the_recommendation_never_shrinks(body_model, full_run):
    """The issue's acceptance case, ``vfit size male_casualsuit02.obj --gender male --height 180 --bust C``:
    S, M, L, XL for C = 90, 98, 106, 114 cm. C = 98 is the full run of the command (all five sizes); as
    the rule decides from the sizes up to the answer, each other customer tries the size below the
    expected one (tight somewhere) and that one (every region at least fitted), the two in processes of one thread
    each (two threads per drape in this process crawl when another program takes a core)."""
    from vfit_engine.sizes import SIZE_NAMES, try_sizes

    got = {98: full_run[1]["recommended"]}
    for chest, want in ((90, "S"), (106, "L"), (114, "XL")):
        below = SIZE_NAMES[SIZE_NAMES.index(want) - 1]
        res = try_sizes(SUIT, {"targets": {"height": 1.80, "bust": chest / 100}, "gender": "male"},
                        sizes=[below, want], workers=2, model=body_model)
        got[chest] = res["recommended"]
        assert f"{below} is tight at the" in res["reason"], res["reason"]
    assert [got[c] for c in sorted(got)] == ["S", "M", "L", "XL"]
    ranks = [SIZE_NAMES.index(got[c]) for c in sorted(got)]
    assert ranks == sorted(ranks)  # never smaller as the customer grows


@needs_shared
@pytest.mark.slow
def test_the_command_tries_five_sizes_in_processes_and_writes_the_json(full_run):
    r, res, where = full_run
    assert "recommended size: M -- M: the smallest size with every region at least fitted" in r.stdout
    assert "rejected XS: tight at the " in r.stdout and "rejected S: tight at the " in r.stdout
    assert "the garment as given is size M" in r.stdout and "chest*" in r.stdout
    assert "vfit size: size " in r.stderr  # progress
    assert res["recommended"] == "M" and res["garment_size"]["size"] == "M"
    assert [s["size"] for s in res["sizes"]] == ["XS", "S", "M", "L", "XL"]
    assert res["workers"] == 2 and abs(res["customer"]["bust"] - 98) < 0.1 and abs(res["size_height_cm"] - 180) < 0.1
    for s in res["sizes"]:
        assert s["status"] in ("settled", "not settled"), s
        keys = {r["region"] for r in s["fit"] if r["key"]}
        # a size too small for the customer rides up: size S's shirt leaves the waist plane of this customer (whose
        # waist, not given, follows the population: 77.8 cm), so its table has no waist row; the others have all three
        assert keys >= ({"chest", "hips"} if s["size"] in ("XS", "S") else {"chest", "waist", "hips"}), (s["size"], keys)
        for r in s["fit"]:
            assert r["verdict"] in VERDICTS + (NOT_COVERED,)
            assert set(r) >= {"region", "body_girth_cm", "garment_girth_cm", "ease_cm", "max_strain", "verdict",
                              "key"}
    assert [p.name for p in where.iterdir()] == ["fit.json"]  # written atomically: no temporary file left
    # the garment's own chest, as made, grows with the size as the grading says (issue 33; the draped girth of
    # the sizes stretched round him is his chest plus the cloth's gap, the same in each); his chest row is the
    # chest he gave
    chest = [next(r for r in s["fit"] if r["region"] == "chest") for s in res["sizes"]]
    made = [r["garment_made_cm"] for r in chest]
    assert np.all(np.diff(made) > 0), made
    assert all(abs(r["body_girth_cm"] - 98.0) < 0.1 for r in chest)
    assert "made cm" in full_run[0].stdout
