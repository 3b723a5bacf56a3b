"""Provides modscope's capture side: sources, framing, pairing, annotation, store and CLI."""

__version__ = "0.1.0"
