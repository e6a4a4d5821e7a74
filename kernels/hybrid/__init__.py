"""Radiosity and ray tracing together: the two-pass renderer the lecture ends on (`two_pass.py`)."""
