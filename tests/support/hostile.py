"""Provides helpers shared by tests (moved from test_hardening_csv.py)."""

from __future__ import annotations

# A device whose dictionary was written by someone hostile.
HOSTILE_TOML = """\
format = 1

[device]
model = "hostile"
name = "=HYPERLINK(\\"http://x\\")"
default_space = "hr"

[spaces.hr]
table = "holding"
prefix = "4"
width = 4
first = 1

[[entry]]
ref = "40001"
name = "=cmd|' /C calc'!A0"
type = "u16"
unit = "@SUM(1+1)"

[[entry]]
ref = "40002"
name = "+mode"
enum = { "0" = "-2+3", "1" = "Run" }

[[entry]]
ref = "40003"
name = "Label"
type = "str"
length = 2
"""
