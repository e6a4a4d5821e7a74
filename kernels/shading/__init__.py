"""shading: see docs/architecture.md."""
