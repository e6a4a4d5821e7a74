"""bake: see docs/architecture.md."""
