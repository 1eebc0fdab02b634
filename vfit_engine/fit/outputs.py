"""A drape's fit outputs: ``fit.ply`` (the maps), ``scene.glb`` (body and coloured garment), ``preview.png``.

The colours of a map are the same in the picture and the scene (:data:`PICTURE_MAPS`): strain on the
diverging strain scale of the preview (-15 .. +15 %), ease on 0 .. 50 mm and pressure on 0 .. 4 kPa (the
range of medical compression garments, 1.3-4 kPa, is its top), so pictures of different drapes compare;
values beyond an end take the end's colour.
"""
from __future__ import annotations

import os

from vfit_engine.body.bodyio import body_mesh
from vfit_engine.fit.maps import MAP_UNITS
from vfit_engine.fit.verdict import tight_line
from vfit_engine.io.gltf import ScenePart, write_scene_glb
from vfit_engine.io.ply import write_ply
from vfit_engine.preview import colour_map, render_views

#: ``--map`` name -> the fit map drawn, the colour bar's label and unit, the colour map and its range.
PICTURE_MAPS = {
    "strain": dict(key="strain", label="yarn strain", unit="%", cmap="strain", vmin=None, vmax=None),
    "ease": dict(key="ease_mm", label="ease from the skin", unit="mm", cmap="viridis", vmin=0.0,
                 vmax=50.0),
    "pressure": dict(key="pressure_kpa", label="contact pressure", unit="kPa", cmap="viridis", vmin=0.0, vmax=4.0),
}


def map_colours(maps, name):
    """(n, 3) float sRGB colours of the fit map ``name`` (a key of :data:`PICTURE_MAPS`)."""
    spec = PICTURE_MAPS[name]
    return colour_map(maps[spec["key"]], spec["cmap"], spec["vmin"], spec["vmax"])


def write_fit_ply(path, setup, pos, maps):
    """``fit.ply``: the draped garment (metres, its vertex order and polygons) with the maps as float
    vertex properties (:data:`vfit_engine.fit.maps.MAP_NAMES`; units in the header's comments)."""
    units = ", ".join(f"{k} {MAP_UNITS[k]}" for k in maps)
    header = [f"vfit fit maps of {os.path.basename(str(setup.garment.source))} on the "
              f"{setup.body.description.get('source')} body; metres, Y up", f"vertex properties: {units}",
              "strain against the garment as given; ease_mm signed distance from the skin (negative inside); "
              "pressure_kpa by Laplace's law from the fabric's stretch stiffness; contact 1 within 5 mm of the skin"]
    write_ply(path, setup.garment.mesh.with_verts(pos), header=header, properties=maps)


def write_scene(path, setup, pos, model, maps, name="strain"):
    """``scene.glb``: the body (hm08, UVs) and the draped garment (its UVs) coloured by the map ``name``."""
    write_scene_glb(path, [ScenePart("body", body_mesh(model, setup.body.verts)),
                           ScenePart("garment", setup.garment.mesh, pos, colors=map_colours(maps, name))])


def write_preview(path, setup, pos, model, maps, name="strain", title=None, rows=None):
    """``preview.png``: body and garment from the front, the side and the back, the garment coloured by the
    map ``name`` with a colour bar in its unit; with the fit table's ``rows`` the title says where it is tight
    (:func:`.verdict.tight_line`: the rows' verdicts)."""
    spec = PICTURE_MAPS[name]
    garment = os.path.basename(str(setup.garment.source))
    render_views(path, setup.body.surface, model.body_tris, pos, setup.garment.mesh.triangles(),
                 maps[spec["key"]], label=spec["label"], unit=spec["unit"], cmap=spec["cmap"], vmin=spec["vmin"],
                 vmax=spec["vmax"], title=title or (f"{garment}: {tight_line(rows)}" if rows is not None else
                                                    f"{garment}: {spec['label']}"
                                                    + (" against the garment as given" if name == "strain" else "")))
