"""Preview pictures and drape GIFs: our Numba rasterizer timed, and the same picture by PyVista/VTK.

    python benchmarks/bench_preview.py [--body body.obj --garment final.obj] [--frames-dir DIR]
                                       [--size 1500x750] [--repeat 5] [--pvenv /tmp/pvenv] [--out DIR] [--json]

The scene: a body and a garment, from a drape's output (``--body``, ``--garment``) or else the
default male body (13,380 vertices) wearing ``male_casualsuit06`` (3,708 vertices) as made for it.
The garment is coloured by a smooth made-up strain field (-8 .. +8 %, through the strain map and
its colour bar), so the colour path costs what it costs in a real preview.

Reported, for ``render_views`` at ``--size`` (three views, title, colour bar, PNG written):

* the first picture in a fresh process (numba imported, kernels loaded from the cache) and with an
  empty cache (kernels compiled), each in a child process;
* the warm time per picture (median of ``--repeat``), split into rasterize, downsample (the
  supersamples averaged into pixels), text and colour bar, PNG encode, and the rest (checks,
  projection, normals, colours, canvas copies);
* ``write_gif`` of the drape's frames (``--frames-dir`` with ``frame_*.obj``) or of 20 made-up
  frames (the garment lowered 10 cm onto the body) at 600 x 600: ms per frame, split into
  drawing, palette, quantizing and GIF encoding;
* the library route: the same meshes, colours and views rendered off screen by PyVista/VTK in a
  child process of ``--pvenv``'s Python (a throwaway venv with pyvista and vtk; skipped with the
  reason when it is missing): import, first picture, and warm pictures with SSAA and FXAA.
"""
import argparse
import glob
import io
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import median_ms  # noqa: E402

GARMENT = Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments" / "male_casualsuit06" / \
    "male_casualsuit06.obj"

TITLE = "the garment coloured by a made-up strain field"

# Runs in the library's venv: argv = npz file, PNG to write, repeats, anti-aliasing ("ssaa", "fxaa", "none").
LIBRARY_SCRIPT = r'''
import json, sys, time
t0 = time.perf_counter()
import numpy as np
import pyvista as pv
from matplotlib.colors import LinearSegmentedColormap
from PIL import Image
out = dict(import_ms=1000 * (time.perf_counter() - t0), pyvista=pv.__version__, vtk=pv.vtk_version_info[:])
d = np.load(sys.argv[1])
png, repeat, aa = sys.argv[2], int(sys.argv[3]), sys.argv[4]
w, h = (int(s) for s in d["size"])
t0 = time.perf_counter()

def poly(v, t):
    return pv.PolyData(v, np.column_stack([np.full(len(t), 3), t]).ravel())

body, garment = poly(d["body_v"], d["body_t"]), poly(d["garment_v"], d["garment_t"])
garment["strain (%)"] = 100 * d["values"]
cmap = LinearSegmentedColormap.from_list("strain", list(zip(d["cmap_pos"], d["cmap_rgb"])))
pl = pv.Plotter(shape=(1, 3), off_screen=True, window_size=(w, h), border=False)
pl.set_background("white")
centre = np.concatenate([d["body_v"], d["garment_v"]]).mean(axis=0)
for k, (name, direction) in enumerate([("front", (0, 0, 1)), ("side (body's left)", (1, 0, 0)),
                                       ("back", (0, 0, -1))]):
    pl.subplot(0, k)
    pl.add_mesh(body, color=tuple(d["skin"]), smooth_shading=True)
    pl.add_mesh(garment, scalars="strain (%)", cmap=cmap, clim=(-15, 15), smooth_shading=True,
                show_scalar_bar=k == 2, scalar_bar_args=dict(title="yarn strain (%)", vertical=True, color="black"))
    pl.add_text(name, position="lower_edge", font_size=10, color="black")
    pl.camera.position = tuple(centre + 3 * np.array(direction))
    pl.camera.focal_point = tuple(centre)
    pl.camera.up = (0, 1, 0)
    pl.camera.parallel_projection = True
    pl.reset_camera()
if aa != "none":
    pl.enable_anti_aliasing(aa)
out["build_ms"] = 1000 * (time.perf_counter() - t0)
t0 = time.perf_counter()
img = pl.screenshot(return_img=True)
out["first_ms"] = 1000 * (time.perf_counter() - t0)
out["window"] = pl.ren_win.GetClassName()
render, grab, encode = [], [], []
for _ in range(repeat):
    garment.points = garment.points * 1.0  # a new drape: the garment's positions uploaded again
    t0 = time.perf_counter()
    pl.render()
    t1 = time.perf_counter()
    img = pl.screenshot(return_img=True)
    t2 = time.perf_counter()
    Image.fromarray(img).save(png, format="PNG", compress_level=3)
    t3 = time.perf_counter()
    render.append(t1 - t0); grab.append(t2 - t1); encode.append(t3 - t2)
out.update(render_ms=1000 * float(np.median(render)), grab_ms=1000 * float(np.median(grab)),
           encode_ms=1000 * float(np.median(encode)), image=list(img.shape))
print(json.dumps(out))
'''

