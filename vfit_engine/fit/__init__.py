"""How a draped garment fits: per-vertex maps (:mod:`.maps`, ``fit.ply``) and a table per body region
(:mod:`.table`, ``report.json["fit"]``)."""
