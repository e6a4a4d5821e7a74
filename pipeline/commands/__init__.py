"""Every CLI command, one module each; importing this package registers them all."""

from . import (  # noqa: F401
    bump,
    compare,
    demo,
    envmap,
    info,
    lightmap_uv,
    radiosity,
    report,
    shadowmap,
    texture,
    trace,
)