# Runs in a fresh process of this Python: argv = npz file, PNG; times the first picture.
FIRST_CALL_SCRIPT = r'''
import json, sys, time
t0 = time.perf_counter()
import numpy as np
from vfit_engine.preview import render_views
d = np.load(sys.argv[1])
t1 = time.perf_counter()
render_views(sys.argv[2], d["body_v"], d["body_t"], d["garment_v"], d["garment_t"], d["values"],
             size=tuple(int(s) for s in d["size"]), label="yarn strain", title="first call")
t2 = time.perf_counter()
print(json.dumps(dict(import_ms=1000 * (t1 - t0), first_ms=1000 * (t2 - t1))))
'''


def _scene(args):
    """(body_v, body_t, garment_v, garment_t, values) in metres."""
    from vfit_engine.io.mesh import read_mesh

    if args.body and args.garment:
        body, garment = read_mesh(args.body), read_mesh(args.garment)
        bv, bt, gv, gt = body.verts, body.triangles(), garment.verts, garment.triangles()
    else:
        from vfit_engine.body.model import N_BODY, BodyModel
        from vfit_engine.garment.garment import load_garment

        model = BodyModel.load()
        g = load_garment(GARMENT)  # MakeHuman clothes are made on the default body: no transfer needed
        bv, bt, gv, gt = model.default_verts("male")[:N_BODY], model.body_tris, g.mesh.verts, g.mesh.triangles()
    values = 0.08 * np.sin(9.0 * gv[:, 1] + 5.0 * gv[:, 0]) * np.cos(7.0 * gv[:, 2])
    return [np.ascontiguousarray(a) for a in (bv, bt, gv, gt, values)]


def _frames(args, gv):
    """Garment positions of the GIF: the drape's frames, or 20 steps lowering it 10 cm onto the body."""
    from vfit_engine.io.mesh import read_mesh

    if args.frames_dir:
        files = sorted(glob.glob(os.path.join(args.frames_dir, "frame_*.obj")))
        if files:
            meshes = [read_mesh(f) for f in files]
            return [m.verts for m in meshes], meshes[0].triangles(), f"{len(files)} frames of {args.frames_dir}"
    drop = np.linspace(0.10, 0.0, 20)
    return [gv + [0.0, d, 0.0] for d in drop], None, "20 made-up frames (the garment lowered 10 cm)"


def _timed(module, name, bucket):
    """Wrap ``module.name`` so that each call's wall time is added to ``bucket[name]``."""
    fn = getattr(module, name)

    def wrapper(*a, **k):
        t = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            bucket[name] = bucket.get(name, 0.0) + time.perf_counter() - t

    setattr(module, name, wrapper)
    return fn


def bench_ours(scene, size, repeat):
    """Warm ms of render_views and its split (medians over ``repeat``)."""
    from PIL import Image

    from vfit_engine import preview
    from vfit_engine.kernels import raster

    bv, bt, gv, gt, values = scene
    kw = dict(size=size, label="yarn strain", title=TITLE)
    with tempfile.TemporaryDirectory() as tmp:
        preview.render_views(os.path.join(tmp, "warm.png"), bv, bt, gv, gt, values, **kw)
        total = median_ms(lambda: preview.render_views(os.path.join(tmp, "p.png"), bv, bt, gv, gt, values, **kw),
                          repeat)
    parts = {"rasterize": [], "downsample": [], "decorate": [], "encode": [], "render_image": []}
    saved = {n: getattr(raster, n) for n in ("rasterize", "downsample")}
    saved_decorate = preview.decorate
    try:
        for _ in range(repeat):
            bucket = {}
            for n in saved:
                setattr(raster, n, saved[n])
                _timed(raster, n, bucket)
            preview.decorate = saved_decorate
            _timed(preview, "decorate", bucket)
            t = time.perf_counter()
            image = preview.render_image(bv, bt, gv, gt, values, **kw)
            bucket["render_image"] = time.perf_counter() - t
            t = time.perf_counter()
            Image.fromarray(image, "RGB").save(io.BytesIO(), format="PNG", compress_level=3)
            bucket["encode"] = time.perf_counter() - t
            for n in parts:
                parts[n].append(1000 * bucket.get(n, 0.0))
    finally:
        for n, fn in saved.items():
            setattr(raster, n, fn)
        preview.decorate = saved_decorate
    split = {("text_bar" if n == "decorate" else n): float(np.median(v)) for n, v in parts.items()}
    split["other"] = split.pop("render_image") - split["rasterize"] - split["downsample"] - split["text_bar"]
    return dict(total_ms=total, split_ms=split, image=[size[1], size[0], 3])


