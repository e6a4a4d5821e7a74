"""envmap: see docs/architecture.md."""
