"""Provides live lines: passive ports, the capture engine, the recorder, the line-settings scan."""