def bench_first_call(npz, png):
    """First picture in fresh processes: kernels from the cache, then compiled into an empty cache."""
    out = {}
    for name, extra in [("cached", {}), ("compiled", None)]:
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
            env.update(extra if extra is not None else {"NUMBA_CACHE_DIR": cache})
            res = subprocess.run([sys.executable, "-c", FIRST_CALL_SCRIPT, npz, png], env=env,
                                 capture_output=True, text=True, timeout=600)
        if res.returncode:
            out[name] = dict(error=res.stderr.strip().splitlines()[-1:])
        else:
            out[name] = json.loads(res.stdout.strip().splitlines()[-1])
    return out


def bench_gif(scene, frames, frame_tris, size, repeat):
    """write_gif's ms per frame and its split."""
    from vfit_engine import animation

    bv, bt, _, gt, values = scene
    gt = gt if frame_tris is None else frame_tris
    vals = values if frame_tris is None else None
    n = len(frames)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "d.gif")
        animation.write_gif(path, bv, bt, frames[:2], gt, vals, size=size)  # warm up
        total = median_ms(lambda: animation.write_gif(path, bv, bt, frames, gt, vals, size=size), repeat)
        gif_bytes = os.path.getsize(path)
    t = time.perf_counter()
    pictures = animation.render_frames(bv, bt, frames, gt, vals, size=size)
    t_setup = time.perf_counter() - t
    t = time.perf_counter()
    drawn = list(pictures)
    t_draw = time.perf_counter() - t
    t = time.perf_counter()
    palette = animation._palette([drawn[0], drawn[-1]], pictures.bar)
    t_palette = time.perf_counter() - t
    t = time.perf_counter()
    quantized = [animation._quantize(p, palette) for p in drawn]
    t_quantize = time.perf_counter() - t
    t = time.perf_counter()
    quantized[0].save(io.BytesIO(), format="GIF", save_all=True, append_images=quantized[1:], duration=80,
                      loop=0, optimize=False)
    t_encode = time.perf_counter() - t
    per = lambda s: 1000 * s / n  # noqa: E731
    return dict(frames=n, size=list(size), total_ms=total, ms_per_frame=total / n, gif_bytes=gif_bytes,
                split_ms=dict(setup=1000 * t_setup, palette=1000 * t_palette),
                split_ms_per_frame=dict(draw=per(t_draw), quantize=per(t_quantize), encode=per(t_encode)))


#: A VTK log line's message: "... vtkXOpenGLRenderWindow.:1452  WARN| bad X server connection. DISPLAY=".
_VTK_LOG = re.compile(r"(?:WARN|ERR)\|\s*(.*?)\s*(?:\x1b\[0m)?$")


