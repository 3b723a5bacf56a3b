"""Provides the TUI's widgets: the frame list, details, units pane, register watch, status
bar, key bar and prompt."""
