"""What an animated fitting writes: the report with every frame's figures and the time per frame, the animated
GLB and the preview GIF.

The quality bars of every frame (issue 13, section 5; the drape's surface definition): no sampled point of
the cloth surface deeper than :data:`MAX_DEPTH_MM` in the body, at most :data:`MAX_INSIDE_PERCENT` of the
samples inside, yarn strain p99 at most :data:`MAX_P99_STRAIN`.

A frame that misses a bar is named with what the user should make of it (``cause`` of each failed frame,
``verdict`` of the whole):

* ``simulation``: the skin came through the cloth (the depth or inside bar): the collision let it through,
  the picture is wrong there, not the garment; the fit is not to be judged by those frames
  (``vfit animate`` exits 5);
* ``garment``: the cloth stays outside the skin but the motion stretches it past the strain bar: the garment is
  too tight for the motion (beyond what the fabric gives when its p99 strain is over
  ``Material.wearable_stretch``): an answer about the garment, not a fault (exit 0).
"""
from __future__ import annotations

import numpy as np

from vfit_engine.animation import write_gif
from vfit_engine.body.bodyio import body_mesh
from vfit_engine.body.model import N_BODY
from vfit_engine.drape.metrics import vertex_strain
from vfit_engine.fit.outputs import PICTURE_MAPS, display_mesh, map_range
from vfit_engine.io.gltf import ScenePart, write_animation_glb

#: The quality bars of every frame (module docstring).
MAX_DEPTH_MM = 2.0
MAX_INSIDE_PERCENT = 1.0
MAX_P99_STRAIN = 0.08
#: The figures of each frame in ``report.json["frames"]``, in order.
FRAME_KEYS = ("time_s", "surface_inside_percent", "surface_max_depth_mm", "surface_deeper_than_2mm", "p99_strain",
              "max_strain", "pressure_max_kpa", "max_step_mm", "slowed_vertices")
#: GIF: at most this many frames, evenly spread.
GIF_FRAMES = 90


def quality(figures, first=1, limit=None):
    """The frames from ``first`` on that miss a quality bar (module docstring): dict ``passed``,
    ``failed_frames`` (frame, why, cause), ``simulation_frames`` and ``garment_frames`` (how many of each
    cause), ``verdict`` (what the user should make of it, None when every frame passes) and ``bars``;
    ``limit`` is the fabric's wearable stretch (fraction), or None."""
    failed = []
    for k, f in enumerate(figures[first:], start=first):
        why = []
        if f["surface_max_depth_mm"] > MAX_DEPTH_MM:
            why.append(f"surface {f['surface_max_depth_mm']:.2f} mm deep")
        if f["surface_inside_percent"] > MAX_INSIDE_PERCENT:
            why.append(f"{f['surface_inside_percent']:.2f} % inside")
        through = bool(why)
        if f["p99_strain"] > MAX_P99_STRAIN:
            why.append(f"strain p99 {100 * f['p99_strain']:.1f} %")
        if why:
            failed.append(dict(frame=k, why=", ".join(why), cause="simulation" if through else "garment"))
    sim = [f for f in failed if f["cause"] == "simulation"]
    worn = [f for f in failed if f["cause"] == "garment"]
    verdict = None
    if sim:
        verdict = (f"the simulation's fault in {len(sim)} frame(s) (first {sim[0]['frame']}: {sim[0]['why']}): the "
                   "skin came through the cloth there, which a garment does not do; do not judge the fit by those frames")
    if worn:
        top = max(figures[f["frame"]]["p99_strain"] for f in worn)
        beyond = limit is not None and top > limit
        text = (f"the garment is too tight for the motion in {len(worn)} frame(s) (first {worn[0]['frame']}: "
                f"{worn[0]['why']}): the body stretches it up to {100 * top:.1f} % (p99)"
                + ("" if limit is None else f", {'beyond' if beyond else 'within'} the {100 * limit:.0f} % the "
                   "fabric gives"))
        verdict = text if verdict is None else verdict + "; " + text
    return dict(passed=not failed, failed_frames=failed, simulation_frames=len(sim), garment_frames=len(worn),
                verdict=verdict,
                bars=dict(surface_max_depth_mm=MAX_DEPTH_MM, surface_inside_percent=MAX_INSIDE_PERCENT,
                          p99_strain=MAX_P99_STRAIN))


