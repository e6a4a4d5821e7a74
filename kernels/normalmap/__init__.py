"""Normal maps made, not only read (issue 40): tangent frames per face corner (MikkTSpace, as
Blender's `Mesh.calc_tangents` computes them, and the lecture's per-triangle frame), height sources
(images and named procedural patterns), height -> tangent-space normal maps, dilation across UV
borders and encoding to 8-bit or float arrays.

| module | what |
|--------|------|
| `mikktspace` | MikkTSpace tangents and bitangent signs per face corner, equal to Blender's |
| `lecture_frame` | the lecture's frame (t from the UV direction, b = n x t) and the angle between frames |
| `heights` | height sources: an image with a wrap mode, or a procedural pattern by name |
| `texture_height` | a material's Bump-node height (a kernel `Texture`) as a height source |
| `surface_metric` | a relief in metres on a stretched UV map: each texel's slope matrix |
| `from_height` | `NormalMapSettings` and height -> tangent-space normal map |
| `dilate` | padding of a map's charts outward across UV borders |
| `encode` | normals <-> rgb, to uint8 and float32 arrays |
"""