def bench_library(pvenv, npz, out_dir, repeat):
    """PyVista/VTK off screen in the throwaway venv; a dict per anti-aliasing mode, or the reason it failed."""
    python = Path(pvenv) / "bin" / "python"
    if not python.exists():
        return dict(skipped=f"{python} not found: python3 -m venv {pvenv} && {pvenv}/bin/pip install pyvista "
                            "vtk numpy pillow")
    out = {}
    runs = [("ssaa", {}), ("fxaa", {}), ("ssaa_egl", {"VTK_DEFAULT_OPENGL_WINDOW": "vtkEGLRenderWindow"}),
            ("ssaa_osmesa", {"VTK_DEFAULT_OPENGL_WINDOW": "vtkOSOpenGLRenderWindow"})]
    for name, env_extra in runs:
        env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}  # headless, as on CI
        env.update(env_extra)
        png = os.path.join(out_dir, f"library_{name}.png")
        try:
            res = subprocess.run([str(python), "-c", LIBRARY_SCRIPT, npz, png, str(repeat), name.split("_")[0]],
                                 env=env, capture_output=True, text=True, timeout=300)
        except subprocess.TimeoutExpired:
            out[name] = dict(error="timed out after 300 s")
            continue
        lines = res.stdout.strip().splitlines()
        messages = [m.group(1) for m in map(_VTK_LOG.search, res.stderr.splitlines()) if m]
        if res.returncode or not lines:
            out[name] = dict(error=f"exit {res.returncode}: " + " | ".join(dict.fromkeys(messages or
                                                                                       res.stderr.splitlines()[-1:])))
        else:
            out[name] = json.loads(lines[-1])
            if messages:
                out[name]["warnings"] = list(dict.fromkeys(messages))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--body", help="body mesh (a drape's body.obj)")
    ap.add_argument("--garment", help="garment mesh on it (a drape's final.obj)")
    ap.add_argument("--frames-dir", help="a drape's OUTDIR with frame_*.obj, for the GIF")
    ap.add_argument("--size", default="1500x750", help="picture size WxH [1500x750]")
    ap.add_argument("--gif-size", default="600x600", help="GIF size WxH [600x600]")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--pvenv", default="/tmp/pvenv", help="venv with pyvista and vtk [/tmp/pvenv]")
    ap.add_argument("--no-library", action="store_true", help="skip the PyVista/VTK route")
    ap.add_argument("--out", help="directory to keep the pictures in (ours and the library's)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    size = tuple(int(s) for s in args.size.lower().split("x"))
    gif_size = tuple(int(s) for s in args.gif_size.lower().split("x"))

    from vfit_engine.preview import COLOUR_MAPS, SKIN_RGB, render_views

    scene = _scene(args)
    bv, bt, gv, gt, values = scene
    result = dict(body_vertices=len(bv), body_triangles=len(bt), garment_vertices=len(gv),
                  garment_triangles=len(gt), size=list(size), cores=os.cpu_count(),
                  load_average=os.getloadavg()[0])
    with tempfile.TemporaryDirectory() as tmp:
        out_dir = args.out or tmp
        os.makedirs(out_dir, exist_ok=True)
        npz = os.path.join(tmp, "scene.npz")
        positions, stops, _ = COLOUR_MAPS["strain"]
        np.savez(npz, body_v=bv, body_t=bt, garment_v=gv, garment_t=gt, values=values, size=np.array(size),
                 cmap_pos=np.array(positions), cmap_rgb=np.array(stops), skin=np.array(SKIN_RGB))
        result["first_call"] = bench_first_call(npz, os.path.join(tmp, "first.png"))
        result["ours"] = bench_ours(scene, size, args.repeat)
        render_views(os.path.join(out_dir, "ours.png"), bv, bt, gv, gt, values, size=size, label="yarn strain",
                     title=TITLE)
        frames, frame_tris, what = _frames(args, gv)
        result["gif"] = dict(source=what, **bench_gif(scene, frames, frame_tris, gif_size, max(1, args.repeat // 2)))
        result["library"] = dict(skipped="--no-library") if args.no_library else \
            bench_library(args.pvenv, npz, out_dir, args.repeat)
    if args.json:
        print(json.dumps(result))
        return
    _print(result)


def _print(r):
    print(f"scene: body {r['body_vertices']:,} v / {r['body_triangles']:,} tris, garment {r['garment_vertices']:,} v / "
          f"{r['garment_triangles']:,} tris; {r['size'][0]} x {r['size'][1]} px, 3 views; {r['cores']} cores, "
          f"load average {r['load_average']:.1f}")
    for name, fc in r["first_call"].items():
        print(f"  first picture, fresh process, kernels {name}: " +
              (f"{fc['first_ms']:.0f} ms (+ import {fc['import_ms']:.0f} ms)" if "first_ms" in fc else fc["error"]))
    o = r["ours"]
    print(f"  ours, warm: {o['total_ms']:.0f} ms per picture  (" +
          ", ".join(f"{k} {v:.0f}" for k, v in o["split_ms"].items()) + " ms)")
    g = r["gif"]
    print(f"  write_gif {g['size'][0]} x {g['size'][1]}, {g['source']}: {g['ms_per_frame']:.1f} ms per frame "
          f"({g['total_ms']:.0f} ms, {g['gif_bytes'] / 1e6:.2f} MB); per frame " +
          ", ".join(f"{k} {v:.1f}" for k, v in g["split_ms_per_frame"].items()) + " ms; once " +
          ", ".join(f"{k} {v:.0f}" for k, v in g["split_ms"].items()) + " ms")
    lib = r["library"]
    if "skipped" in lib:
        print(f"  library route skipped: {lib['skipped']}")
        return
    for name, x in lib.items():
        if "error" in x:
            print(f"  pyvista/vtk {name}: FAILED {x['error']}")
            continue
        print(f"  pyvista {x['pyvista']} / vtk {'.'.join(map(str, x['vtk']))} {name} ({x['window']}): import "
              f"{x['import_ms']:.0f} ms, build {x['build_ms']:.0f} ms, first picture {x['first_ms']:.0f} ms; warm "
              f"render {x['render_ms']:.0f} + grab {x['grab_ms']:.0f} + PNG {x['encode_ms']:.0f} ms"
              + (f"  [{x['warnings'][0]}]" if x.get("warnings") else ""))


if __name__ == "__main__":
    main()
