"""A drape's fit outputs: ``fit.ply`` (the maps), ``scene.glb`` (body and coloured garment), ``preview.png``.

The colours of a map are the same in the picture and the scene (:data:`PICTURE_MAPS`, :func:`map_range`): ease on
0 .. 50 mm and pressure on 0 .. 4 kPa (the top of medical compression stockings' class II, 3.1-4.3 kPa), so
pictures of different drapes compare; values beyond an end take the end's colour. Strain is drawn on a sequential
scale from 0 to twice the fabric's wearable stretch (:data:`vfit_engine.preview.COLOUR_MAPS` ``stretch``): 0 and
below in the plain cloth colour (cloth shorter than given is gathered or buckled and carries nothing: it is not
drawn as compression), yellow at the wearable stretch, which the colour bar marks, red at twice it.

The picture draws each polygon as a fan of triangles round its centre through its edges' midpoints
(:func:`display_mesh`), the map's values at the corners (the fit map's, as the fit table takes them) and their
means at the midpoints and centres, interpolated across each triangle: colours run smoothly over the cloth and
the same way in every direction. Split into two triangles along one diagonal, a quad showed the diagonal's two
corners' colours along it and the other two only in their corners (blocky quads, streaks along the diagonals).
"""
from __future__ import annotations

import os

import numpy as np

from vfit_engine.body.bodyio import body_mesh
from vfit_engine.fit.maps import MAP_UNITS
from vfit_engine.fit.verdict import tight_line
from vfit_engine.io.gltf import ScenePart, write_scene_glb
from vfit_engine.io.ply import write_ply
from vfit_engine.preview import colour_map, render_views

#: ``--map`` name -> the fit map drawn, the colour bar's label and unit, the colour map and its range (strain:
#: from the fabric, :func:`map_range`).
PICTURE_MAPS = {
    "strain": dict(key="strain", label="yarn strain", unit="%", cmap="stretch", vmin=0.0, vmax=None),
    "ease": dict(key="ease_mm", label="ease from the skin", unit="mm", cmap="viridis", vmin=0.0,
                 vmax=50.0),
    "pressure": dict(key="pressure_kpa", label="contact pressure", unit="kPa", cmap="viridis", vmin=0.0, vmax=4.0),
}


def map_range(name, material):
    """(vmin, vmax, marks) of the fit map ``name`` for a garment of ``material``: strain runs from 0 to twice the
    fabric's wearable stretch, marked on the bar; the other maps have fixed ranges and no marks."""
    spec = PICTURE_MAPS[name]
    if name != "strain":
        return spec["vmin"], spec["vmax"], ()
    w = float(material.wearable_stretch)
    return 0.0, 2.0 * w, ((w, f"{100.0 * w:g} % wearable"),)


def map_colours(maps, name, material):
    """(n, 3) float sRGB colours of the fit map ``name`` (a key of :data:`PICTURE_MAPS`) of a garment of
    ``material``, at its vertices."""
    spec = PICTURE_MAPS[name]
    vmin, vmax, _ = map_range(name, material)
    return colour_map(maps[spec["key"]], spec["cmap"], vmin, vmax)


def display_mesh(mesh, pos, values):
    """The garment as the picture draws it (module docstring): (verts (n + E + F, 3), tris (T, 3) int64, values
    (n + E + F,)), the corners first (``pos``, ``values``), then the edges' midpoints (``mesh.edges()`` order) and
    the polygons' centres, each with the mean of its corners' values."""
    edges = mesh.edges()
    n, ne = mesh.n_verts, edges.shape[0]
    fo, fv = mesh.face_offsets, mesh.face_verts
    sizes = np.diff(fo)
    face = np.repeat(np.arange(sizes.size), sizes)
    nxt = fv[fo[face] + (np.arange(fv.size) - fo[face] + 1) % sizes[face]]
    a, b = np.minimum(fv, nxt).astype(np.int64), np.maximum(fv, nxt).astype(np.int64)
    key = edges[:, 0].astype(np.int64) * n + edges[:, 1]
    order = np.argsort(key)
    corner_edge = order[np.minimum(np.searchsorted(key[order], a * n + b), ne - 1)]  # to the next corner
    real = (a != b) & (key[corner_edge] == a * n + b)  # a repeated corner is no edge
    prev = fo[face] + (np.arange(fv.size) - fo[face] - 1) % sizes[face]
    values = np.asarray(values, dtype=np.float64)
    centre_pos = np.stack([np.bincount(face, weights=pos[fv, k], minlength=sizes.size) for k in range(3)], 1)
    verts = np.concatenate([pos, 0.5 * (pos[edges[:, 0]] + pos[edges[:, 1]]), centre_pos / sizes[:, None]])
    vals = np.concatenate([values, 0.5 * (values[edges[:, 0]] + values[edges[:, 1]]),
                           np.bincount(face, weights=values[fv], minlength=sizes.size) / sizes])
    c = n + ne + face
    # each corner: (centre, the midpoint of the edge before it, the corner) and (centre, the corner, the next one)
    tris = np.concatenate([np.stack([c, n + corner_edge[prev], fv], 1)[real[prev]],
                           np.stack([c, fv, n + corner_edge], 1)[real]])
    return verts, tris.astype(np.int64), vals


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
                           ScenePart("garment", setup.garment.mesh, pos,
                                     colors=map_colours(maps, name, setup.material))])


def write_preview(path, setup, pos, model, maps, name="strain", title=None, rows=None):
    """``preview.png``: body and garment from the front, the side and the back, the garment coloured by the
    map ``name`` (drawn through :func:`display_mesh`) with a colour bar in its unit; with the fit table's ``rows``
    the title says where it is tight (:func:`.verdict.tight_line`: the rows' verdicts)."""
    spec = PICTURE_MAPS[name]
    mesh = setup.garment.mesh
    garment = os.path.basename(str(setup.garment.source))
    verts, tris, values = display_mesh(mesh, pos, maps[spec["key"]])
    vmin, vmax, marks = map_range(name, setup.material)
    render_views(path, setup.body.surface, model.body_tris, verts, tris, values, label=spec["label"],
                 unit=spec["unit"], cmap=spec["cmap"], vmin=vmin, vmax=vmax, marks=marks,
                 title=title or (f"{garment}: {tight_line(rows)}" if rows is not None else
                                 f"{garment}: {spec['label']}" + (" against the garment as given" if name == "strain"
                                                                  else "")))
