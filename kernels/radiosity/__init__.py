"""radiosity: see docs/architecture.md."""
