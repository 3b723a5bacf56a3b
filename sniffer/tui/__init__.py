"""Provides the Textual TUI: a virtual frame list, details, filters, units and register watch.

Only this package imports Textual; the CLI imports `app.run_tui` inside the commands that
show the TUI, so a listing never loads Textual.
"""
