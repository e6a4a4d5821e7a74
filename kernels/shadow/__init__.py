"""shadow: see docs/architecture.md."""