def animation_report(drape, anim, settings, limit=None, **context):
    """``report.json`` of an animation: the rest drape, the motion, every frame's figures, their maxima, the
    quality bars (``limit``: the fabric's wearable stretch, :func:`quality`) and the time per frame split into
    posing, collision and cloth."""
    n = max(anim.frames, 1)
    t = anim.timings
    ms = {k: round(1000.0 * v / n, 2) for k, v in t.items()}
    figures = anim.figures
    rows = [dict(frame=k, **{key: _num(f[key]) for key in FRAME_KEYS}) for k, f in enumerate(figures)]
    maxima = {key: _num(max(f[key] for f in figures[1:] or figures)) for key in FRAME_KEYS[1:-2]}
    sim = t["simulation"]
    return dict(
        command="animate", **context,
        rest_drape=dict(converged=drape.converged, frames=drape.frames, wall_time_s=round(drape.wall_time, 3),
                        surface_max_depth_mm=drape.metrics.get("surface_max_depth_mm"),
                        p99_strain=drape.metrics.get("p99_strain")),
        motion=anim.info["clip"], fps=settings.fps, frames=anim.frames, duration_s=anim.frames / settings.fps,
        blend_s=settings.blend_s, skinning=settings.skinning, settled=anim.settled,
        substeps_per_frame=anim.info["substeps"], body_moves_per_frame=anim.info["body_moves_per_frame"],
        collider=anim.info["collider"], solver=anim.info["solver"], matrix_refactors=anim.info["matrix_refactors"],
        ms_per_frame=dict(simulation=ms["simulation"], posing=ms["posing"], collision=ms["collision"],
                          cloth=ms["cloth"], figures=ms["figures"]),
        collision_share=round(t["collision"] / sim, 4) if sim > 0 else 0.0,
        frames_per_second_wall=round(n / sim, 2) if sim > 0 else None,
        maxima=maxima, quality=quality(figures, limit=limit), frame_figures=rows,
        slowed_vertices=int(sum(f["slowed_vertices"] for f in figures)), max_speed_m_s=settings.max_speed,
        units=dict(mesh="m", time="s", depth="mm", strain="fraction", pressure="kPa", ms_per_frame="ms"))


def _num(x):
    x = float(x)
    return round(x, 6) if np.isfinite(x) else None


def write_animation(path, setup, model, bodies, cloth, fps):
    """``animation.glb``: the body and the garment in every frame (:func:`vfit_engine.io.gltf.write_animation_glb`)."""
    parts = [ScenePart("body", body_mesh(model, bodies[0])), ScenePart("garment", setup.garment.mesh)]
    return write_animation_glb(path, parts, [np.asarray(bodies)[:, :N_BODY], np.asarray(cloth)], fps)


def write_preview_gif(path, setup, model, bodies, cloth, fps):
    """``preview.gif``: the garment coloured by yarn strain on the moving body, from the front and the side, at
    most :data:`GIF_FRAMES` frames; the strain on the still preview's scale and colour bar (0 to twice the
    fabric's wearable stretch, marked: :func:`vfit_engine.fit.outputs.map_range`), so the two pictures read alike."""
    pick = np.unique(np.linspace(0, len(cloth) - 1, min(len(cloth), GIF_FRAMES)).round().astype(int))
    mesh = setup.garment.mesh
    # drawn as the still preview draws it (fit.outputs.display_mesh: every polygon fanned from its centre through
    # its edges' midpoints), so the colours run smoothly over a quad instead of splitting along one diagonal
    shown = [display_mesh(mesh, cloth[k], vertex_strain(mesh, cloth[k])) for k in pick]
    labels = [f"{k / fps:.2f} s" for k in pick]
    spec = PICTURE_MAPS["strain"]
    vmin, vmax, marks = map_range("strain", setup.material)
    return write_gif(path, bodies[pick[0]], model.body_tris, [v for v, _, _ in shown], shown[0][1],
                     np.stack([c for _, _, c in shown]), fps=min(max(fps * len(pick) / len(cloth), 1.0), 50.0),
                     view=("front", "side"),
                     size=(800, 600), labels=labels, body_frames=[bodies[k] for k in pick], label=spec["label"],
                     unit=spec["unit"], cmap=spec["cmap"], vmin=vmin, vmax=vmax, marks=marks)
