"""Provides the Textual TUI: a virtual frame list, details, filters, units and register watch.

Only this package imports Textual. `commands` registers the `tui` and `serve` commands
without importing it; `app.run_tui` starts the app.
"""
