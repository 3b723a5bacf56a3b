"""Provides a capture session: a source read into a store, its sidecar index, paged views
and verdicts."""
