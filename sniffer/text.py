"""Provides safe plain text for anything that came from a device or a file.

Device strings are data, never markup or terminal control: control characters are
escaped as `\\xNN` and long strings are cut with an ellipsis. Views render the result as
plain text (never through a markup parser).
"""

from __future__ import annotations

MAX_TEXT = 400


def plain(text: str, limit: int = MAX_TEXT) -> str:
    """`text` with control characters escaped and at most `limit` characters."""
    out = []
    for ch in text:
        code = ord(ch)
        if code < 0x20 or 0x7F <= code < 0xA0 or code in (0x2028, 0x2029):
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")
        else:
            out.append(ch)
    result = "".join(out)
    if len(result) > limit:
        result = result[: limit - 1] + "…"
    return result
