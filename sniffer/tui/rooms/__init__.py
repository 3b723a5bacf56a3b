"""Provides the rooms of the TUI app: one controller per pane or mode, composed by `ModscopeApp`.

A room is a plain object, not a widget. Textual hands a key's action (`app.<action>`
bindings) and a message (handlers found by name on DOM nodes) to the App, and the App
passes each on to the room that owns it; a room keeps its own state and reaches what
the rooms share (the session, the view model, the main screen, the pacing) through the
App, so a restart that replaces them is seen by every room at once.
"""
