"""Offline reference renderer (see render.py)."""
