"""Radiosity: the diffuse light of a whole scene solved on patches, then read out at texels, corners
and pixels (docs/architecture.md, docs/techniques/radiosity.md).

Entry points: `solve.radiosity_steps` / `solve.solve_radiosity` (settings: `settings.py`, result:
`result.py`), `lightmap.bake_steps`, `view.render_steps`.

The solve: `patches.py` (the mesh), `sources.py` and `lamps.py` (what the patches start from),
`emitters.py` (emissive triangles gathered directly), `planning.py` (auto settings, memory, the
solver), `levels.py` and `solve.py` (the level loop), `patch_levels.py` and `solvers.py` (the
matrix solvers), `hierarchical.py` and `source_clusters.py` (the hierarchy), `clusters.py`
(grouped patches), `refine.py` (splits), `form_factors/` (the factors), `final_gather.py` and
`elements.py` (the read-out).
"""
