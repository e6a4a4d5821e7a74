"""Every CLI command, one module each; importing this package registers them all."""

from . import compare, demo, info, lightmap_uv, radiosity, report, shadowmap, trace  # noqa: F401
