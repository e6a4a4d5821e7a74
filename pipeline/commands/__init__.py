"""Every CLI command, one module each; importing this package registers them all."""

from . import demo, info, lightmap_uv, report, trace  # noqa: F401
