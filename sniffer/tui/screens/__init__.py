"""Provides the TUI's screens: the main screen, dialogs, the ladder, the register table and
plot, the full-screen views."""
