"""The tests textile labs run on a fabric, run on the cloth solver: the cantilever (:mod:`.cantilever`) and
the Cusick drape test (:mod:`.cusick`), on specimens meshed at a chosen spacing (:mod:`.specimen`)."""
